// Seeded draws shared by the simulators (road_sim.cpp, street_sim.cpp, slam_sim.cpp): explicit
// formulas on std::mt19937_64, so that a seed gives the same maps with any standard library
// (<random>'s distributions are implementation-defined).
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

#include "lmalign/map/map.hpp"

namespace lmalign::sim::detail {

/// splitmix64's finaliser: a well-mixed 64-bit value of x (seeds of independent streams).
inline std::uint64_t mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// Uniform in [0, 1): the top 53 bits of one draw.
inline double uniform01(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

/// Standard normal by Box-Muller, one value per call (two draws).
inline double gauss(std::mt19937_64& rng) {
  const double u1 = 1.0 - uniform01(rng);  // (0, 1]
  const double u2 = uniform01(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

/// Places `lm` at the true point `P` (world frame, m) plus noise of `sigma_across_m` across and
/// `sigma_along_m` along the unit `ray` (world frame; three standard normal draws of `normal()`,
/// across first), and sets its covariance to that noise's (R diag(sa^2, sa^2, sl^2) R^T, m^2).
template <typename Normal>
void place_with_ray_noise(Landmark& lm, const Vec3& P, const Vec3& ray, double sigma_across_m,
                          double sigma_along_m, Normal&& normal) {
  Mat3 R;  // columns: two directions across the ray, then the ray
  R.col(2) = ray;
  R.col(0) = ray.unitOrthogonal();
  R.col(1) = ray.cross(R.col(0));
  const Vec3 e(sigma_across_m * normal(), sigma_across_m * normal(), sigma_along_m * normal());
  lm.p_world = P + R * e;
  lm.cov_world_m2 = R *
                    Vec3(sigma_across_m * sigma_across_m, sigma_across_m * sigma_across_m,
                         sigma_along_m * sigma_along_m)
                        .asDiagonal() *
                    R.transpose();
}

}  // namespace lmalign::sim::detail
