// The outdoor stereo road simulator (include/lmalign/sim/road_sim.hpp): the properties the
// accuracy benchmark relies on (issue 18).
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <map>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/sim/road_sim.hpp"
#include "support/invalid_options.hpp"
#include "support/sim_checks.hpp"

namespace lmalign {
namespace {

sim::RoadSimOptions small_options() {
  sim::RoadSimOptions o;
  o.num_landmarks = 1500;
  o.seed = 7;
  return o;
}

// Covariance stretched along the viewing ray of the landmark's last observation, with the
// stereo law: sigma_along = depth^2 sigma_d / (fx b), sigma_across = depth 0.5 px / fx.
TEST(RoadSim, CovarianceAlongTheRayGrowsWithRangeSquared) {
  const sim::RoadSimOptions o = small_options();
  const sim::SlamMapPair pair = sim::simulate_road_pair(o);
  const Map& map = pair.target;  // world frame
  std::map<Id, const Frame*> frames;
  for (const Frame& f : map.frames) frames[f.id] = &f;
  double near_sigma = 0.0, far_sigma = 0.0;
  std::size_t near = 0, far = 0;
  for (const Landmark& lm : map.landmarks) {
    Eigen::SelfAdjointEigenSolver<Mat3> es(lm.cov_world_m2);
    const double sigma_along = std::sqrt(es.eigenvalues()[2]);
    const double sigma_across = std::sqrt(es.eigenvalues()[0]);
    ASSERT_NEAR(es.eigenvalues()[1], es.eigenvalues()[0], 1e-9 * es.eigenvalues()[2]);
    // The depth this covariance stands for, from the across-ray sigma; the along-ray sigma
    // must follow the range-squared law at that depth.
    const double depth = sigma_across * o.fx_px / 0.5;
    EXPECT_NEAR(sigma_along, depth * depth * o.disparity_sigma_px / (o.fx_px * o.baseline_m),
                1e-6 * sigma_along);
    EXPECT_GE(depth, o.min_range_m - 1e-9);
    EXPECT_LE(depth, o.max_range_m + 1e-9);
    // The long axis points along the ray from the camera of the last observation.
    const Frame& last = *frames.at(lm.observations.back().frame_id);
    const Vec3 ray = (lm.p_world - last.p_world_camera).normalized();
    EXPECT_GT(std::abs(ray.dot(es.eigenvectors().col(2))), 0.99);
    if (depth < 10.0) {
      near_sigma = std::max(near_sigma, sigma_along);
      ++near;
    } else if (depth > 30.0) {
      far_sigma = far_sigma == 0.0 ? sigma_along : std::min(far_sigma, sigma_along);
      ++far;
    }
  }
  ASSERT_GT(near, 10u);
  ASSERT_GT(far, 10u);
  // (30 / 10)^2 = 9: every far landmark is at least 9x less certain along its ray.
  EXPECT_GT(far_sigma, 9.0 * near_sigma);
}

TEST(RoadSim, ObservationsAndFrames) {
  const sim::RoadSimOptions o = small_options();
  const sim::SlamMapPair pair = sim::simulate_road_pair(o);
  for (const Map* m : {&pair.source, &pair.target}) {
    EXPECT_EQ(m->landmarks.size(), o.num_landmarks);
    EXPECT_NO_THROW(m->validate());
    test::expect_stereo_observations(*m, o.max_observations);
  }
}

// The fraction of the source's stretch of road (its keyframes, moved to the target frame by the
// truth) that the target also drives is the overlap asked for; the maps reach max_range_m ahead.
TEST(RoadSim, OverlapFractionAsAsked) {
  for (double overlap : {0.0, 0.25, 0.5}) {
    sim::RoadSimOptions o = small_options();
    o.overlap = overlap;
    o.T_target_source = pose_from_xyz_rpy_deg(3, -1, 20, 1, 2, 30);
    const sim::SlamMapPair pair = sim::simulate_road_pair(o);
    double target_first_z = 1e9, target_last_z = -1e9;
    for (const Frame& f : pair.target.frames) {
      target_first_z = std::min(target_first_z, f.p_world_camera.z());
      target_last_z = std::max(target_last_z, f.p_world_camera.z());
    }
    EXPECT_NEAR(target_last_z - target_first_z, o.stretch_length_m, o.frame_step_m);
    std::size_t shared = 0;
    double source_last_z = -1e9;
    for (const Frame& f : pair.source.frames) {
      const double z = (pair.T_target_source * f.p_world_camera).z();
      shared += z >= target_first_z - 1e-9 ? 1 : 0;
      source_last_z = std::max(source_last_z, z);
    }
    EXPECT_NEAR(static_cast<double>(shared) / pair.source.frames.size(), overlap,
                1.5 / pair.source.frames.size())
        << "overlap " << overlap;
    // Landmarks lie ahead of the keyframes that see them, up to max_range_m beyond the stretch.
    double source_max_z = -1e9;
    for (const Landmark& lm : pair.source.landmarks)
      source_max_z = std::max(source_max_z, (pair.T_target_source * lm.p_world).z());
    EXPECT_GT(source_max_z, source_last_z + 0.5 * o.max_range_m);
  }
}

TEST(RoadSim, DeterministicPerSeed) {
  const sim::RoadSimOptions o = small_options();
  const sim::SlamMapPair a = sim::simulate_road_pair(o), b = sim::simulate_road_pair(o);
  EXPECT_EQ(a.source.positions(), b.source.positions());
  EXPECT_EQ(a.target.positions(), b.target.positions());
  sim::RoadSimOptions other = o;
  other.seed = 8;
  EXPECT_FALSE(sim::simulate_road_pair(other).target.positions() == a.target.positions());
}

// p_target = T_target_source * p_source: the source drawn under a transform is the identity
// case's source moved by T^-1 (landmarks, covariances and frames), and the target is unchanged.
TEST(RoadSim, TrueTransformRelatesTheMaps) {
  sim::RoadSimOptions o = small_options();
  const sim::SlamMapPair plain = sim::simulate_road_pair(o);
  o.T_target_source = pose_from_xyz_rpy_deg(5, 2, -30, 3, -2, 120);
  const sim::SlamMapPair moved = sim::simulate_road_pair(o);
  ASSERT_TRUE(moved.T_target_source.isApprox(o.T_target_source));
  test::expect_source_moved(plain, moved);
  for (std::size_t f = 0; f < plain.source.frames.size(); ++f) {
    EXPECT_LT((moved.T_target_source * moved.source.frames[f].p_world_camera -
               plain.source.frames[f].p_world_camera)
                  .norm(),
              1e-9);
  }
}

TEST(RoadSim, InvalidOptionsNamed) {
  using Change = test::OptionChange<sim::RoadSimOptions>;
  test::expect_each_change_named(
      small_options(), [](const sim::RoadSimOptions& o) { sim::simulate_road_pair(o); },
      {Change{[](auto& o) { o.overlap = 0.6; }, "overlap"},
       Change{[](auto& o) { o.overlap = std::nan(""); }, "overlap"},
       Change{[](auto& o) { o.num_landmarks = 3; }, "num_landmarks"},
       Change{[](auto& o) { o.min_range_m = 50.0; }, "max_range_m"},
       Change{[](auto& o) { o.max_observations = 1; }, "max_observations"}});
}

}  // namespace
}  // namespace lmalign
