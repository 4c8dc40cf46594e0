// Seeded synthetic landmark maps for tests (after COLMAP's synthetic-scene generators).
#pragma once

#include <cstdint>
#include <random>

#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map.hpp"

namespace lmalign::test {

/// Random points in an asymmetric "room": a floor, two walls and a box on the floor, plus
/// uniform clutter; metres. No symmetry, so ICP has a unique minimum.
inline Points3 room_points(std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Points3 pts;
  pts.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double pick = u(rng);
    if (pick < 0.3) {
      pts.emplace_back(4.0 * u(rng), 3.0 * u(rng), 0.0);  // floor 4 x 3
    } else if (pick < 0.5) {
      pts.emplace_back(4.0 * u(rng), 0.0, 2.5 * u(rng));  // wall y = 0
    } else if (pick < 0.65) {
      pts.emplace_back(0.0, 3.0 * u(rng), 2.5 * u(rng));  // wall x = 0
    } else if (pick < 0.85) {
      // box [1, 1.8] x [0.5, 1.1] x [0, 0.7] surface points
      const double a = u(rng), b = u(rng);
      switch (static_cast<int>(u(rng) * 3.0)) {
        case 0:
          pts.emplace_back(1.0 + 0.8 * a, 0.5 + 0.6 * b, 0.7);
          break;
        case 1:
          pts.emplace_back(1.0, 0.5 + 0.6 * a, 0.7 * b);
          break;
        default:
          pts.emplace_back(1.0 + 0.8 * a, 1.1, 0.7 * b);
          break;
      }
    } else {
      pts.emplace_back(4.0 * u(rng), 3.0 * u(rng), 2.5 * u(rng));  // clutter
    }
  }
  return pts;
}

/// A Map whose landmarks are `points`, observed by `num_frames` cameras on a circle around the
/// room centre, with seeded observation counts (1-8) and covariances growing with distance.
inline Map map_from_points(const Points3& points, std::uint32_t seed, int num_frames = 12) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> nobs(1, 8);
  std::uniform_int_distribution<int> frame(0, num_frames - 1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Map map;
  for (int f = 0; f < num_frames; ++f) {
    Frame fr;
    fr.id = 100 + 3 * f;  // non-contiguous ids
    const double a = 2.0 * M_PI * f / num_frames;
    fr.p_world_camera = Vec3(2.0 + 1.5 * std::cos(a), 1.5 + 1.2 * std::sin(a), 1.2);
    fr.q_world_camera = Quat(Eigen::AngleAxisd(a, Vec3::UnitZ()));
    map.frames.push_back(fr);
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    Landmark lm;
    lm.id = static_cast<Id>(i * 2 + 1);
    lm.p_world = points[i];
    const int n = nobs(rng);
    for (int j = 0; j < n; ++j) {
      lm.observations.push_back({map.frames[frame(rng)].id, 640.0 * u(rng), 480.0 * u(rng)});
    }
    const Vec3 axis = Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5).normalized();
    const double s = 1e-4 * (1.0 + 10.0 * u(rng));
    lm.cov_world_m2 = s * axis * axis.transpose() + 1e-6 * Mat3::Identity();
    map.landmarks.push_back(lm);
  }
  return map;
}

}  // namespace lmalign::test
