// Bit-exact comparison of two maps for tests: EXPECT_TRUE(maps_identical(a, b)).
#pragma once

#include <cstdint>
#include <cstring>
#include <string>

#include <gtest/gtest.h>

#include "lmalign/map/map.hpp"

namespace lmalign::test {

inline std::uint64_t bits(double value) {
  std::uint64_t out = 0;
  std::memcpy(&out, &value, sizeof(out));
  return out;
}

/// Success if every field of every frame and landmark is equal bit for bit, in order; otherwise
/// a failure naming the first difference.
inline ::testing::AssertionResult maps_identical(const Map& a, const Map& b) {
  auto differ = [](const std::string& what) { return ::testing::AssertionFailure() << what; };
  auto same = [](double x, double y) { return bits(x) == bits(y); };
  if (a.frames.size() != b.frames.size()) return differ("frame counts differ");
  for (std::size_t i = 0; i < a.frames.size(); ++i) {
    const Frame& fa = a.frames[i];
    const Frame& fb = b.frames[i];
    const std::string at =
        "frame index " + std::to_string(i) + " (id " + std::to_string(fa.id) + ")";
    if (fa.id != fb.id) return differ(at + ": ids differ");
    for (int k = 0; k < 3; ++k) {
      if (!same(fa.p_world_camera(k), fb.p_world_camera(k))) return differ(at + ": position");
    }
    for (int k = 0; k < 4; ++k) {
      if (!same(fa.q_world_camera.coeffs()(k), fb.q_world_camera.coeffs()(k))) {
        return differ(at + ": quaternion");
      }
    }
  }
  if (a.landmarks.size() != b.landmarks.size()) return differ("landmark counts differ");
  for (std::size_t i = 0; i < a.landmarks.size(); ++i) {
    const Landmark& la = a.landmarks[i];
    const Landmark& lb = b.landmarks[i];
    const std::string at =
        "landmark index " + std::to_string(i) + " (id " + std::to_string(la.id) + ")";
    if (la.id != lb.id) return differ(at + ": ids differ");
    for (int k = 0; k < 3; ++k) {
      if (!same(la.p_world(k), lb.p_world(k))) return differ(at + ": position");
    }
    for (int k = 0; k < 9; ++k) {
      if (!same(la.cov_world_m2.data()[k], lb.cov_world_m2.data()[k])) {
        return differ(at + ": covariance");
      }
    }
    if (la.observations.size() != lb.observations.size())
      return differ(at + ": observation counts");
    for (std::size_t k = 0; k < la.observations.size(); ++k) {
      const Observation& oa = la.observations[k];
      const Observation& ob = lb.observations[k];
      if (oa.frame_id != ob.frame_id || !same(oa.u_px, ob.u_px) || !same(oa.v_px, ob.v_px)) {
        return differ(at + ": observation " + std::to_string(k));
      }
    }
  }
  return ::testing::AssertionSuccess();
}

}  // namespace lmalign::test
