// Seeded draws shared by the simulators (road_sim.cpp, street_sim.cpp, slam_sim.cpp): explicit
// formulas on std::mt19937_64, so that a seed gives the same maps with any standard library
// (<random>'s distributions are implementation-defined).
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

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

}  // namespace lmalign::sim::detail
