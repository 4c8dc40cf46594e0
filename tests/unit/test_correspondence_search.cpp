// The correspondence search (registration/stages/correspondence_search.hpp): descriptors,
// matches, the covariance-aware consistency graph and its cliques, on seeded simulated streets;
// and the default, whose complete search refines its poses.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/map/transform.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/stages/correspondence_search.hpp"
#include "lmalign/registration/stages/data_scales.hpp"
#include "lmalign/registration/stages/landmark_descriptors.hpp"
#include "lmalign/search/kdtree.hpp"
#include "lmalign/sim/fleet_sim.hpp"
#include "lmalign/sim/street_sim.hpp"
#include "support/align_preset.hpp"

namespace lmalign {
namespace {

// `lmalign simulate --scene street --overlap 0.25 --frames 30 --landmarks 3000 --transform
// 20,5,0,0,0,120 --seed SEED`: the pairs.
sim::SlamMapPair street(std::uint64_t seed) {
  sim::StreetSimOptions o;
  o.seed = seed;
  o.overlap = 0.25;
  o.window_frames = 30;
  o.num_landmarks = 3000;
  o.T_target_source = pose_from_xyz_rpy_deg(20.0, 5.0, 0.0, 0.0, 0.0, 120.0);
  return sim::simulate_street_pair(o);
}

struct Search {
  SourceLandmarks source;
  PreparedTarget target;
  CorrespondenceSearchInput input;
  explicit Search(const sim::SlamMapPair& pair)
      : source(SourceLandmarks::from_map(pair.source)), target(pair.target) {
    input.source.points = &source.positions;
    input.source.covariances_m2 = &source.covariances_m2;
    input.source.view_directions = &source.view_directions;
    input.target = &target;
    input.ups_source = {source.up.value_or(Vec3::UnitZ())};
    input.ups_target = {target.up_axis().value_or(Vec3::UnitZ())};
    input.floor_m = estimate_data_scales(source.positions, &source.covariances_m2).floor_m;
  }
};

bool near_truth(const CorrespondenceSearchResult& r, const Isometry3& truth) {
  for (const CorrespondenceHypothesis& h : r.hypotheses) {
    const TransformError e = transform_error(h.T_target_source, truth);
    if (e.rotation_deg < 5.0 && e.translation_m < 3.0) return true;
  }
  return false;
}

TEST(CorrespondenceSearch, OneOfItsPosesIsNearTheTruthOnAStreetAndTheRunRepeats) {
  // Measured on seeds 1-9 of the street (one pair of up axes, 32 poses): a pose within
  // 5 deg / 3 m of the truth on 7 of 9; on seed 5 it is the 15th by clique size, within the
  // default 16.
  const sim::SlamMapPair pair = street(5);
  const Search s(pair);
  const CorrespondenceSearchOptions o;
  const CorrespondenceSearchResult r = correspondence_search(s.input, o);
  EXPECT_GT(r.matches, 100u);
  EXPECT_GT(r.radius_m, 0.0);
  ASSERT_FALSE(r.hypotheses.empty());
  EXPECT_LE(r.hypotheses.size(), o.hypotheses);
  // Each descriptor kind's poses by decreasing clique size (one pair of up axes here); the
  // street knows its viewing directions, so both kinds propose, in turn.
  for (const bool oriented : {false, true}) {
    std::size_t last = std::numeric_limits<std::size_t>::max(), count = 0;
    for (const CorrespondenceHypothesis& h : r.hypotheses) {
      EXPECT_GE(h.inliers, o.min_inliers);
      if (h.oriented != oriented) continue;
      EXPECT_LE(h.inliers, last);
      last = h.inliers;
      ++count;
    }
    EXPECT_GT(count, 0u) << (oriented ? "oriented" : "yaw-invariant");
  }
  EXPECT_NE(r.hypotheses[0].oriented, r.hypotheses[1].oriented);
  EXPECT_TRUE(near_truth(r, pair.T_target_source));
  // Deterministic, whatever the thread count.
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const CorrespondenceSearchResult again = correspondence_search(s.input, o);
  omp_set_num_threads(saved);
  ASSERT_EQ(again.hypotheses.size(), r.hypotheses.size());
  for (std::size_t i = 0; i < r.hypotheses.size(); ++i) {
    EXPECT_TRUE(again.hypotheses[i].T_target_source.matrix() ==
                r.hypotheses[i].T_target_source.matrix());
  }
}

// Landmarks described once (the merge's verification) give the search's own hypotheses when
// described at the target's radius. (At each map's own radius the merge's verification still
// separates overlapping from unrelated maps: MergeRetrieval.VerificationSeparates...)
TEST(CorrespondenceSearch, LandmarksDescribedOnceGiveTheSearchsOwnHypotheses) {
  const sim::SlamMapPair pair = street(5);
  const Search s(pair);
  CorrespondenceSearchOptions o;
  o.oriented = false;
  const CorrespondenceSearchResult direct = correspondence_search(s.input, o);
  ASSERT_FALSE(direct.hypotheses.empty());
  const double radius = search_descriptor_radius(s.target.points(), o);
  EXPECT_EQ(radius, direct.radius_m);
  const DescribedLandmarks src = describe_search_landmarks(
      s.source.positions, &s.source.view_directions, s.input.ups_source[0], radius, true, o);
  const DescribedLandmarks tgt = describe_search_landmarks(
      s.target.points(), &s.target.view_directions(), s.input.ups_target[0], radius, false, o);
  EXPECT_EQ(src.keys.size(), std::min<std::size_t>(o.keypoints, s.source.positions.size()));
  const CorrespondenceSearchResult described =
      correspondence_search_described(s.input, src, tgt, o);
  EXPECT_EQ(described.matches, direct.matches);
  ASSERT_EQ(described.hypotheses.size(), direct.hypotheses.size());
  for (std::size_t i = 0; i < direct.hypotheses.size(); ++i) {
    EXPECT_TRUE(described.hypotheses[i].T_target_source.matrix() ==
                direct.hypotheses[i].T_target_source.matrix());
    EXPECT_EQ(described.hypotheses[i].inliers, direct.hypotheses[i].inliers);
  }
  // Bad input: a radius, an up axis, view directions of another size, a key out of range.
  EXPECT_THROW(describe_search_landmarks(s.source.positions, nullptr, Vec3::UnitZ(), 0.0, true, o),
               InvalidArgument);
  EXPECT_THROW(describe_search_landmarks(s.source.positions, nullptr, Vec3::Zero(), 1.0, true, o),
               InvalidArgument);
  const std::vector<Vec3> two_views(2, Vec3::UnitX());
  EXPECT_THROW(
      describe_search_landmarks(s.source.positions, &two_views, Vec3::UnitZ(), 1.0, true, o),
      InvalidArgument);
  DescribedLandmarks bad = tgt;
  bad.keys.back() = static_cast<std::uint32_t>(s.target.points().size());
  EXPECT_THROW(correspondence_search_described(s.input, src, bad, o), InvalidArgument);
  bad = tgt;
  bad.described.pop_back();
  EXPECT_THROW(correspondence_search_described(s.input, src, bad, o), InvalidArgument);
  bad = tgt;
  bad.up = Vec3::Zero();
  EXPECT_THROW(correspondence_search_described(s.input, src, bad, o), InvalidArgument);
}

// The oriented descriptors on seed 2 of the street (measured 2026-11-25): the
// yaw-invariant kind's pose nearest the truth rests on a clique of 27 matches, 2.3 deg /
// 0.49 m off; the oriented kind's on a clique of 80, 0.35 deg / 0.09 m off. The landmark's
// horizontal viewing direction orients its neighbourhood, so that a descriptor tells apart what
// lies ahead of a facade from what lies along it (the true counterpart among a landmark's 3
// nearest descriptors: 16% against 3-5% on the street's seeds).
TEST(CorrespondenceSearch, OrientedDescriptorsMatchMoreOfTheTrueCorrespondences) {
  const sim::SlamMapPair pair = street(2);
  const Search s(pair);
  const CorrespondenceSearchResult r = correspondence_search(s.input, {});
  std::size_t best[2] = {0, 0};
  double error_m[2] = {1e9, 1e9};
  for (const CorrespondenceHypothesis& h : r.hypotheses) {
    const TransformError e = transform_error(h.T_target_source, pair.T_target_source);
    if (e.rotation_deg > 5.0 || e.translation_m > 3.0 || h.inliers <= best[h.oriented]) continue;
    best[h.oriented] = h.inliers;
    error_m[h.oriented] = e.translation_m;
  }
  EXPECT_GE(best[1], 2 * best[0]);
  EXPECT_LT(error_m[1], 0.3);
  EXPECT_LT(error_m[1], error_m[0]);
  // Without the oriented kind (or without viewing directions), the yaw-invariant poses alone.
  CorrespondenceSearchOptions off;
  off.oriented = false;
  for (const CorrespondenceHypothesis& h : correspondence_search(s.input, off).hypotheses) {
    EXPECT_FALSE(h.oriented);
  }
  Search blind(pair);
  blind.input.source.view_directions = nullptr;
  for (const CorrespondenceHypothesis& h : correspondence_search(blind.input, {}).hypotheses) {
    EXPECT_FALSE(h.oriented);
  }
}

// A landmark's oriented descriptor is its neighbourhood's, whatever the map's yaw about the up
// axis and its translation (the viewing direction turns with the map); it needs a viewing
// direction away from the up axis and 4 neighbours.
TEST(LandmarkDescriptors, TheOrientedOneIsInvariantToYawAndTranslation) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Points3 pts;
  for (int i = 0; i < 400; ++i) pts.emplace_back(3.0 * u(rng), 3.0 * u(rng), u(rng));
  const Vec3 up = Vec3::UnitZ();
  const Vec3 view = Vec3(0.6, -0.3, 0.2).normalized();
  const Isometry3 T = pose_from_xyz_rpy_deg(12.0, -4.0, 2.0, 0.0, 0.0, 73.0);
  const KdTree tree(pts);
  const KdTree moved_tree(transform_points(T, pts));
  std::vector<float> a(kOrientedDescriptorDims), b(kOrientedDescriptorDims);
  std::vector<PointIndex> scratch;
  int described = 0;
  for (std::size_t i = 0; i < pts.size(); i += 20) {
    const bool ok = describe_landmark_oriented(pts, tree, i, up, view, 0.8, a.data(), &scratch);
    const bool ok_moved = describe_landmark_oriented(moved_tree.points(), moved_tree, i, up,
                                                     T.linear() * view, 0.8, b.data(), &scratch);
    ASSERT_EQ(ok, ok_moved);
    if (!ok) continue;
    ++described;
    double norm2 = 0.0;
    for (int x = 0; x < kOrientedDescriptorDims; ++x) {
      EXPECT_NEAR(a[x], b[x], 1e-5) << "landmark " << i << ", component " << x;
      norm2 += static_cast<double>(a[x]) * a[x];
    }
    EXPECT_NEAR(norm2, 1.0, 1e-5);  // Hellinger: the square roots of a distribution
  }
  EXPECT_GT(described, 10);
  // A different viewing direction is a different descriptor; looking straight down, none.
  ASSERT_TRUE(describe_landmark_oriented(pts, tree, 0, up, view, 0.8, a.data(), &scratch));
  ASSERT_TRUE(describe_landmark_oriented(pts, tree, 0, up, Vec3(-view.x(), -view.y(), view.z()),
                                         0.8, b.data(), &scratch));
  double diff = 0.0;
  for (int x = 0; x < kOrientedDescriptorDims; ++x) diff += std::abs(a[x] - b[x]);
  EXPECT_GT(diff, 0.1);
  EXPECT_FALSE(describe_landmark_oriented(pts, tree, 0, up, -up, 0.8, a.data(), &scratch));
  EXPECT_FALSE(describe_landmark_oriented(pts, tree, 0, up, Vec3::Zero(), 0.8, a.data(), &scratch));
  EXPECT_FALSE(describe_landmark_oriented(pts, tree, 0, up, view, 1e-6, a.data(), &scratch));
  EXPECT_FALSE(
      describe_landmark_oriented(pts, tree, 0, up, view, std::nan(""), a.data(), &scratch));
  for (const float x : a) EXPECT_EQ(x, 0.0f);
}

// A greedy clique holds a few of the true matches; its pose, fitted to those few, can be metres
// off. Refitted from every match it carries within the consistency test's standard deviations
// (LO-RANSAC's local optimisation), it takes in the others. Measured on issue 39's street seed
// 33: no clique pose within 3 deg / 3 m of the truth without refits, the nearest 4.2 deg / 3.7 m
// off; with 2 refits one, 0.41 deg / 0.43 m off.
TEST(LandmarkDescriptors, TheYawInvariantOneIsThatOfItsKNearestWithinTheRadius) {
  // describe_landmark takes the landmarks within the radius in the kd-tree's total order, at
  // most max_neighbours + 1 of them: bit for bit the histogram of the (max_neighbours + 1)
  // nearest that lie within the radius, summed in their order. Checked against that histogram
  // built here, on a lattice (exact distance ties) and on random points, with the cap reached
  // (a wide radius) and not.
  auto reference = [](const Points3& pts, const KdTree& tree, std::size_t i, const Vec3& up,
                      double radius, std::size_t cap, float* out) {
    const int dims = kLandmarkDescriptorDims;
    std::fill(out, out + dims, 0.0f);
    std::vector<PointIndex> idx(cap + 1);
    std::vector<double> d2(cap + 1);
    const std::size_t found = tree.knn(pts[i], cap + 1, idx.data(), d2.data());
    double total = 0.0;
    for (std::size_t j = 0; j < found; ++j) {
      if (idx[j] == i || d2[j] > radius * radius) continue;
      const Vec3 d = pts[idx[j]] - pts[i];
      const double h = d.dot(up);
      const double r = std::sqrt(std::max(d.squaredNorm() - h * h, 0.0));
      const double fr = std::clamp(r / radius * 4 - 0.5, 0.0, 3.0);
      const double fh = std::clamp((h / radius + 1.0) * 0.5 * 5 - 0.5, 0.0, 4.0);
      const int r0 = std::min(static_cast<int>(fr), 3), h0 = std::min(static_cast<int>(fh), 4);
      const int r1 = std::min(r0 + 1, 3), h1 = std::min(h0 + 1, 4);
      const double ar = fr - r0, ah = fh - h0;
      out[r0 * 5 + h0] += static_cast<float>((1 - ar) * (1 - ah));
      out[r1 * 5 + h0] += static_cast<float>(ar * (1 - ah));
      out[r0 * 5 + h1] += static_cast<float>((1 - ar) * ah);
      out[r1 * 5 + h1] += static_cast<float>(ar * ah);
      total += 1.0;
    }
    if (total < 4.0) {
      std::fill(out, out + dims, 0.0f);
      return false;
    }
    for (int b = 0; b < dims; ++b) out[b] = std::sqrt(out[b] / static_cast<float>(total));
    return true;
  };
  Points3 lattice, random;
  for (int x = 0; x < 12; ++x)
    for (int y = 0; y < 12; ++y)
      for (int z = 0; z < 6; ++z) lattice.emplace_back(0.1 * x, 0.1 * y, 0.1 * z);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 2.0);
  for (int i = 0; i < 800; ++i) random.emplace_back(u(rng), u(rng), 0.5 * u(rng));
  const Vec3 up = Vec3(0.1, 0.0, 1.0).normalized();
  int described = 0;
  for (const Points3* pts : {&lattice, &random}) {
    const KdTree tree(*pts);
    for (const double radius : {0.15, 0.25, 0.6}) {
      for (const std::size_t cap : {std::size_t{16}, std::size_t{192}}) {
        for (std::size_t i = 0; i < pts->size(); i += 37) {
          std::vector<float> a(kLandmarkDescriptorDims), b(kLandmarkDescriptorDims);
          const bool ok = describe_landmark(*pts, tree, i, up, radius, cap, a.data());
          const bool ok_ref = reference(*pts, tree, i, up, radius, cap, b.data());
          ASSERT_EQ(ok, ok_ref) << "landmark " << i << ", radius " << radius << ", cap " << cap;
          for (int k = 0; k < kLandmarkDescriptorDims; ++k) {
            ASSERT_EQ(a[k], b[k]) << "landmark " << i << ", radius " << radius << ", cap " << cap;
          }
          described += ok ? 1 : 0;
        }
      }
    }
  }
  EXPECT_GT(described, 100);
}

TEST(CorrespondenceSearch, DescriptorMatchesAreTheBruteForceNearest) {
  // match_descriptors sums 1, 4 (SSE2) or 8 (AVX) targets at a time and stops a sum once it
  // exceeds the m-th best: its matches must be the brute-force m nearest (ties by the earlier
  // target), for every width this machine runs. Components are multiples of 1/4 up to 2, so
  // every sum is exact in single precision whatever its order and the ties are exact; about a
  // tenth of either side is invalid; key counts that are not multiples of 4 or 8.
  std::vector<std::size_t> widths = {0, 1};
#if defined(__SSE2__)
  widths.push_back(4);
#endif
#if defined(__x86_64__) && defined(__GNUC__)
  if (__builtin_cpu_supports("avx")) widths.push_back(8);
#endif
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> level(0, 8), pick(0, 9);
  for (const int dims : {1, 5, 21, 97}) {
    for (const std::size_t m : {std::size_t{1}, std::size_t{3}, std::size_t{7}}) {
      const std::size_t ns = 53, nt = 203;
      std::vector<std::uint32_t> skeys(ns), tkeys(nt);
      for (std::size_t a = 0; a < ns; ++a) skeys[a] = static_cast<std::uint32_t>(3 * a + 1);
      for (std::size_t b = 0; b < nt; ++b) tkeys[b] = static_cast<std::uint32_t>(2 * b);
      std::vector<float> sd(ns * dims), td(nt * dims);
      for (float& v : sd) v = 0.25f * static_cast<float>(level(rng));
      for (float& v : td) v = 0.25f * static_cast<float>(level(rng) / 3);  // many ties
      std::vector<char> sok(ns), tok(nt);
      for (char& f : sok) f = pick(rng) != 0;
      for (char& f : tok) f = pick(rng) != 0;
      std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> got;
      for (const std::size_t lanes : widths) {
        got.push_back(match_descriptors(skeys, sd, sok, tkeys, td, tok, dims, m, lanes));
      }
      std::vector<std::pair<std::uint32_t, std::uint32_t>> want;
      for (std::size_t a = 0; a < ns; ++a) {
        if (!sok[a]) continue;
        std::vector<std::pair<float, std::size_t>> all;
        for (std::size_t b = 0; b < nt; ++b) {
          if (!tok[b]) continue;
          float d = 0.0f;
          for (int x = 0; x < dims; ++x) {
            const float e = sd[a * dims + x] - td[b * dims + x];
            d += e * e;
          }
          all.emplace_back(d, b);
        }
        std::sort(all.begin(), all.end());
        for (std::size_t r = 0; r < std::min(m, all.size()); ++r) {
          want.emplace_back(skeys[a], tkeys[all[r].second]);
        }
      }
      for (std::size_t w = 0; w < widths.size(); ++w) {
        EXPECT_EQ(got[w], want) << "dims " << dims << ", m " << m << ", lanes " << widths[w];
      }
    }
  }
  EXPECT_THROW(match_descriptors({1}, {0.0f}, {1}, {2}, {0.0f, 1.0f}, {1}, 1, 1), InvalidArgument);
  EXPECT_THROW(match_descriptors({1}, {0.0f}, {1}, {2}, {0.0f}, {1}, 1, 1, 3), InvalidArgument);
}

TEST(CorrespondenceSearch, RefitsBringTheCliquePosesNearTheTruthCloser) {
  const sim::SlamMapPair pair = street(33);
  const Search s(pair);
  auto nearest = [&](int refits) {
    CorrespondenceSearchOptions o;
    o.refits = refits;
    TransformError best{std::numeric_limits<double>::infinity(),
                        std::numeric_limits<double>::infinity()};
    std::size_t near = 0;
    for (const CorrespondenceHypothesis& h : correspondence_search(s.input, o).hypotheses) {
      const TransformError e = transform_error(h.T_target_source, pair.T_target_source);
      if (e.rotation_deg < 3.0 && e.translation_m < 3.0) ++near;
      if (e.translation_m < best.translation_m) best = e;
    }
    return std::make_pair(near, best);
  };
  const auto [near0, e0] = nearest(0);
  const auto [near2, e2] = nearest(2);
  EXPECT_GT(near2, near0);
  EXPECT_LT(e2.translation_m, e0.translation_m);
  CorrespondenceSearchOptions bad;
  bad.refits = 17;
  EXPECT_FALSE(bad.is_valid());
  bad.refits = -1;
  EXPECT_FALSE(bad.is_valid());
}

TEST(CorrespondenceSearch, VagueLandmarksMatchNothing) {
  // Covariances far wider than the descriptor radius: no landmark can tell where the maps
  // meet, so there are no matches and no poses (and no crash).
  const sim::SlamMapPair pair = street(2);
  Search s(pair);
  std::vector<Mat3> vague(s.source.positions.size(), Mat3::Identity() * 1e4);
  s.input.source.covariances_m2 = &vague;
  const CorrespondenceSearchResult r = correspondence_search(s.input, {});
  EXPECT_EQ(r.matches, 0u);
  EXPECT_TRUE(r.hypotheses.empty());
}

TEST(CorrespondenceSearch, TinyMapsGiveNoPosesAndBadInputThrows) {
  Points3 three{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  Points3 two{Vec3(0, 0, 0), Vec3(1, 0, 0)};
  const PreparedTarget target(three);
  CorrespondenceSearchInput in;
  in.source.points = &two;
  in.target = &target;
  in.ups_source = {Vec3::UnitZ()};
  in.ups_target = {Vec3::UnitZ()};
  in.floor_m = 0.01;
  EXPECT_TRUE(correspondence_search(in, {}).hypotheses.empty());
  in.source.points = &three;  // too sparse for a descriptor: no poses either
  EXPECT_TRUE(correspondence_search(in, {}).hypotheses.empty());
  CorrespondenceSearchOptions bad;
  bad.neighbours = 2;
  EXPECT_THROW(correspondence_search(in, bad), InvalidArgument);
  in.floor_m = 0.0;
  EXPECT_THROW(correspondence_search(in, {}), InvalidArgument);
  in.floor_m = 0.01;
  in.ups_target.clear();
  EXPECT_THROW(correspondence_search(in, {}), InvalidArgument);
}

TEST(CorrespondenceSearch, ScaleStepsAreCheckedAndRigidCliquesKeepScaleOne) {
  const sim::SlamMapPair pair = street(5);
  const Search s(pair);
  for (const CorrespondenceHypothesis& h : correspondence_search(s.input, {}).hypotheses) {
    EXPECT_EQ(h.scale, 1.0);
  }
  CorrespondenceSearchOptions bad;
  EXPECT_EQ(bad.scale_steps, 0);  // rigid unless asked
  bad.scale_steps = 6;
  bad.scale_ratio = 1.0;
  EXPECT_THROW(correspondence_search(s.input, bad), InvalidArgument);
  bad.scale_ratio = 1.12;
  bad.scale_steps = -1;
  EXPECT_THROW(correspondence_search(s.input, bad), InvalidArgument);
}

// The four maps of MergeFleet.FourMapsWithoutMetricScaleOnASim3PoseGraph's fleet (seed 11),
// each overlapping pair with its source's lengths times 1 / 1.6: the correspondences measure
// the scale where their evidence is decisive, and then the engine searches once, at the
// measured scale (no searches again at other scales). Measured (2026-11-25): decisive on 5 of
// the 6 overlapping pairs, each initial scale within 1% of the truth; 3 of them trusted and
// right; two pairs that share few landmarks end elsewhere, untrusted (5-6 gated inliers).
TEST(AdaptiveFleet, AFreeScaleIsMeasuredByTheCorrespondencesNotSearchedAgain) {
  sim::FleetSimOptions fo;
  fo.num_maps = 4;
  fo.seed = 11;
  const sim::FleetScene scene = sim::simulate_fleet(fo);
  const double truth = 1.6;  // target units per source unit
  std::size_t measured = 0, trusted = 0;
  for (const sim::FleetOverlap& ov : scene.overlaps) {
    const Map source_map =
        transform_map(scene.maps[ov.i], Similarity3{1.0 / truth, Isometry3::Identity()});
    const SourceLandmarks source = SourceLandmarks::from_map(source_map);
    const PreparedTarget target(scene.maps[ov.j]);
    const Isometry3 T_j_i = scene.T_world_map[ov.j].inverse() * scene.T_world_map[ov.i];
    AlignRequest request;
    request.scale = ScaleMode::kFree;
    const Summary s = align(find_preset("adaptive"), source.view(), target, request);
    const TransformError e = transform_error(s.registration.T_target_source, T_j_i);
    if (s.verdict.trustworthy) {
      ++trusted;
      EXPECT_LT(e.rotation_deg, 1.0) << ov.i << " -> " << ov.j;
      EXPECT_LT(e.translation_m, 0.1) << ov.i << " -> " << ov.j;
      EXPECT_LT(std::abs(s.scale.scale / truth - 1.0), 0.01) << ov.i << " -> " << ov.j;
    }
    if (!std::isfinite(s.scale.measured_factor)) continue;
    ++measured;
    EXPECT_LT(std::abs(s.scale.initial_scale / truth - 1.0), 0.03) << ov.i << " -> " << ov.j;
    EXPECT_EQ(s.scale.searches, 1);
  }
  EXPECT_GE(measured + 1, scene.overlaps.size());
  EXPECT_GE(trusted, 3u);
}

// The default on the street `seed`, checked to end at the truth (0.5 deg, 0.2 m), trusted.
Summary default_at_the_truth(std::uint64_t seed) {
  const sim::SlamMapPair pair = street(seed);
  const SourceLandmarks source = SourceLandmarks::from_map(pair.source);
  const PreparedTarget target(pair.target);
  const Summary s = test::align_with("adaptive", source, target, test::Ask{});
  const TransformError e = transform_error(s.registration.T_target_source, pair.T_target_source);
  EXPECT_LT(e.rotation_deg, 0.5) << "seed " << seed;
  EXPECT_LT(e.translation_m, 0.2) << "seed " << seed;
  EXPECT_TRUE(s.verdict.trustworthy) << "seed " << seed << ": " << s.verdict.reason;
  return s;
}

TEST(AdaptiveStreet, TheCorrespondencePosesFindAPairTheVoteMisses) {
  // Seed 5 of the street: without the correspondence poses the default ends 24 deg /
  // 49 m off (a search failure: refined from the truth the same maps score 364 against 296);
  // with them it ends at the truth, trusted.
  default_at_the_truth(5);
}

// The value of the initialiser's note `name`, or NaN when it has none.
double note(const Summary& s, const std::string& name) {
  for (const auto& [key, value] : s.initialisation.notes) {
    if (key == name) return value;
  }
  return std::nan("");
}

TEST(AdaptiveStreet, TheFirstPassAloneAnswersWhenTrustedAndTheCompleteSearchOtherwise) {
  // Seed 2 of the street: the correspondence poses alone give the truth, trusted, and
  // the vote never runs (measured 2026-11-25: 0.47 s against 1.80 s with the vote).
  {
    const Summary s = default_at_the_truth(2);
    EXPECT_GT(note(s, "first pass correspondence poses"), 0.0);
    EXPECT_EQ(note(s, "search candidates"), 0.0);  // no vote
    EXPECT_TRUE(std::isnan(note(s, "deeper pass after an untrusted answer")));
  }
  // A street of 1,000 landmarks (seed 1) where the first pass's answer is not trusted: the
  // complete search runs, and its answer is the reference's (the `exhaustive` preset: the
  // complete search at once, no first pass), bit for bit.
  sim::StreetSimOptions o;
  o.seed = 1;
  o.num_landmarks = 1000;
  o.T_target_source = pose_from_xyz_rpy_deg(20.0, 5.0, 0.0, 0.0, 0.0, 120.0);
  const sim::SlamMapPair pair = sim::simulate_street_pair(o);
  const SourceLandmarks source = SourceLandmarks::from_map(pair.source);
  const PreparedTarget target(pair.target);
  const Summary s = test::align_with("adaptive", source, target, test::Ask{});
  EXPECT_EQ(note(s, "deeper pass after an untrusted answer"), 1.0);
  EXPECT_GT(note(s, "search candidates"), 0.0);  // the vote ran
  const Summary off = test::align_with("exhaustive", source, target, test::Ask{});
  EXPECT_TRUE(std::isnan(note(off, "first pass correspondence poses")));
  EXPECT_GT(note(off, "search candidates"), 0.0);
  EXPECT_TRUE(s.registration.T_target_source.matrix() == off.registration.T_target_source.matrix());
  EXPECT_EQ(s.verdict.trustworthy, off.verdict.trustworthy);
  EXPECT_EQ(s.verdict.reason, off.verdict.reason);
  // search.complete_search = check (a fleet's pairs without priors): the first pass's untrusted
  // answer is the result; the complete search does not run.
  const Summary check =
      test::align_with("adaptive", source, target, test::Ask{{"search.complete_search=check"}});
  EXPECT_GT(note(check, "first pass correspondence poses"), 0.0);
  EXPECT_TRUE(std::isnan(note(check, "deeper pass after an untrusted answer")));
  EXPECT_EQ(note(check, "search candidates"), 0.0);  // no vote
  EXPECT_FALSE(check.verdict.trustworthy) << check.verdict.reason;
}

TEST(AdaptiveStreet, TheFirstPassSettlesAStreetWhoseLargestCliquesAreFacadeAliases) {
  // Seed 33 of the street: the repeated facades give larger wrong cliques (37-67
  // matches) than the truth's (at most 23-40). Until 2026-11-27 the first pass refined the 16
  // largest, all wrong; the complete search then ended on a wrong pose, refused (5.7 s). Now 64
  // clique poses, refitted, of which 16 by size and by the sharp score in turn: the first pass
  // alone gives the truth, trusted (1.3 s).
  const Summary s = default_at_the_truth(33);
  EXPECT_EQ(note(s, "search candidates"), 0.0);  // no vote
  EXPECT_TRUE(std::isnan(note(s, "deeper pass after an untrusted answer")));
}

// search.complete_search = check: a pair whose first pass finds no correspondence pose gets no
// answer (not trusted, the reason says why, the pose the initial guess) without the complete
// search; with rescue (the default) the complete search runs on the same pair. Two maps of a
// simulated fleet far apart from each other (a fleet's typical candidate pair that does not
// overlap; docs/merge.md, "Pairs without priors").
TEST(CompleteSearchSetting, CheckLeavesAPairWithoutACorrespondencePoseUnanswered) {
  sim::FleetSimOptions o;
  o.num_maps = 16;
  o.seed = 3;
  o.num_twins = 0;
  const sim::FleetScene scene = sim::simulate_fleet(o);
  // The pair of maps farthest apart (no landmark in common).
  std::size_t a = 0, b = 1;
  double farthest = 0.0;
  for (std::size_t i = 0; i < scene.maps.size(); ++i) {
    for (std::size_t j = i + 1; j < scene.maps.size(); ++j) {
      const double d =
          (scene.T_world_map[i].translation() - scene.T_world_map[j].translation()).norm();
      if (d > farthest) {
        farthest = d;
        a = i;
        b = j;
      }
    }
  }
  ASSERT_GT(farthest, 40.0);  // beyond twice the maps' radius
  const SourceLandmarks source = SourceLandmarks::from_map(scene.maps[a]);
  const PreparedTarget target(scene.maps[b]);
  const Summary check =
      test::align_with("adaptive", source, target, test::Ask{{"search.complete_search=check"}});
  EXPECT_EQ(note(check, "first pass correspondence poses"), 0.0);
  EXPECT_FALSE(check.verdict.trustworthy);
  EXPECT_NE(check.verdict.reason.find("no correspondence pose"), std::string::npos)
      << check.verdict.reason;
  EXPECT_TRUE(std::isnan(note(check, "search candidates")));  // no vote
  EXPECT_TRUE(check.hypotheses.empty());
  EXPECT_TRUE(check.registration.T_target_source.matrix() == Isometry3::Identity().matrix());
  EXPECT_EQ(check.registration.termination, TerminationReason::kNoCorrespondences);
  const Summary rescue = test::align_with("adaptive", source, target, test::Ask{});
  EXPECT_EQ(note(rescue, "first pass correspondence poses"), 0.0);
  EXPECT_GT(note(rescue, "search candidates"), 0.0);  // the vote ran
  EXPECT_FALSE(rescue.hypotheses.empty());
  EXPECT_FALSE(rescue.verdict.trustworthy) << rescue.verdict.reason;
  // A bad value is refused, naming the choices.
  try {
    test::align_with("adaptive", source, target, test::Ask{{"search.complete_search=never"}});
    ADD_FAILURE() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("rescue"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace lmalign
