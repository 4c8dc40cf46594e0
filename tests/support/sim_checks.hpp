// Checks every stereo simulator's pair must pass (road_sim.hpp, street_sim.hpp): the
// observations a landmark has, and how the true transform relates the two maps.
#pragma once

#include <cstddef>

#include <gtest/gtest.h>

#include "lmalign/map/map.hpp"
#include "lmalign/sim/slam_sim.hpp"

namespace lmalign::test {

/// Each landmark of `map` has 2..max_observations observations, from consecutive keyframes; some
/// have 2 and some have max_observations.
inline void expect_stereo_observations(const Map& map, int max_observations) {
  const auto most = static_cast<std::size_t>(max_observations);
  std::size_t with_two = 0, with_most = 0;
  for (const Landmark& lm : map.landmarks) {
    ASSERT_GE(lm.observations.size(), 2u);
    ASSERT_LE(lm.observations.size(), most);
    with_two += lm.observations.size() == 2 ? 1 : 0;
    with_most += lm.observations.size() == most ? 1 : 0;
    for (std::size_t i = 1; i < lm.observations.size(); ++i)
      EXPECT_EQ(lm.observations[i].frame_id, lm.observations[i - 1].frame_id + 1);
  }
  EXPECT_GT(with_two, 0u);
  EXPECT_GT(with_most, 0u);
}

/// `moved` was simulated as `plain` but with a true transform: its target is plain's, and its
/// source landmarks are plain's seen from the moved frame (p_target = T_target_source p_source,
/// covariances rotated alike).
inline void expect_source_moved(const sim::SlamMapPair& plain, const sim::SlamMapPair& moved) {
  EXPECT_EQ(moved.target.positions(), plain.target.positions());
  ASSERT_EQ(moved.source.landmarks.size(), plain.source.landmarks.size());
  const Mat3 R = moved.T_target_source.linear();
  for (std::size_t i = 0; i < plain.source.landmarks.size(); ++i) {
    const Landmark& p = plain.source.landmarks[i];
    const Landmark& m = moved.source.landmarks[i];
    ASSERT_LT((moved.T_target_source * m.p_world - p.p_world).norm(), 1e-9);
    ASSERT_LT((R * m.cov_world_m2 * R.transpose() - p.cov_world_m2).norm(),
              1e-9 * (1.0 + p.cov_world_m2.norm()));
  }
}

}  // namespace lmalign::test
