// The map-reader fuzz oracle, shared by the libFuzzer target (fuzz_map_reader.cpp) and the
// regression test that replays fuzz/regressions/map_reader/ in every test build
// (tests/unit/test_degenerate_fuzz_regressions.cpp). docs/robustness.md describes it.
//
// For any bytes:
//   - read_map either throws lmalign::Error or returns a map. Any other exception, a crash, a
//     sanitizer report, a leak or a hang is a bug.
//   - A returned map is valid (Map::validate), writes and reads back bit-exactly, has finite
//     non-negative weights of every kind, and:
//   - ICP of the map onto itself (small maps) returns a finite proper rigid transform with a
//     termination reason, for the four strategies;
//   - split_map (stored and re-triangulated) returns a map that write_map accepts.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>

#include "lmalign/core/error.hpp"
#include "lmalign/core/geometry.hpp"
#include "lmalign/map/map_io.hpp"
#include "lmalign/map/split.hpp"
#include "lmalign/registration/presets.hpp"
#include "lmalign/registration/registration.hpp"
#include "lmalign/weights/weights.hpp"

namespace lmalign::fuzz {

/// An oracle violation: print it and abort, so libFuzzer (and gtest) report the input.
#define LMALIGN_FUZZ_CHECK(condition, what)                                                \
  do {                                                                                     \
    if (!(condition)) {                                                                    \
      std::fprintf(stderr, "lmalign fuzz oracle violated: %s (%s:%d)\n", (what), __FILE__, \
                   __LINE__);                                                              \
      std::abort();                                                                        \
    }                                                                                      \
  } while (0)

/// Longest line the fuzzed reader accepts: small, so that the limit itself is exercised.
inline constexpr std::size_t kFuzzMaxLineBytes = 4096;
/// ICP and split run only on maps up to this size (keeps one input well under a millisecond).
inline constexpr std::size_t kFuzzMaxLandmarksForIcp = 64;

inline bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

inline bool maps_identical(const Map& a, const Map& b) {
  if (a.frames.size() != b.frames.size() || a.landmarks.size() != b.landmarks.size()) return false;
  for (std::size_t i = 0; i < a.frames.size(); ++i) {
    const Frame& fa = a.frames[i];
    const Frame& fb = b.frames[i];
    if (fa.id != fb.id) return false;
    for (int k = 0; k < 3; ++k) {
      if (!same_bits(fa.p_world_camera(k), fb.p_world_camera(k))) return false;
    }
    for (int k = 0; k < 4; ++k) {
      if (!same_bits(fa.q_world_camera.coeffs()(k), fb.q_world_camera.coeffs()(k))) return false;
    }
  }
  for (std::size_t i = 0; i < a.landmarks.size(); ++i) {
    const Landmark& la = a.landmarks[i];
    const Landmark& lb = b.landmarks[i];
    if (la.id != lb.id || la.observations.size() != lb.observations.size()) return false;
    for (int k = 0; k < 3; ++k) {
      if (!same_bits(la.p_world(k), lb.p_world(k))) return false;
    }
    for (int k = 0; k < 9; ++k) {
      if (!same_bits(la.cov_world_m2.data()[k], lb.cov_world_m2.data()[k])) return false;
    }
    for (std::size_t k = 0; k < la.observations.size(); ++k) {
      const Observation& oa = la.observations[k];
      const Observation& ob = lb.observations[k];
      if (oa.frame_id != ob.frame_id || !same_bits(oa.u_px, ob.u_px) ||
          !same_bits(oa.v_px, ob.v_px)) {
        return false;
      }
    }
  }
  return true;
}

inline bool is_proper_rigid(const Isometry3& T) {
  if (!is_finite(T)) return false;
  const Mat3 R = T.linear();
  return (R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff() < 1e-6 &&
         std::abs(R.determinant() - 1.0) < 1e-6;
}

inline bool within_coordinate_range(const Points3& points) {
  for (const Vec3& p : points) {
    if (!(p.cwiseAbs().maxCoeff() <= kMaxCoordinateM)) return false;
  }
  return true;
}

/// ICP of the map onto itself, from a small displacement, with each strategy.
inline void check_icp(const Map& map) {
  const Points3 points = map.positions();
  const PreparedTarget target(map);
  const bool in_range = within_coordinate_range(points);
  for (const WeightKind weight : {WeightKind::kUniform, WeightKind::kCovariance,
                                  WeightKind::kObservations, WeightKind::kMeanDistance}) {
    // The engine itself (it refuses what align() of presets.hpp would leave out).
    PipelineSpec spec = find_preset(weight == WeightKind::kUniform        ? "base"
                                    : weight == WeightKind::kCovariance   ? "covariance"
                                    : weight == WeightKind::kObservations ? "observations"
                                                                          : "distance")
                            .spec;
    if (weight != WeightKind::kUniform) spec.settings.emplace_back("match.k", 3LL);
    spec.settings.emplace_back("schedule.max_iterations", 10LL);
    SourceView view;
    view.positions = &points;
    PipelineRequest request;
    request.initial_guess = pose_from_xyz_rpy_deg(0.01, -0.02, 0.01, 1, -1, 2);
    try {
      const RegistrationResult r = Pipeline(spec).run(view, target, request).registration;
      LMALIGN_FUZZ_CHECK(is_proper_rigid(r.T_target_source), "ICP transform not finite/rigid");
      LMALIGN_FUZZ_CHECK(r.termination != TerminationReason::kNotTerminated,
                         "ICP returned without a termination reason");
      LMALIGN_FUZZ_CHECK(!std::isnan(r.final_score_m2) && !std::isnan(r.initial_score_m2),
                         "ICP score is NaN");
    } catch (const InvalidArgument&) {
      // Only a coordinate beyond kMaxCoordinateM may be refused.
      LMALIGN_FUZZ_CHECK(!in_range, "align refused a valid map within the coordinate range");
    }
  }
}

/// split_map over the map's whole frame-id range, stored and re-triangulated: the result must be
/// a map that write_map accepts.
inline void check_split(const Map& map) {
  if (map.frames.empty()) return;
  Id first = map.frames.front().id;
  Id last = first;
  for (const Frame& f : map.frames) {
    first = std::min(first, f.id);
    last = std::max(last, f.id);
  }
  for (const bool retriangulate : {false, true}) {
    SplitOptions options;
    options.first_frame_id = first;
    options.last_frame_id = last;
    options.min_observations = 2;
    options.retriangulate = retriangulate;
    options.min_parallax_deg = 0.0;
    const Map out = split_map(map, options);
    std::string problem;
    try {
      std::ostringstream sink;
      out.validate();
      write_map(sink, out);
      std::istringstream again(sink.str());
      MapReadOptions keep_all;
      keep_all.min_observations = 0;
      const Map back = read_map(again, "split-roundtrip", keep_all);
      LMALIGN_FUZZ_CHECK(back.landmarks.size() == out.landmarks.size(),
                         "split output does not read back");
    } catch (const Error& e) {
      std::fprintf(stderr, "split (retriangulate=%d) output rejected: %s\n",
                   static_cast<int>(retriangulate), e.what());
      LMALIGN_FUZZ_CHECK(false, "split produced a map that the reader rejects");
    }
  }
}

/// The whole oracle for one input.
inline void check_map_bytes(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  MapReadOptions options;
  options.min_observations = 0;
  options.max_line_bytes = kFuzzMaxLineBytes;
  Map map;
  try {
    std::istringstream in(text);
    map = read_map(in, "fuzz.txt", options);
  } catch (const Error&) {
    return;  // a clear refusal is a correct outcome; anything else propagates
  }

  try {
    map.validate();
  } catch (const Error& e) {
    std::fprintf(stderr, "accepted map is invalid: %s\n", e.what());
    LMALIGN_FUZZ_CHECK(false, "read_map accepted a map that Map::validate rejects");
  }

  // Write -> read is bit-exact.
  std::ostringstream out;
  write_map(out, map);
  Map back;
  try {
    std::istringstream again(out.str());
    MapReadOptions keep_all;
    keep_all.min_observations = 0;
    back = read_map(again, "roundtrip.txt", keep_all);
  } catch (const Error& e) {
    std::fprintf(stderr, "round trip rejected: %s\n", e.what());
    LMALIGN_FUZZ_CHECK(false, "write_map output of an accepted map does not read back");
  }
  LMALIGN_FUZZ_CHECK(maps_identical(map, back), "write -> read is not bit-exact");

  // The default filter keeps exactly the landmarks with >= 2 observations.
  {
    std::istringstream again(text);
    MapReadOptions filtered = options;
    filtered.min_observations = 2;
    const Map kept = read_map(again, "fuzz.txt", filtered);
    std::size_t expected = 0;
    for (const Landmark& l : map.landmarks) expected += l.num_observations() >= 2 ? 1 : 0;
    LMALIGN_FUZZ_CHECK(kept.landmarks.size() == expected, "min_observations filter miscounts");
  }

  for (const WeightKind kind : {WeightKind::kUniform, WeightKind::kCovariance,
                                WeightKind::kObservations, WeightKind::kMeanDistance}) {
    for (const double w : compute_weights(map, kind)) {
      LMALIGN_FUZZ_CHECK(std::isfinite(w) && w >= 0.0, "a weight is negative or not finite");
    }
  }
  WeightOptions frobenius;
  frobenius.covariance_norm = CovarianceNorm::kFrobenius;
  for (const double w : compute_weights(map, WeightKind::kCovariance, frobenius)) {
    LMALIGN_FUZZ_CHECK(std::isfinite(w) && w >= 0.0, "a Frobenius weight is not finite");
  }

  if (!map.landmarks.empty() && map.landmarks.size() <= kFuzzMaxLandmarksForIcp) {
    check_icp(map);
  }
  if (map.landmarks.size() <= kFuzzMaxLandmarksForIcp) check_split(map);
}

}  // namespace lmalign::fuzz
