// split_map(): mini-map extraction by frame window (method.md §6), on a seeded synthetic map.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include "lmalign/core/error.hpp"
#include "lmalign/map/split.hpp"
#include "lmalign/weights/weights.hpp"

namespace lmalign {
namespace {

bool bit_identical(const Vec3& a, const Vec3& b) {
  return std::memcmp(a.data(), b.data(), sizeof(double) * 3) == 0;
}
bool bit_identical(const Mat3& a, const Mat3& b) {
  return std::memcmp(a.data(), b.data(), sizeof(double) * 9) == 0;
}

// Ten frames (ids 0..9, stored out of order) on a line along x, 0.1 m apart, looking along +z
// with a small tilt; 200 landmarks 2-4 m in front with noiseless pixels from random frame
// subsets; plus special landmarks with ids >= 1000 (see below).
struct SyntheticMap {
  Map map;
  std::unordered_map<Id, Vec3> true_position;
};

SyntheticMap make_map(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const PinholeIntrinsics k = PinholeIntrinsics::tum_fr1();
  SyntheticMap s;
  for (Id id : {5, 0, 9, 2, 7, 1, 3, 8, 4, 6}) {
    Frame f;
    f.id = id;
    f.p_world_camera = Vec3(0.1 * static_cast<double>(id), 0.02 * unit(rng), 0.0);
    f.q_world_camera =
        Quat(Eigen::AngleAxisd(0.05 * unit(rng), Vec3(unit(rng), unit(rng), 1.0).normalized()));
    s.map.frames.push_back(f);
  }
  auto observe = [&](const Vec3& p, Id frame_id) {
    const Frame& f = *std::find_if(s.map.frames.begin(), s.map.frames.end(),
                                   [&](const Frame& fr) { return fr.id == frame_id; });
    const Eigen::Vector2d uv = k.project(f.T_world_camera().inverse() * p);
    return Observation{frame_id, uv.x(), uv.y()};
  };
  for (Id id = 0; id < 200; ++id) {
    Landmark l;
    l.id = 3 * id + 7;  // non-contiguous ids
    const Vec3 p(0.5 + 1.2 * unit(rng), 0.8 * unit(rng), 3.0 + unit(rng));
    s.true_position[l.id] = p;
    // The stored estimate is off the truth by ~0.1 mm so that copying and re-estimating differ.
    l.p_world = p + 1e-4 * Vec3(unit(rng), unit(rng), unit(rng));
    Eigen::Matrix3d a = Eigen::Matrix3d::Random() * 1e-3;
    l.cov_world_m2 = a * a.transpose() + Mat3::Identity() * 1e-7 * (1.0 + std::abs(unit(rng)));
    std::vector<Id> order = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
    std::shuffle(order.begin(), order.end(), rng);
    const int n = 1 + static_cast<int>(rng() % 8);
    for (int i = 0; i < n; ++i) l.observations.push_back(observe(p, order[i]));
    s.map.landmarks.push_back(l);
  }
  // 1000: far away (200 m), seen by frames 2 and 3 only: parallax ~0.03 deg.
  {
    Landmark l;
    l.id = 1000;
    const Vec3 p(0.25, 0.0, 200.0);
    l.p_world = s.true_position[l.id] = p;
    l.cov_world_m2 = Mat3::Identity();
    l.observations = {observe(p, 2), observe(p, 3)};
    s.map.landmarks.push_back(l);
  }
  // 1001: rays of frames 2 and 3 that diverge (they meet behind the cameras): triangulation fails.
  {
    Landmark l;
    l.id = 1001;
    l.p_world = Vec3(0.25, 0.0, 2.0);
    l.cov_world_m2 = Mat3::Identity() * 1e-4;
    l.observations = {{2, k.cx_px - 80.0, k.cy_px}, {3, k.cx_px + 80.0, k.cy_px}};
    s.map.landmarks.push_back(l);
  }
  // 1002: only outside the window [2, 6]; 1003: one observation inside it.
  {
    Landmark l;
    l.id = 1002;
    l.p_world = Vec3(0.5, 0.0, 3.0);
    l.cov_world_m2 = Mat3::Identity() * 1e-4;
    l.observations = {observe(l.p_world, 0), observe(l.p_world, 9), observe(l.p_world, 8)};
    s.map.landmarks.push_back(l);
    l.id = 1003;
    l.observations = {observe(l.p_world, 0), observe(l.p_world, 4), observe(l.p_world, 8)};
    s.map.landmarks.push_back(l);
  }
  return s;
}

SplitOptions window(Id first, Id last) {
  SplitOptions o;
  o.first_frame_id = first;
  o.last_frame_id = last;
  return o;
}

const Landmark* find_landmark(const Map& map, Id id) {
  for (const Landmark& l : map.landmarks) {
    if (l.id == id) return &l;
  }
  return nullptr;
}

std::size_t window_count(const Landmark& l, Id first, Id last) {
  return static_cast<std::size_t>(std::count_if(
      l.observations.begin(), l.observations.end(),
      [&](const Observation& o) { return o.frame_id >= first && o.frame_id <= last; }));
}

TEST(Split, KeepsTheWindowFramesInTheirOriginalOrder) {
  const SyntheticMap s = make_map(1);
  SplitStats stats;
  const Map out = split_map(s.map, window(2, 6), &stats);
  std::vector<Id> ids;
  for (const Frame& f : out.frames) ids.push_back(f.id);
  EXPECT_EQ(ids, (std::vector<Id>{5, 2, 3, 4, 6}));  // the input order, filtered
  EXPECT_EQ(stats.frames_kept, 5u);
  for (const Frame& f : out.frames) {
    const Frame* original = s.map.find_frame(f.id);
    ASSERT_NE(original, nullptr);
    EXPECT_TRUE(bit_identical(f.p_world_camera, original->p_world_camera));
    EXPECT_EQ(f.q_world_camera.coeffs(), original->q_world_camera.coeffs());
  }
  EXPECT_NO_THROW(out.validate());
}

TEST(Split, RestrictsObservationsAndKeepsStoredEstimatesBitForBit) {
  const SyntheticMap s = make_map(2);
  const Id first = 2;
  const Id last = 6;
  SplitStats stats;
  const Map out = split_map(s.map, window(first, last), &stats);

  std::size_t expected_kept = 0;
  std::size_t expected_too_few = 0;
  std::size_t expected_outside = 0;
  for (const Landmark& original : s.map.landmarks) {
    const std::size_t n = window_count(original, first, last);
    const Landmark* kept = find_landmark(out, original.id);
    if (n == 0) {
      ++expected_outside;
      EXPECT_EQ(kept, nullptr);
      continue;
    }
    if (n < 2) {
      ++expected_too_few;
      EXPECT_EQ(kept, nullptr) << "landmark " << original.id;
      continue;
    }
    ++expected_kept;
    ASSERT_NE(kept, nullptr) << "landmark " << original.id;
    EXPECT_TRUE(bit_identical(kept->p_world, original.p_world)) << "landmark " << original.id;
    EXPECT_TRUE(bit_identical(kept->cov_world_m2, original.cov_world_m2));
    // The window's observations, in their original order, values untouched.
    std::vector<Observation> expected;
    for (const Observation& o : original.observations) {
      if (o.frame_id >= first && o.frame_id <= last) expected.push_back(o);
    }
    ASSERT_EQ(kept->observations.size(), expected.size());
    EXPECT_EQ(kept->num_observations(), n);  // the count is the window's
    for (std::size_t i = 0; i < expected.size(); ++i) {
      EXPECT_EQ(kept->observations[i].frame_id, expected[i].frame_id);
      EXPECT_EQ(kept->observations[i].u_px, expected[i].u_px);
      EXPECT_EQ(kept->observations[i].v_px, expected[i].v_px);
    }
  }
  EXPECT_EQ(stats.landmarks_kept, expected_kept);
  EXPECT_EQ(out.landmarks.size(), expected_kept);
  EXPECT_EQ(stats.dropped_too_few_observations, expected_too_few);
  EXPECT_EQ(stats.landmarks_outside_window, expected_outside);
  EXPECT_EQ(stats.dropped_low_parallax, 0u);
  EXPECT_EQ(stats.dropped_triangulation_failed, 0u);
  EXPECT_NE(find_landmark(out, 1000), nullptr);  // default mode never triangulates
  EXPECT_NE(find_landmark(out, 1001), nullptr);
  EXPECT_EQ(find_landmark(out, 1002), nullptr);
  EXPECT_EQ(find_landmark(out, 1003), nullptr);
  EXPECT_GT(expected_kept, 50u);
  EXPECT_GT(expected_too_few, 10u);
  EXPECT_NO_THROW(out.validate());
}

TEST(Split, LandmarkOrderAndIdsArePreserved) {
  const SyntheticMap s = make_map(3);
  const Map out = split_map(s.map, window(0, 9));
  // Whole range: every landmark with >= 2 observations, in input order.
  std::vector<Id> expected;
  for (const Landmark& l : s.map.landmarks) {
    if (l.observations.size() >= 2) expected.push_back(l.id);
  }
  std::vector<Id> got;
  for (const Landmark& l : out.landmarks) got.push_back(l.id);
  EXPECT_EQ(got, expected);
}

TEST(Split, MeanObservationDistanceIsTheWindows) {
  const SyntheticMap s = make_map(4);
  const Map out = split_map(s.map, window(2, 6));
  std::size_t changed = 0;
  for (const Landmark& kept : out.landmarks) {
    double sum = 0.0;
    std::size_t n = 0;
    for (const Observation& o : find_landmark(s.map, kept.id)->observations) {
      if (o.frame_id < 2 || o.frame_id > 6) continue;
      sum += (kept.p_world - s.map.find_frame(o.frame_id)->p_world_camera).norm();
      ++n;
    }
    const double window_mean = sum / static_cast<double>(n);
    EXPECT_NEAR(mean_observation_distance_m(kept, out), window_mean, 1e-12);
    const double full_mean = mean_observation_distance_m(*find_landmark(s.map, kept.id), s.map);
    if (std::abs(full_mean - window_mean) > 1e-9) ++changed;
  }
  EXPECT_GT(changed, 10u);  // the restriction changes D for landmarks seen outside the window
}

TEST(Split, MinObservationsThreshold) {
  const SyntheticMap s = make_map(5);
  for (std::size_t min_obs : {1u, 2u, 3u, 5u}) {
    SplitOptions o = window(1, 7);
    o.min_observations = min_obs;
    SplitStats stats;
    const Map out = split_map(s.map, o, &stats);
    std::size_t expected = 0;
    for (const Landmark& l : s.map.landmarks) {
      if (window_count(l, 1, 7) >= min_obs) ++expected;
    }
    EXPECT_EQ(out.landmarks.size(), expected) << "min_observations " << min_obs;
    for (const Landmark& l : out.landmarks) EXPECT_GE(l.observations.size(), min_obs);
    EXPECT_EQ(
        stats.landmarks_kept + stats.dropped_too_few_observations + stats.landmarks_outside_window,
        s.map.landmarks.size());
  }
}

TEST(Split, EmptyWindowGivesAnEmptyMap) {
  const SyntheticMap s = make_map(6);
  SplitStats stats;
  const Map out = split_map(s.map, window(50, 60), &stats);
  EXPECT_TRUE(out.frames.empty());
  EXPECT_TRUE(out.landmarks.empty());
  EXPECT_EQ(stats.landmarks_outside_window, s.map.landmarks.size());
}

TEST(Split, RetriangulateReproducesNoiselessPositions) {
  const SyntheticMap s = make_map(7);
  SplitOptions o = window(2, 6);
  o.retriangulate = true;
  o.min_parallax_deg = 2.0;
  SplitStats stats;
  const Map out = split_map(s.map, o, &stats);
  ASSERT_GT(out.landmarks.size(), 50u);
  for (const Landmark& l : out.landmarks) {
    EXPECT_LT((l.p_world - s.true_position.at(l.id)).norm(), 1e-6) << "landmark " << l.id;
    // The covariance is the triangulation's, not the stored one: SPD, mm-level for 3 m depth.
    EXPECT_FALSE(bit_identical(l.cov_world_m2, find_landmark(s.map, l.id)->cov_world_m2));
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Mat3>(l.cov_world_m2).eigenvalues()(0), 0.0);
    EXPECT_EQ(l.observations.size(), window_count(*find_landmark(s.map, l.id), 2, 6));
  }
  // 1000 (200 m, 0.03 deg) is dropped for parallax, 1001 (diverging rays) for triangulation.
  EXPECT_EQ(find_landmark(out, 1000), nullptr);
  EXPECT_EQ(find_landmark(out, 1001), nullptr);
  EXPECT_GE(stats.dropped_low_parallax, 1u);
  EXPECT_EQ(stats.dropped_triangulation_failed, 1u);
  EXPECT_EQ(stats.landmarks_kept, out.landmarks.size());
  EXPECT_EQ(stats.landmarks_kept + stats.dropped_too_few_observations +
                stats.landmarks_outside_window + stats.dropped_low_parallax +
                stats.dropped_triangulation_failed,
            s.map.landmarks.size());

  // With the parallax filter off, the far landmark is kept (and still exact without noise).
  o.min_parallax_deg = 0.0;
  SplitStats all_stats;
  const Map all = split_map(s.map, o, &all_stats);
  EXPECT_EQ(all_stats.dropped_low_parallax, 0u);
  const Landmark* far = find_landmark(all, 1000);
  ASSERT_NE(far, nullptr);
  EXPECT_LT((far->p_world - s.true_position.at(1000)).norm(), 1e-4);
  EXPECT_EQ(all.landmarks.size(), out.landmarks.size() + stats.dropped_low_parallax);
}

TEST(Split, LowParallaxDropCountsEveryLandmarkBelowTheThreshold) {
  const SyntheticMap s = make_map(8);
  SplitOptions o = window(2, 3);  // 0.1 m baseline at 2-4 m depth: parallax ~1.4-2.9 degrees
  o.retriangulate = true;
  o.min_parallax_deg = 0.0;
  const Map all = split_map(s.map, o);
  std::size_t below = 0;
  for (const Landmark& l : all.landmarks) {
    const Vec3 a = l.p_world - s.map.find_frame(2)->p_world_camera;
    const Vec3 b = l.p_world - s.map.find_frame(3)->p_world_camera;
    const double deg = std::atan2(a.cross(b).norm(), a.dot(b)) * 180.0 / 3.14159265358979323846;
    if (deg < 2.0) ++below;
  }
  ASSERT_GT(below, 0u);
  o.min_parallax_deg = 2.0;
  SplitStats stats;
  const Map filtered = split_map(s.map, o, &stats);
  EXPECT_EQ(stats.dropped_low_parallax, below);
  EXPECT_EQ(filtered.landmarks.size(), all.landmarks.size() - below);
}

void expect_invalid(const SplitOptions& o, const std::string& field) {
  std::string why;
  EXPECT_FALSE(o.is_valid(&why)) << field;
  EXPECT_NE(why.find(field), std::string::npos) << "why = " << why;
  const SyntheticMap s = make_map(9);
  try {
    split_map(s.map, o);
    ADD_FAILURE() << "no exception for " << field;
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
  }
}

TEST(Split, InvalidOptionsNameTheField) {
  SplitOptions o = window(120, 5);
  std::string why;
  EXPECT_FALSE(o.is_valid(&why));
  EXPECT_EQ(why, "first_frame_id (120) > last_frame_id (5)");
  expect_invalid(o, "first_frame_id (120) > last_frame_id (5)");
  expect_invalid(window(-1, 5), "first_frame_id");

  o = window(0, 5);
  o.min_observations = 0;
  expect_invalid(o, "min_observations");
  o = window(0, 5);
  o.retriangulate = true;
  o.min_observations = 1;
  expect_invalid(o, "min_observations");

  for (double bad : {-1.0, std::nan(""), std::numeric_limits<double>::infinity(), 181.0}) {
    o = window(0, 5);
    o.min_parallax_deg = bad;
    expect_invalid(o, "min_parallax_deg");
  }
  o = window(0, 5);
  o.triangulation.intrinsics.fx_px = 0.0;
  expect_invalid(o, "fx_px");
  o = window(0, 5);
  o.triangulation.intrinsics.cy_px = std::nan("");
  expect_invalid(o, "cy_px");
  for (double bad : {0.0, -1.0, std::nan("")}) {
    o = window(0, 5);
    o.triangulation.pixel_sigma_px = bad;
    expect_invalid(o, "pixel_sigma_px");
  }
  o = window(0, 5);
  o.triangulation.max_iterations = -1;
  expect_invalid(o, "max_iterations");

  EXPECT_TRUE(window(3, 3).is_valid());
}

TEST(Split, UnknownFrameInTheWindowIsAnError) {
  SyntheticMap s = make_map(10);
  s.map.landmarks[0].observations.push_back({42, 100.0, 100.0});
  EXPECT_THROW(split_map(s.map, window(40, 45)), InvalidArgument);
}

TEST(Intrinsics, ParseAndValidate) {
  const PinholeIntrinsics k = PinholeIntrinsics::parse("517.3, 516.5,318.6,255.3");
  EXPECT_EQ(k.fx_px, 517.3);
  EXPECT_EQ(k.fy_px, 516.5);
  EXPECT_EQ(k.cx_px, 318.6);
  EXPECT_EQ(k.cy_px, 255.3);
  EXPECT_TRUE(k.is_valid());
  for (const char* bad : {"", "1,2,3", "1,2,3,4,5", "1,,3,4", "a,2,3,4", "1,2,3,4x", "0,1,2,3",
                          "1,-1,2,3", "1,1,nan,3", "1e999,1,1,1"}) {
    EXPECT_THROW(PinholeIntrinsics::parse(bad), InvalidArgument) << bad;
  }
  try {
    PinholeIntrinsics::parse("1,2,x,4");
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("1,2,x,4"), std::string::npos);
  }
  std::string why;
  EXPECT_FALSE((PinholeIntrinsics{1.0, -2.0, 0.0, 0.0}).is_valid(&why));
  EXPECT_NE(why.find("fy_px"), std::string::npos);
}

}  // namespace
}  // namespace lmalign
