// The exact neighbour reuse of the ICP loop (docs/performance.md): the cached search must give the
// same correspondences as a fresh search -- indices, order and distances to the last bit -- on
// seeded random transform sequences, for both strategies, several k and max distances, with
// exact distance ties, on the synthetic room and on the SLAM simulator; and align() must be
// bit-identical with the cache on and off. Also the kd-tree's total order and seeded search.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/registration/correspondence.hpp"
#include "lmalign/registration/pipeline.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/registration/score.hpp"
#include "lmalign/search/kdtree.hpp"
#include "lmalign/sim/slam_sim.hpp"
#include "support/align_preset.hpp"
#include "support/synthetic_scene.hpp"

namespace lmalign {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Points on a 0.05 m lattice: many exactly equal distances (ties at every rank).
Points3 lattice(int nx, int ny, int nz) {
  Points3 p;
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j)
      for (int k = 0; k < nz; ++k) p.emplace_back(0.05 * i, 0.05 * j, 0.05 * k);
  return p;
}

// The k first points of the total order (squared_distance, index), by brute force.
std::vector<PointIndex> brute_knn(const Points3& pts, const Vec3& q, std::size_t k) {
  std::vector<PointIndex> order(pts.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](PointIndex a, PointIndex b) {
    const double da = squared_distance(q, pts[a]), db = squared_distance(q, pts[b]);
    return da < db || (da == db && a < b);
  });
  order.resize(std::min(k, pts.size()));
  return order;
}

TEST(KdTreeTotalOrder, TiesResolveByIndexAtEveryRank) {
  const Points3 pts = lattice(9, 8, 5);  // 360 points
  const KdTree tree(pts, 4);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> pick(0, static_cast<int>(pts.size()) - 1);
  std::uniform_real_distribution<double> jitter(-0.03, 0.03);
  std::vector<PointIndex> idx(40);
  std::vector<double> d2(40);
  for (int trial = 0; trial < 300; ++trial) {
    // Half the queries exactly on lattice points or lattice midpoints (maximal ties).
    Vec3 q = pts[static_cast<std::size_t>(pick(rng))];
    if (trial % 3 == 1) q += Vec3(0.025, 0.025, 0.0);
    if (trial % 3 == 2) q += Vec3(jitter(rng), jitter(rng), jitter(rng));
    for (std::size_t k : {1u, 2u, 6u, 7u, 27u, 40u}) {
      const std::size_t found = tree.knn(q, k, idx.data(), d2.data());
      const std::vector<PointIndex> expect = brute_knn(pts, q, k);
      ASSERT_EQ(found, expect.size());
      for (std::size_t j = 0; j < found; ++j) {
        ASSERT_EQ(idx[j], expect[j]) << "trial " << trial << " k " << k << " rank " << j;
        ASSERT_EQ(d2[j], squared_distance(q, pts[expect[j]]));  // bit-identical
      }
    }
  }
}

// The leaf scans prune with float copies of the coordinates (relative to the centre of the
// points' box): a point within the bound must never be dropped, ties at the bound included, even
// when float rounding is as coarse as the lattice; coordinates beyond the float range fall back
// to exact scans.
TEST(KdTreeTotalOrder, FloatPrefilterKeepsEveryPointWithinTheBound) {
  std::mt19937 rng(17);
  std::uniform_int_distribution<int> pick(0, 359);
  std::uniform_real_distribution<double> jitter(-0.03, 0.03);
  std::vector<PointIndex> idx(27);
  std::vector<double> d2(27);
  // far: one point so far away that the float copies of the lattice are rounded to ~1 cm
  // (2e5 m from the centre: float spacing there 1.6 cm); at 1e31 m they cannot be floats at all.
  // far < 0: the lattice shrunk to 1e-21 m, where float squares are subnormal or zero.
  for (const double far : {0.0, 2e5, 3e5, 1e31, -1.0}) {
    Points3 pts = lattice(9, 8, 5);  // 360 points, 0.05 m apart: ties at every rank
    for (Vec3& p : pts)
      p = far < 0.0 ? Vec3(p * 2e-20) : Vec3(p + Vec3(0.0, 0.0, far > 1e30 ? 0.0 : 0.5 * far));
    if (far > 0.0) pts.emplace_back(far, -far, 0.0);
    const KdTree tree(pts, 4);
    for (int trial = 0; trial < 200; ++trial) {
      Vec3 q = pts[static_cast<std::size_t>(pick(rng))];
      const double unit = far < 0.0 ? 2e-20 : 1.0;
      if (trial % 3 == 1) q += unit * Vec3(0.025, 0.025, 0.0);
      if (trial % 3 == 2) q += unit * Vec3(jitter(rng), jitter(rng), jitter(rng));
      if (trial == 199) q = Vec3(-2e31, 0.0, 0.0);  // a query beyond the float range
      for (std::size_t k : {1u, 6u, 7u, 27u}) {
        const std::size_t found = tree.knn(q, k, idx.data(), d2.data());
        const std::vector<PointIndex> expect = brute_knn(pts, q, k);
        ASSERT_EQ(found, expect.size());
        for (std::size_t j = 0; j < found; ++j) {
          ASSERT_EQ(idx[j], expect[j]) << "far " << far << " trial " << trial << " k " << k;
          ASSERT_EQ(d2[j], squared_distance(q, pts[expect[j]]));
        }
      }
    }
  }
}

TEST(KdTreeTotalOrder, FirstKOfAWiderQueryAreTheKQuery) {
  const Points3 pts = test::room_points(4000, 41);
  const KdTree tree(pts);
  const Points3 queries = test::room_points(500, 42);
  std::vector<PointIndex> a(12), b(12);
  std::vector<double> da(12), db(12);
  for (const Vec3& q : queries) {
    for (std::size_t k : {1u, 5u, 8u}) {
      tree.knn(q, k, a.data(), da.data());
      tree.knn(q, k + 4, b.data(), db.data());
      for (std::size_t j = 0; j < k; ++j) {
        ASSERT_EQ(a[j], b[j]);
        ASSERT_EQ(da[j], db[j]);
      }
    }
  }
}

TEST(KdTreeTotalOrder, SeededSearchEqualsPlainSearch) {
  const Points3 pts = lattice(10, 10, 4);
  const KdTree tree(pts, 6);
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-0.1, 0.55);
  std::vector<PointIndex> plain(9), seeded(9);
  std::vector<double> dp(9), ds(9);
  for (int trial = 0; trial < 400; ++trial) {
    const Vec3 q(u(rng), u(rng), 0.4 * u(rng));
    const Vec3 near_q = q + Vec3(0.02 * u(rng), 0.02 * u(rng), 0.0);
    // Seeds: the 9 nearest of a nearby query, re-evaluated at q and sorted (the cache's use).
    tree.knn(near_q, 9, seeded.data(), ds.data());
    for (std::size_t j = 0; j < 9; ++j) ds[j] = squared_distance(q, pts[seeded[j]]);
    std::vector<std::size_t> o(9);
    std::iota(o.begin(), o.end(), 0);
    std::sort(o.begin(), o.end(), [&](std::size_t a, std::size_t b) {
      return ds[a] < ds[b] || (ds[a] == ds[b] && seeded[a] < seeded[b]);
    });
    std::vector<PointIndex> si(9);
    std::vector<double> sd(9);
    for (std::size_t j = 0; j < 9; ++j) {
      si[j] = seeded[o[j]];
      sd[j] = ds[o[j]];
    }
    const std::size_t n_seeds = static_cast<std::size_t>(trial % 10);  // 0..9 seeds
    const std::size_t f1 = tree.knn(q, 9, plain.data(), dp.data());
    const std::size_t f2 =
        tree.knn_seeded(q, 9, si.data(), sd.data(), n_seeds, si.data(), sd.data());
    ASSERT_EQ(f1, f2);
    for (std::size_t j = 0; j < f1; ++j) {
      ASSERT_EQ(plain[j], si[j]) << "trial " << trial;
      ASSERT_EQ(dp[j], sd[j]);
    }
  }
}

// A seeded random walk of transforms: mostly small steps (the cache holds), some large jumps
// (it must let go), some exact repeats.
std::vector<Isometry3> random_walk(std::uint32_t seed, int steps, double step_m, double step_deg) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Isometry3> walk;
  Isometry3 T = pose_from_xyz_rpy_deg(0.2 * g(rng), 0.2 * g(rng), 0.1 * g(rng), 3 * g(rng),
                                      3 * g(rng), 10 * g(rng));
  for (int i = 0; i < steps; ++i) {
    const double r = u(rng);
    const double scale = r < 0.1 ? 20.0 : r < 0.2 ? 0.0 : r < 0.6 ? 1.0 : 0.05;
    T = pose_from_xyz_rpy_deg(scale * step_m * g(rng), scale * step_m * g(rng),
                              scale * step_m * g(rng), scale * step_deg * g(rng),
                              scale * step_deg * g(rng), scale * step_deg * g(rng)) *
        T;
    walk.push_back(T);
  }
  return walk;
}

void expect_same(const Correspondences& a, const Correspondences& b, const std::string& what) {
  ASSERT_EQ(a.size(), b.size()) << what;
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].source_index, b[i].source_index) << what << " #" << i;
    ASSERT_EQ(a[i].target_index, b[i].target_index) << what << " #" << i;
    ASSERT_EQ(a[i].distance_sq_m2, b[i].distance_sq_m2) << what << " #" << i;  // to the bit
  }
}

// Points served by the fast path (half the k-th to (k+1)-th gap) over all walks.
std::size_t fast_total = 0;

// Runs the cached finder along the walk and compares every step with a fresh plain search.
void check_walk(const Points3& source, const KdTree& tree, const std::vector<double>& weights,
                const CorrespondenceOptions& options, const std::vector<Isometry3>& walk,
                std::size_t* reused_total) {
  const CorrespondenceFinder finder(tree, weights, options);
  CorrespondenceWorkspace ws;
  Points3 moved, moved_plain;
  Correspondences cached, plain, plain_loop;
  const std::string what = to_string(options.kind) + " k=" + std::to_string(options.k) +
                           " max=" + std::to_string(options.max_distance_m);
  for (std::size_t i = 0; i < walk.size(); ++i) {
    finder.find(source, walk[i], moved, cached, ws, /*reuse=*/true);
    *reused_total += ws.last_reused();
    fast_total += ws.last_fast();
    ASSERT_LE(ws.last_fast(), ws.last_reused());
    transform_points(walk[i], source, moved_plain);
    ASSERT_TRUE(moved == moved_plain) << what << " step " << i;  // exactly transform_points
    finder.find(moved_plain, plain);
    expect_same(cached, plain, what + " step " + std::to_string(i));
    // The loop's call without reuse is the same plain search.
    Points3 m2;
    CorrespondenceWorkspace ws2;
    finder.find(source, walk[i], m2, plain_loop, ws2, /*reuse=*/false);
    expect_same(plain_loop, plain, what + " (no reuse) step " + std::to_string(i));
  }
}

TEST(NeighbourReuse, IdenticalToPlainSearchOnRandomWalks) {
  const Points3 target = test::room_points(2500, 51);
  const Points3 source = test::room_points(1800, 52);
  const KdTree tree(target);
  std::mt19937 rng(53);
  std::uniform_int_distribution<int> w(0, 4);  // many equal weights: ties in the argmax
  std::vector<double> weights(target.size());
  for (double& x : weights) x = w(rng);
  std::size_t reused = 0;
  std::uint32_t seed = 100;
  for (CorrespondenceKind kind : {CorrespondenceKind::kNearest, CorrespondenceKind::kWeightedKnn}) {
    for (int k : {1, 3, 5, 10}) {
      if (kind == CorrespondenceKind::kNearest && k != 1) continue;
      for (double max_d : {kInf, 0.2, 0.05}) {
        CorrespondenceOptions o;
        o.kind = kind;
        o.k = k;
        o.max_distance_m = max_d;
        check_walk(source, tree, weights, o, random_walk(seed++, 25, 0.004, 0.2), &reused);
      }
    }
  }
  EXPECT_GT(reused, 10000u);     // the cache did serve (the test is not vacuous)
  EXPECT_GT(fast_total, 5000u);  // and so did its fast path
}

TEST(NeighbourReuse, OneWorkspaceForFindersWithOtherWeights) {
  // The fast path remembers which of a point's k nearest carry the largest weight. A workspace
  // used by a finder with other weights (same target, k and source) must not use those marks.
  const Points3 target = test::room_points(2000, 71);
  const Points3 source = test::room_points(1500, 72);
  const KdTree tree(target);
  std::mt19937 rng(73);
  std::uniform_int_distribution<int> w(1, 4);
  std::vector<double> weights_a(target.size()), weights_b(target.size());
  for (std::size_t i = 0; i < target.size(); ++i) {
    weights_a[i] = w(rng);
    weights_b[i] = 5.0 - weights_a[i];  // the opposite preference
  }
  CorrespondenceOptions o;
  o.kind = CorrespondenceKind::kWeightedKnn;
  o.k = 5;
  const std::vector<Isometry3> walk = random_walk(400, 30, 0.002, 0.1);
  CorrespondenceWorkspace ws;
  Points3 moved, moved_plain;
  Correspondences cached, plain;
  std::size_t fast = 0;
  for (std::size_t i = 0; i < walk.size(); ++i) {
    // A fresh finder each time, alternating the weights (the same addresses may come back).
    const CorrespondenceFinder finder(tree, i % 2 == 0 ? weights_a : weights_b, o);
    for (int repeat = 0; repeat < 2; ++repeat) {
      finder.find(source, walk[i], moved, cached, ws, /*reuse=*/true);
      fast += ws.last_fast();
      transform_points(walk[i], source, moved_plain);
      finder.find(moved_plain, plain);
      expect_same(cached, plain, "step " + std::to_string(i) + " repeat " + std::to_string(repeat));
    }
  }
  EXPECT_GT(fast, 10000u);  // the fast path served, with the marks of the finder in use
}

TEST(NeighbourReuse, IdenticalFarFromTheOrigin) {
  // Geo-referenced maps (UTM-like coordinates, 1e5-1e6 m): q - p cancels most digits, so the
  // reuse tests rely on their absolute rounding allowance (one bound per call, from the target's
  // coordinates and every registered pose).
  const Vec3 offset(512345.25, 5412345.5, 231.0);
  Points3 target = test::room_points(1500, 61);
  Points3 source = test::room_points(1200, 62);
  for (Vec3& p : target) p += offset;
  for (Vec3& p : source) p += offset;
  const KdTree tree(target);
  std::mt19937 rng(63);
  std::uniform_int_distribution<int> w(0, 4);
  std::vector<double> weights(target.size());
  for (double& x : weights) x = w(rng);
  // Walks of small steps about the offset: a rotation about the origin would move the points
  // by kilometres, so each pose turns about the map's own centre.
  std::size_t reused = 0;
  const std::size_t fast_before = fast_total;
  std::uint32_t seed = 300;
  for (int k : {1, 5}) {
    CorrespondenceOptions o;
    o.kind = k == 1 ? CorrespondenceKind::kNearest : CorrespondenceKind::kWeightedKnn;
    o.k = k;
    std::vector<Isometry3> walk = random_walk(seed++, 25, 0.004, 0.2);
    for (Isometry3& T : walk) {
      Isometry3 to_centre = Isometry3::Identity();
      to_centre.translation() = -offset;
      T = to_centre.inverse() * T * to_centre;
    }
    check_walk(source, tree, weights, o, walk, &reused);
  }
  EXPECT_GT(reused, 5000u);                    // the cache served despite the large coordinates
  EXPECT_GT(fast_total - fast_before, 1000u);  // and so did its fast path
}

TEST(NeighbourReuse, IdenticalWithExactTiesEverywhere) {
  // Lattice target, lattice source: every distance is tied with others, at every rank.
  const Points3 target = lattice(12, 10, 4);
  const Points3 source = lattice(8, 8, 3);
  const KdTree tree(target, 5);
  std::vector<double> weights(target.size());
  for (std::size_t i = 0; i < weights.size(); ++i) weights[i] = static_cast<double>(i % 3);
  std::vector<Isometry3> walk;  // small exact translations keep ties exact
  for (int i = 0; i < 30; ++i) {
    Isometry3 T = Isometry3::Identity();
    T.translation() = Vec3(0.0125 * (i % 5), 0.025 * ((i / 5) % 3), 0.0);
    walk.push_back(T);
  }
  std::size_t reused = 0;
  for (int k : {1, 4, 6}) {
    CorrespondenceOptions o;
    o.kind = k == 1 ? CorrespondenceKind::kNearest : CorrespondenceKind::kWeightedKnn;
    o.k = k;
    check_walk(source, tree, weights, o, walk, &reused);
  }
}

TEST(NeighbourReuse, IdenticalOnTheSlamSimulator) {
  sim::SlamSimOptions so;
  so.num_landmarks = 4000;
  so.seed = 11;
  so.T_target_source = pose_from_xyz_rpy_deg(0.1, -0.05, 0.02, 1, -1, 3);
  const sim::SlamMapPair pair = sim::simulate_map_pair(so);
  const PreparedTarget target(pair.target);
  const Points3 source = pair.source.positions();
  std::size_t reused = 0;
  std::vector<Isometry3> walk = random_walk(7, 30, 0.003, 0.1);
  for (Isometry3& T : walk) T = T * so.T_target_source;  // around the true alignment
  for (WeightKind wk : {WeightKind::kUniform, WeightKind::kObservations, WeightKind::kCovariance}) {
    CorrespondenceOptions o;
    o.kind = wk == WeightKind::kUniform ? CorrespondenceKind::kNearest
                                        : CorrespondenceKind::kWeightedKnn;
    o.k = 5;
    check_walk(source, target.tree(), target.weights(wk), o, walk, &reused);
  }
  EXPECT_GT(reused, 10000u);
}

TEST(NeighbourReuse, ScoreThroughTheCacheIsBitIdentical) {
  const Points3 target = test::room_points(2000, 61);
  const Points3 source = test::room_points(1500, 62);
  const KdTree tree(target);
  CorrespondenceOptions o;
  o.kind = CorrespondenceKind::kWeightedKnn;
  o.k = 5;
  const CorrespondenceFinder finder(tree, std::vector<double>(target.size(), 1.0), o);
  CorrespondenceWorkspace ws;
  Points3 moved;
  Correspondences c;
  for (const Isometry3& T : random_walk(63, 20, 0.005, 0.3)) {
    for (double range : {kInf, 0.1}) {
      const FitnessScore plain = fitness_score(source, tree, T, range);
      const FitnessScore cached = fitness_score(source, finder, T, range, ws);
      ASSERT_EQ(plain.mean_sq_m2, cached.mean_sq_m2);
      ASSERT_EQ(plain.num_scored, cached.num_scored);
    }
    finder.find(source, T, moved, c, ws);
  }
}

TEST(NeighbourReuse, SameForAnyThreadCount) {
  const Points3 target = test::room_points(3000, 71);
  const Points3 source = test::room_points(2500, 72);
  const KdTree tree(target);
  std::vector<double> weights(target.size());
  for (std::size_t i = 0; i < weights.size(); ++i) weights[i] = static_cast<double>(i % 5);
  CorrespondenceOptions o;
  o.kind = CorrespondenceKind::kWeightedKnn;
  o.k = 5;
  const CorrespondenceFinder finder(tree, weights, o);
  const std::vector<Isometry3> walk = random_walk(73, 15, 0.004, 0.2);
  const int saved = omp_get_max_threads();
  std::vector<Correspondences> runs;
  for (int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    CorrespondenceWorkspace ws;
    Points3 moved;
    Correspondences c, all;
    for (const Isometry3& T : walk) {
      finder.find(source, T, moved, c, ws);
      all.insert(all.end(), c.begin(), c.end());
    }
    runs.push_back(all);
  }
  omp_set_num_threads(saved);
  expect_same(runs[0], runs[1], "1 vs 2 threads");
  expect_same(runs[0], runs[2], "1 vs 3 threads");
}

TEST(NeighbourReuse, WorkspaceRebindsToAnotherSourceSet) {
  const Points3 target = test::room_points(1500, 81);
  const KdTree tree(target);
  const CorrespondenceFinder finder(tree, {}, CorrespondenceOptions{});
  const Points3 a = test::room_points(800, 82), b = test::room_points(600, 83);
  CorrespondenceWorkspace ws;
  Points3 moved;
  Correspondences cached, plain;
  const Isometry3 T = pose_from_xyz_rpy_deg(0.05, 0, 0, 0, 0, 2);
  for (const Points3* src : {&a, &b, &a}) {
    finder.find(*src, T, moved, cached, ws);
    finder.find(transform_points(T, *src), plain);
    expect_same(cached, plain, "rebind");
  }
  EXPECT_GT(ws.memory_bytes(), 0u);
}

// align() with the cache on and off: the same T, iterations, termination, scores and history,
// bit for bit, for every strategy, from seeded random starts.
TEST(NeighbourReuse, AlignIsBitIdenticalWithReuseOnAndOff) {
  const Points3 pts = test::room_points(3000, 91);
  const Map target_map = test::map_from_points(pts, 92);
  const PreparedTarget target(target_map);
  const Points3 source(pts.begin(), pts.begin() + 2000);
  std::mt19937 rng(93);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int trial = 0; trial < 4; ++trial) {
    const Isometry3 init = pose_from_xyz_rpy_deg(0.1 * g(rng), 0.1 * g(rng), 0.05 * g(rng),
                                                 2 * g(rng), 2 * g(rng), 8 * g(rng));
    for (WeightKind st : all_weight_kinds()) {
      for (int k : {1, 5}) {
        // The engine run directly, for the history without scores on odd trials.
        PipelineSpec spec = find_preset(test::paper_preset(st)).spec;
        if (st != WeightKind::kUniform) spec.settings.emplace_back("match.k", (long long)k);
        spec.settings.emplace_back("schedule.max_distance_m", trial == 3 ? 0.15 : kInf);
        PipelineRequest request;
        request.initial_guess = init;
        request.record_history = true;
        request.history_scores = trial % 2 == 0;
        SourceView view;
        view.positions = &source;
        spec.settings.emplace_back("match.reuse_neighbours", true);
        const RegistrationResult on = Pipeline(spec).run(view, target, request).registration;
        spec.settings.back().second = false;
        const RegistrationResult off = Pipeline(spec).run(view, target, request).registration;
        const std::string what = to_string(st) + " k=" + std::to_string(k);
        ASSERT_TRUE(on.T_target_source.matrix() == off.T_target_source.matrix()) << what;
        ASSERT_EQ(on.iterations, off.iterations) << what;
        ASSERT_EQ(on.termination, off.termination) << what;
        ASSERT_EQ(on.initial_score_m2, off.initial_score_m2) << what;
        ASSERT_EQ(on.final_score_m2, off.final_score_m2) << what;
        ASSERT_EQ(on.num_correspondences, off.num_correspondences) << what;
        ASSERT_EQ(on.history.size(), off.history.size()) << what;
        for (std::size_t i = 0; i < on.history.size(); ++i) {
          ASSERT_EQ(on.history[i].mse_m2, off.history[i].mse_m2) << what;
          ASSERT_EQ(on.history[i].num_correspondences, off.history[i].num_correspondences);
          if (request.history_scores) {
            ASSERT_EQ(on.history[i].score_m2, off.history[i].score_m2);
          }
        }
      }
    }
  }
}

TEST(SlamSimulator, SeededDeterministicAndValid) {
  sim::SlamSimOptions so;
  so.num_landmarks = 3000;
  so.seed = 5;
  so.T_target_source = pose_from_xyz_rpy_deg(0.3, -0.1, 0.05, 2, -1, 10);
  const sim::SlamMapPair a = sim::simulate_map_pair(so), b = sim::simulate_map_pair(so);
  ASSERT_EQ(a.source.landmarks.size(), 3000u);
  ASSERT_EQ(a.target.landmarks.size(), 3000u);
  EXPECT_NO_THROW(a.source.validate());
  EXPECT_NO_THROW(a.target.validate());
  EXPECT_TRUE(a.source.positions() == b.source.positions());
  EXPECT_TRUE(a.target.positions() == b.target.positions());
  so.seed = 6;
  EXPECT_FALSE(sim::simulate_map_pair(so).target.positions() == a.target.positions());
  for (const Landmark& lm : a.target.landmarks) {
    ASSERT_GE(lm.observations.size(), 2u);
    ASSERT_LE(lm.observations.size(), 8u);
  }
  // Base ICP from near the truth recovers it (the maps overlap by 80%, and the corridor's
  // furniture fixes the slide along it to within a few centimetres).
  so.overlap = 1.0;
  so.seed = 5;
  const sim::SlamMapPair full = sim::simulate_map_pair(so);
  const PreparedTarget full_target(full.target);
  test::Ask near;
  near.initial_guess = so.T_target_source * pose_from_xyz_rpy_deg(0.03, 0.02, 0, 0, 0, 1.5);
  const RegistrationResult r =
      test::align_with("base", full.source.positions(), full_target, near).registration;
  const TransformError e = transform_error(r.T_target_source, so.T_target_source);
  EXPECT_LT(e.rotation_deg, 0.5);
  EXPECT_LT(e.translation_m, 0.05);
  sim::SlamSimOptions bad;
  bad.num_landmarks = 3;
  EXPECT_THROW(sim::simulate_map_pair(bad), InvalidArgument);
}

}  // namespace
}  // namespace lmalign
