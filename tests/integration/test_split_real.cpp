// split_map() on the real TUM fr1/desk map (method.md §1, §6).
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <unordered_map>
#include <vector>

#include <gtest/gtest.h>

#include "lmalign/map/map_io.hpp"
#include "lmalign/map/split.hpp"
#include "support/data_path.hpp"

namespace lmalign {
namespace {

const Map& real_map() {
  // All landmarks, all observations: split must see observations of single-view landmarks too.
  static const Map map = [] {
    MapReadOptions options;
    options.min_observations = 0;
    return read_map(test::data_file("tum_fr1_desk/map_fr1_desk.txt"), options);
  }();
  return map;
}

double percentile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  const std::size_t i = static_cast<std::size_t>(q * static_cast<double>(values.size() - 1) + 0.5);
  return values[std::min(i, values.size() - 1)];
}

TEST(SplitReal, DefaultModeKeepsStoredLandmarksExactly) {
  const std::string path = test::data_file("tum_fr1_desk/map_fr1_desk.txt");
  LMALIGN_REQUIRE_FILE(path);
  const Map& map = real_map();
  ASSERT_EQ(map.frames.size(), 240u);
  ASSERT_EQ(map.landmarks.size(), 22338u);

  SplitOptions options;
  options.first_frame_id = 0;
  options.last_frame_id = 119;
  SplitStats stats;
  const Map out = split_map(map, options, &stats);
  EXPECT_EQ(out.frames.size(), 120u);
  EXPECT_EQ(stats.frames_kept, 120u);
  for (const Frame& f : out.frames) {
    EXPECT_GE(f.id, 0);
    EXPECT_LE(f.id, 119);
  }
  std::unordered_map<Id, const Landmark*> original;
  for (const Landmark& l : map.landmarks) original[l.id] = &l;

  // Landmarks with >= 2 observations in frames 0-119 (the ground-truth pair's desk_gt_a, which
  // additionally requires the last observation in the window, has 3,050).
  std::size_t expected = 0;
  for (const Landmark& l : map.landmarks) {
    const auto n = std::count_if(l.observations.begin(), l.observations.end(),
                                 [](const Observation& o) { return o.frame_id <= 119; });
    if (n >= 2) ++expected;
  }
  EXPECT_EQ(out.landmarks.size(), expected);
  EXPECT_GE(out.landmarks.size(), 3050u);
  EXPECT_EQ(
      stats.landmarks_kept + stats.dropped_too_few_observations + stats.landmarks_outside_window,
      map.landmarks.size());

  for (const Landmark& l : out.landmarks) {
    const Landmark& o = *original.at(l.id);
    ASSERT_EQ(std::memcmp(l.p_world.data(), o.p_world.data(), 3 * sizeof(double)), 0) << l.id;
    ASSERT_EQ(std::memcmp(l.cov_world_m2.data(), o.cov_world_m2.data(), 9 * sizeof(double)), 0)
        << l.id;
    ASSERT_GE(l.observations.size(), 2u);
    for (const Observation& obs : l.observations) {
      ASSERT_GE(obs.frame_id, 0);
      ASSERT_LE(obs.frame_id, 119);
    }
  }
  EXPECT_NO_THROW(out.validate());
}

// With --retriangulate, the well-conditioned landmarks (>= 3 window observations, max parallax
// >= 10 degrees) are re-estimated from the window's pixels alone, with the stored odometry poses,
// and compared with the stored positions (RGB-D back-projections from each landmark's last frame).
//
// Measured (Release build, fr1/desk):
//   frames   0-119: 101 landmarks, median 6.2 mm, p90 16.4 mm, p99 47 mm, max 55 mm
//   frames 120-239: 203 landmarks, median 6.5 mm, p90 19.8 mm, p99 47 mm, max 77 mm
// Why mm and not better: the 0.05 px median of method.md is over all observations, most of which
// are the landmark's own last (exact) observation or single-view landmarks. The stored positions
// reproject into the other window observations at a median of 0.44-0.50 px (p90 1.5-1.9 px), which
// at ~0.95 m depth, f = 517 px and 10-20 degrees of parallax is ~2-5 mm in depth; the stored
// depth itself is one Kinect measurement (a few mm of noise at 1 m). The error plateaus at ~6 mm
// above 5 degrees of parallax (median 7.6 / 5.8 mm for 5-10 degrees), which is that depth noise.
// Bounds: median < 10 mm and p90 < 25 mm (about 1.5x and 1.3x the worst window measured).
// The code is deterministic, so the margin only guards against legitimate algorithm changes.
TEST(SplitReal, RetriangulationReproducesWellConditionedLandmarks) {
  const std::string path = test::data_file("tum_fr1_desk/map_fr1_desk.txt");
  LMALIGN_REQUIRE_FILE(path);
  const Map& map = real_map();
  std::unordered_map<Id, const Landmark*> original;
  for (const Landmark& l : map.landmarks) original[l.id] = &l;

  struct Window {
    Id first;
    Id last;
    std::size_t min_landmarks;  // measured 101 and 203
  };
  for (const Window& w : {Window{0, 119, 90}, Window{120, 239, 180}}) {
    SCOPED_TRACE("frames " + std::to_string(w.first) + "-" + std::to_string(w.last));
    SplitOptions options;
    options.first_frame_id = w.first;
    options.last_frame_id = w.last;
    options.retriangulate = true;
    options.min_observations = 3;
    options.min_parallax_deg = 10.0;
    SplitStats stats;
    const Map out = split_map(map, options, &stats);

    std::vector<double> errors_m;
    for (const Landmark& l : out.landmarks) {
      ASSERT_GE(l.observations.size(), 3u);
      errors_m.push_back((l.p_world - original.at(l.id)->p_world).norm());
    }
    ASSERT_GE(errors_m.size(), w.min_landmarks);
    const double median = percentile(errors_m, 0.5);
    const double p90 = percentile(errors_m, 0.9);
    std::printf(
        "frames %lld-%lld: retriangulated %zu landmarks (low parallax %zu, failed %zu): "
        "error median %.4f m, p90 %.4f m, max %.4f m\n",
        static_cast<long long>(w.first), static_cast<long long>(w.last), errors_m.size(),
        stats.dropped_low_parallax, stats.dropped_triangulation_failed, median, p90,
        percentile(errors_m, 1.0));
    EXPECT_LT(median, 0.010);
    EXPECT_LT(p90, 0.025);
  }
}

}  // namespace
}  // namespace lmalign
