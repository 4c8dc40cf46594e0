// A seeded simulator of a SLAM-like landmark map pair (for scaling benchmarks and tests).
//
// The world is an office corridor along +x: a floor, two walls and boxes of furniture against the
// walls (sizes and places drawn per metre, so the geometry never repeats and ICP has one
// minimum). Two mapping sessions each walk a stretch of it with an RGB-D camera looking ahead and
// to the sides; they overlap by `overlap`. Each session's map has exactly `num_landmarks`
// landmarks on the surfaces, each with
//   - 2..8 observations from consecutive keyframes (pinhole pixels of the true point, with noise),
//   - a position back-projected from its last observation, with the depth noise of a structured-
//     light sensor (sigma_z = 0.0012 + 0.0019 (z - 0.4)^2 m, Nguyen et al. 2012) and 1.5 px of
//     lateral noise, and the matching covariance (along the viewing ray).
// The corridor grows with num_landmarks at constant surface density, so maps of 1k to 1M
// landmarks look alike locally: only their extent changes.
//
// The target map is in the world frame; the source map in a frame moved by T_target_source^-1,
// so that p_target = T_target_source * p_source relates the two. Deterministic for a given seed
// (and standard library: the draws use std::mt19937_64 and <random> distributions).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "lmalign/core/types.hpp"
#include "lmalign/map/map.hpp"

namespace lmalign::sim {

struct SlamSimOptions {
  /// Landmarks in each map (>= 10).
  std::size_t num_landmarks = 10000;
  std::uint64_t seed = 1;
  /// Landmarks per square metre of surface.
  double density_per_m2 = 100.0;
  /// Fraction of the source session's stretch of corridor that the target session also maps.
  double overlap = 0.8;
  /// The true transform between the two maps' frames (see above).
  Isometry3 T_target_source = Isometry3::Identity();

  /// Ceres-style check: false and the bad field named in *why.
  bool is_valid(std::string* why = nullptr) const;
};

struct SlamMapPair {
  Map source;
  Map target;
  Isometry3 T_target_source = Isometry3::Identity();  ///< p_target = T * p_source
};

/// Simulates the pair. Throws InvalidArgument on invalid options.
SlamMapPair simulate_map_pair(const SlamSimOptions& options);

}  // namespace lmalign::sim
