// lmalign::merge on real maps: the motion-capture-anchored desk map and the KITTI stereo VO map,
// cut into frame windows with split_map() (the library behind `lmalign split`), each window
// moved by a seeded random pose (any yaw about the up axis, up to 3 m), then merged without
// priors and with noisy odometry priors. Checked against the known moves (docs/merge.md).
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>

#include "lmalign/core/geometry.hpp"
#include "lmalign/map/formats/formats.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/map/split.hpp"
#include "lmalign/merge/evaluation.hpp"
#include "lmalign/merge/merge.hpp"
#include "lmalign/registration/stages/data_scales.hpp"
#include "support/data_path.hpp"

namespace lmalign {
namespace {

struct Windows {
  std::vector<Map> maps;
  std::vector<std::string> names;
  std::vector<Isometry3> truth;  ///< T_world_map: world = the full map's frame
};

// Windows [first + k * step, first + k * step + length - 1] of `full`, each expressed in a frame
// moved by a random yaw about the map's up axis and a translation up to 3 m.
Windows cut(const Map& full, Id first, Id length, Id step, std::size_t count, std::uint64_t seed) {
  const Vec3 up = estimate_up_axis(full).value_or(Vec3::UnitZ());
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> yaw(-kPi, kPi), u(-1.0, 1.0);
  Windows w;
  for (std::size_t k = 0; k < count; ++k) {
    SplitOptions o;
    o.first_frame_id = first + static_cast<Id>(k) * step;
    o.last_frame_id = o.first_frame_id + length - 1;
    const Map window = split_map(full, o);
    Isometry3 T_map_world = Isometry3::Identity();
    T_map_world.linear() = Eigen::AngleAxisd(yaw(rng), up).toRotationMatrix();
    Vec3 t(u(rng), u(rng), u(rng));
    T_map_world.translation() = 3.0 * t / std::max(1.0, t.norm());
    w.maps.push_back(transform_map(window, T_map_world));
    w.names.push_back("w" + std::to_string(k));
    w.truth.push_back(T_map_world.inverse());
  }
  return w;
}

std::vector<std::optional<MapPrior>> noisy_priors(const Windows& w, double sd_deg, double sd_m,
                                                  std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<std::optional<MapPrior>> priors;
  for (const Isometry3& T : w.truth) {
    const Vec3 phi = sd_deg * kRadPerDeg * Vec3(g(rng), g(rng), g(rng));
    Isometry3 D = Isometry3::Identity();
    D.linear() = Eigen::AngleAxisd(phi.norm(), phi.normalized()).toRotationMatrix();
    D.translation() = sd_m * Vec3(g(rng), g(rng), g(rng));
    MapPrior p;
    p.T_world_map = D * T;
    p.covariance.setZero();
    const double r = sd_deg * kRadPerDeg;
    p.covariance.diagonal() << sd_m * sd_m, sd_m * sd_m, sd_m * sd_m, r * r, r * r, r * r;
    priors.push_back(p);
  }
  return priors;
}

// Maps within max_deg / max_m; edges judged true within the 5 deg / edge_m (a 1 deg
// error moves a frame origin 3 m away by 5 cm, so an edge's own error is larger than a map's).
void expect_placed(const Windows& w, const MergeRun& run, double max_deg, double max_m,
                   double edge_m, bool one_component = true, bool check_edges = true) {
  ASSERT_FALSE(run.cancelled);
  const MergeEvaluation ev = evaluate_merge(run.result, run.edges, w.truth, {max_deg, max_m});
  const MergeEvaluation edges = evaluate_merge(run.result, run.edges, w.truth, {5.0, edge_m});
  if (one_component) EXPECT_EQ(run.result.num_components, 1u);
  for (std::size_t i = 0; i < w.maps.size(); ++i) {
    // In several parts, only the largest is placed; each is checked in its own frame.
    const MapError& e = ev.maps[i];
    EXPECT_TRUE(one_component
                    ? e.within
                    : e.connected && e.rotation_deg <= max_deg && e.translation_m <= max_m)
        << w.names[i] << ": " << e.rotation_deg << " deg, " << e.translation_m << " m";
  }
  EXPECT_EQ(ev.num_parts, run.result.num_components);
  if (check_edges) EXPECT_EQ(edges.false_kept_edges, 0u);
  std::size_t used = 0;
  for (const EdgeReport& e : run.result.edges) used += e.used ? 1 : 0;
  std::cout << "  " << w.maps.size() << " maps, " << run.edges.size() << " pairs, " << used
            << " used, within " << ev.fraction_within << ", max " << ev.max_rotation_deg
            << " deg / " << ev.max_translation_m << " m, precision " << ev.edge_precision
            << ", recall " << ev.edge_recall << ", edges " << run.seconds_edges << " s\n";
}

const char* kDesk = "tum_fr1_desk/ground_truth_pair/map_fr1_desk_gt.txt";
const char* kKitti = "kitti_stereo_vo/kitti_vo_full.txt";

// The three stella_vslam maps of one video (real monocular maps, each of its own arbitrary
// scale; ../shared/data/real_formats/stella_openhps_aist_living_lab_1): merged without priors on
// the Sim(3) pose graph, against the similarities SOURCE.md estimated from matching keyframes
// (an estimate: its own cycle closes to 0.1% in scale). World: the frame of 4683e8ac.
TEST(MergeReal, StellaMapsOfOneVideoMergeOnASim3Graph) {
  const std::string dir = "real_formats/stella_openhps_aist_living_lab_1/";
  const std::vector<std::string> names{"356a5a6e", "94eb7149", "4683e8ac"};
  std::vector<Map> maps;
  for (const std::string& n : names) {
    const std::string path = test::data_file(dir + n + "/map.msg");
    LMALIGN_REQUIRE_FILE(path);
    maps.push_back(read_any_map(path));
    ASSERT_NE(maps.back().header.scale, MapScale::kMetric) << n;
  }
  auto similarity = [](double s, const Mat3& R, const Vec3& t) {
    Isometry3 T = Isometry3::Identity();
    T.linear() = R;
    T.translation() = t;
    return Similarity3{s, T};
  };
  Mat3 R_356_4683, R_94_4683;
  R_356_4683 << 0.999826, 0.01738, -0.006787, -0.017191, 0.999489, 0.026942, 0.007252, -0.026821,
      0.999614;
  R_94_4683 << 0.999738, 0.021504, -0.007805, -0.021262, 0.999328, 0.029848, 0.008441, -0.029675,
      0.999524;
  const std::vector<Similarity3> truth{
      similarity(0.79165, R_356_4683, Vec3(-0.003697, -0.008522, 0.128970)),
      similarity(1.06574, R_94_4683, Vec3(-0.005149, -0.005160, 0.153141)), Similarity3{}};
  const MergeRun run =
      run_merge(maps, names, std::vector<std::optional<MapPrior>>(maps.size()), {});
  ASSERT_FALSE(run.cancelled);
  EXPECT_EQ(run.result.num_components, 1u);
  for (const Edge& e : run.edges) {
    EXPECT_TRUE(e.scale_free);
    EXPECT_TRUE(e.trusted) << e.trust_reason;
  }
  // Translations in the world's units: its landmarks' median distance from their centre is
  // about 1.3, so 0.02 is 1.5% of it.
  const MergeEvaluation ev = evaluate_merge(run.result, run.edges, truth, {1.0, 0.02, 0.01});
  for (std::size_t i = 0; i < maps.size(); ++i) {
    EXPECT_TRUE(ev.maps[i].within)
        << names[i] << ": " << ev.maps[i].rotation_deg << " deg, " << ev.maps[i].translation_m
        << ", scale error " << ev.maps[i].scale_error;
  }
  EXPECT_DOUBLE_EQ(ev.pair_fraction_within, 1.0);
  EXPECT_LT(ev.max_pair_scale_error, 0.01);
  std::cout << "  stella: scales";
  for (const MapPose& p : run.result.maps)
    std::cout << " " << p.scale << " (sd " << p.scale_sd << ")";
  std::cout << "; max errors " << ev.max_rotation_deg << " deg, " << ev.max_translation_m
            << ", scale maps " << ev.max_scale_error << ", pairs " << ev.max_pair_scale_error
            << "; edges " << run.seconds_edges << " s, graph " << run.seconds_graph << " s\n";
}

TEST(MergeReal, DeskWindowsWithoutPriors) {
  const std::string path = test::data_file(kDesk);
  LMALIGN_REQUIRE_FILE(path);
  // 4 windows of 30 frames (6 pairs, every pair aligned globally); the 8-window case is in
  // configs/merge_desk.yaml (28 pairs: a benchmark, not a unit test).
  const Windows w = cut(read_map(path, MapReadOptions{0}), 0, 30, 30, 4, 21);
  const MergeRun run =
      run_merge(w.maps, w.names, std::vector<std::optional<MapPrior>>(w.maps.size()), {});
  // Known gap (docs/merge.md): consecutive 30-frame windows of this map share no frame and ~1%
  // of their landmarks, and the default's complete search finds, for most pairs, a distinct
  // pose scoring nearly as well as the best (measured 2026-11-23: frames 30-59 / 60-89 answer a
  // pose 149 deg off, its rival scores 93%): the verdict refuses them as ambiguous, so the graph
  // stays in parts. Since the first pass (2026-11-25) the pairs 0-29 / 30-59 and 60-89 / 90-119
  // are trusted from the correspondence poses alone, 2.1-2.2 deg off (4-6 cm at the landmarks;
  // the vote's rival 20 deg away at 87% refused the second before).
  // Checked: at least one edge is kept; every window a kept edge reaches is placed within
  // 2 deg / 5 cm in its part; no kept edge is false (5 deg, and 0.25 m at the target origin:
  // the windows are moved up to 3 m from it, where 5 deg is 0.26 m); only the largest part
  // counts as placed.
  ASSERT_FALSE(run.cancelled);
  const MergeEvaluation ev = evaluate_merge(run.result, run.edges, w.truth, {2.0, 0.05});
  const MergeEvaluation edges = evaluate_merge(run.result, run.edges, w.truth, {5.0, 0.25});
  std::size_t used = 0;
  for (const EdgeReport& e : run.result.edges) used += e.used ? 1 : 0;
  EXPECT_GE(used, 1u);
  EXPECT_EQ(edges.false_kept_edges, 0u);
  std::size_t connected = 0;
  for (std::size_t i = 0; i < w.maps.size(); ++i) {
    const MapError& e = ev.maps[i];
    if (!e.connected) continue;
    ++connected;
    EXPECT_LE(e.rotation_deg, 2.0) << w.names[i];
    EXPECT_LE(e.translation_m, 0.05) << w.names[i];
  }
  EXPECT_GE(connected, 2u);
  EXPECT_EQ(ev.num_parts, run.result.num_components);
  EXPECT_EQ(ev.placed, ev.largest_part);
  EXPECT_DOUBLE_EQ(ev.fraction_within,
                   static_cast<double>(ev.largest_part) / static_cast<double>(w.maps.size()));
}

TEST(MergeReal, DeskEightWindowsWithOdometryPriors) {
  const std::string path = test::data_file(kDesk);
  LMALIGN_REQUIRE_FILE(path);
  const Windows w = cut(read_map(path, MapReadOptions{0}), 0, 30, 30, 8, 22);
  const std::vector<std::optional<MapPrior>> priors = noisy_priors(w, 3.0, 0.1, 5);
  // Planned as a fleet's (more maps than all_pairs_max_maps): its prior edges take
  // init.prior_complete_search = check, whose edges and map errors here are those of rescue
  // (the default for 8 maps) to the last digit printed below, in 40% of the time (measured
  // 2026-11-27: 20 s against 50 s). Rescue on real windows: KittiWindowsWithOdometryPriors.
  MergeOptions options;
  options.candidates.all_pairs_max_maps = 7;
  const MergeRun run = run_merge(w.maps, w.names, priors, options);
  ASSERT_FALSE(run.cancelled);
  EXPECT_EQ(run.result.num_components, 1u);
  // Known gap (docs/merge.md): the target is 2 deg / 5 cm for every window. Consecutive
  // 30-frame windows of this map share only ~1% of their landmarks, and the alignment optimum
  // of two of them lies 1-2 deg from the motion-capture truth (the map's own inconsistency).
  // Issue 41: every prior edge is checked by the maps' own search, so no edge the maps place
  // elsewhere is trusted. With the prior's search alone (init.prior_check=off, the merge's
  // default until 2026-11-26) two edges 8.7 and 16.5 deg off were trusted (the cycle check then
  // rejected them); now 8 edges are trusted, each within 2.6 deg (measured 2026-11-26), and the
  // four right edges the maps cannot tell from a far pose are refused. Checked: every trusted
  // edge in the right basin (5 deg: the windows disagree by 1-3.6 deg non-rigidly); the windows
  // of the largest piece the kept edges join end no worse than their priors (beyond 0.5 deg and
  // 2 cm); a window outside it keeps a prior-level error (measured: three windows end at 2.1-5.4
  // deg against priors 0.9-4.4 deg off, in the frame fitted to the others); the merge improves
  // on the priors on average.
  const MergeEvaluation ev = evaluate_merge(run.result, run.edges, w.truth, {2.0, 0.05});
  std::vector<std::size_t> piece(w.maps.size());
  for (std::size_t i = 0; i < piece.size(); ++i) piece[i] = i;
  auto root = [&](std::size_t i) {
    while (piece[i] != i) i = piece[i];
    return i;
  };
  std::size_t trusted = 0;
  for (std::size_t e = 0; e < run.edges.size(); ++e) {
    const Edge& edge = run.edges[e];
    if (!edge.trusted) continue;
    ++trusted;
    const TransformError err = transform_error(
        edge.T_target_source, w.truth[edge.target].inverse() * w.truth[edge.source]);
    EXPECT_LE(err.rotation_deg, 5.0) << edge.source << " -> " << edge.target;
    if (run.result.edges[e].used && !run.result.edges[e].rejected) {
      piece[root(edge.source)] = root(edge.target);
    }
  }
  EXPECT_GE(trusted, 5u);
  std::map<std::size_t, std::size_t> sizes;
  for (std::size_t i = 0; i < piece.size(); ++i) ++sizes[root(i)];
  const std::size_t largest =
      std::max_element(sizes.begin(), sizes.end(), [](const auto& a, const auto& b) {
        return a.second < b.second;
      })->first;
  EXPECT_GE(sizes[largest], 4u);
  double prior_sum_deg = 0.0, merged_sum_deg = 0.0;
  for (std::size_t i = 0; i < w.maps.size(); ++i) {
    const TransformError prior = transform_error(priors[i]->T_world_map, w.truth[i]);
    prior_sum_deg += prior.rotation_deg;
    merged_sum_deg += ev.maps[i].rotation_deg;
    if (root(i) == largest) {
      EXPECT_LE(ev.maps[i].rotation_deg, std::max(2.0, prior.rotation_deg + 0.5)) << w.names[i];
      EXPECT_LE(ev.maps[i].translation_m, std::max(0.05, prior.translation_m + 0.02)) << w.names[i];
    }
    std::cout << "  " << w.names[i] << (root(i) == largest ? "" : " (outside the largest piece)")
              << ": prior " << prior.rotation_deg << " deg / " << prior.translation_m
              << " m, merged " << ev.maps[i].rotation_deg << " deg / " << ev.maps[i].translation_m
              << " m\n";
  }
  // The edges improve on the odometry: measured mean rotation error 2.06 deg against the
  // priors' 3.11 deg. (Translations are errors of the frame origins, moved up to 3 m from the
  // data, so a 1 deg error already moves them 5 cm: docs/merge.md.)
  EXPECT_LT(merged_sum_deg, 0.8 * prior_sum_deg);
}

TEST(MergeReal, KittiWindowsWithoutPriors) {
  const std::string path = test::data_file(kKitti);
  LMALIGN_REQUIRE_FILE(path);
  const Windows w = cut(read_map(path, MapReadOptions{0}), 1, 6, 5, 5, 23);
  const MergeRun run =
      run_merge(w.maps, w.names, std::vector<std::optional<MapPrior>>(w.maps.size()), {});
  expect_placed(w, run, 2.0, 0.5, 1.0);
}

// Priors of 3 deg / 0.5 m per axis: each window's prior is 4.4-9.3 deg off, and the relative
// priors of the pairs with w4 are 10-13 deg off, partly in tilt, with the windows tens of metres
// from the target's origin. The prior-bounded search finds them with its window widened by the
// rotation's lever arm and its second base (the guess tilted to agree with the maps' up axes)
// (docs/merge.md, "Edges with priors").
TEST(MergeReal, KittiWindowsWithOdometryPriors) {
  const std::string path = test::data_file(kKitti);
  LMALIGN_REQUIRE_FILE(path);
  const Windows w = cut(read_map(path, MapReadOptions{0}), 1, 6, 5, 5, 24);
  const MergeRun run = run_merge(w.maps, w.names, noisy_priors(w, 3.0, 0.5, 6), {});
  expect_placed(w, run, 2.0, 0.5, 1.0);
}

}  // namespace
}  // namespace lmalign
