// The fuzz oracle of the readers of other map formats (Bundler, COLMAP text and binary, PLY),
// shared by fuzz_bundler_reader.cpp, fuzz_colmap_reader.cpp, fuzz_ply_reader.cpp and the
// regression test that replays
// fuzz/regressions/<target>/ and fuzz/corpus/<target>/
// (tests/unit/test_degenerate_fuzz_regressions.cpp).
//
// For any bytes the reader throws lmalign::Error or returns a map; a returned map is valid
// (Map::validate), every frame has valid intrinsics, and (after estimate_covariances() for the
// formats with observations; as read for PLY) every landmark has either a finite symmetric positive
// semi-definite covariance or the unknown flag with a zero covariance. Any other exception, a
// crash, a sanitizer report, a leak or a hang is a bug.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <string_view>

#include <Eigen/Eigenvalues>

#include "lmalign/core/error.hpp"
#include "lmalign/map/formats/bundler.hpp"
#include "lmalign/map/formats/colmap.hpp"
#include "lmalign/map/formats/formats.hpp"
#include "lmalign/map/formats/ply.hpp"
#include "lmalign/map/formats/stella_vslam.hpp"
#include "map_reader_check.hpp"  // LMALIGN_FUZZ_CHECK

namespace lmalign::fuzz {

/// Confidences are derived only for maps up to this size (one input well under a millisecond).
inline constexpr std::size_t kFuzzMaxLandmarksForCovariance = 256;

inline void check_foreign_map(Map& map, bool derive_covariances = true) {
  try {
    map.validate();
  } catch (const Error& e) {
    std::fprintf(stderr, "accepted map is invalid: %s\n", e.what());
    LMALIGN_FUZZ_CHECK(false, "reader accepted a map that Map::validate rejects");
  }
  for (const Frame& frame : map.frames) {
    LMALIGN_FUZZ_CHECK(frame.camera && frame.camera->is_valid(), "frame without valid intrinsics");
  }
  if (derive_covariances) {
    if (map.landmarks.size() > kFuzzMaxLandmarksForCovariance) return;
    estimate_covariances(map, ConfidenceOptions{});
  }
  for (const Landmark& l : map.landmarks) {
    if (l.covariance_unknown) {
      LMALIGN_FUZZ_CHECK(l.cov_world_m2 == Mat3::Zero(), "flagged but not zero");
      continue;
    }
    LMALIGN_FUZZ_CHECK(l.cov_world_m2.allFinite(), "covariance not finite");
    LMALIGN_FUZZ_CHECK(l.cov_world_m2.isApprox(l.cov_world_m2.transpose()),
                       "covariance not symmetric");
    const Eigen::SelfAdjointEigenSolver<Mat3> eig(l.cov_world_m2, Eigen::EigenvaluesOnly);
    // Derived: positive definite. Read (PLY): PSD within the reader's tolerance.
    const double tolerance =
        derive_covariances ? 0.0 : 1e-9 * std::max(1e-12, eig.eigenvalues().cwiseAbs().maxCoeff());
    LMALIGN_FUZZ_CHECK(eig.eigenvalues()(0) >= -tolerance, "covariance not PSD");
  }
}

/// Runs `read` (bytes -> Map); a clear refusal (lmalign::Error) is a correct outcome, a map is
/// checked by check_foreign_map.
template <typename Read>
void check_read(const Read& read, bool derive_covariances = true) {
  Map map;
  try {
    map = read();
  } catch (const Error&) {
    return;
  }
  check_foreign_map(map, derive_covariances);
}

inline std::string_view as_text(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

/// Bundler: the bytes are a .out file, read with a 640 x 480 image size.
inline void check_bundler_bytes(const std::uint8_t* data, std::size_t size) {
  check_read([&] {
    std::istringstream in{std::string(as_text(data, size))};
    return read_bundler(in, "fuzz.out", BundlerReadOptions{640, 480});
  });
}

/// COLMAP: the first byte's low bit chooses binary (1) or text (0); the rest is the three files
/// separated by the line "@@@" (cameras, images, points3D; missing files are empty).
inline void check_colmap_bytes(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return;
  const bool binary = (data[0] & 1) != 0;
  std::string_view rest = as_text(data + 1, size - 1);
  ColmapFiles files;
  for (int i = 0; i < 3; ++i) {
    const std::size_t cut = i < 2 ? rest.find("\n@@@\n") : std::string_view::npos;
    files.contents[i] = std::string(rest.substr(0, cut));
    rest = cut == std::string_view::npos ? std::string_view() : rest.substr(cut + 5);
  }
  check_read([&] { return read_colmap(files, binary); });
}

/// stella_vslam: the bytes are a .msg map database.
inline void check_stella_vslam_bytes(const std::uint8_t* data, std::size_t size) {
  check_read([&] { return read_stella_vslam_bytes(as_text(data, size), "fuzz.msg"); });
}

/// PLY: the bytes are a .ply file; covariances are checked as read.
inline void check_ply_bytes(const std::uint8_t* data, std::size_t size) {
  check_read(
      [&] {
        std::istringstream in{std::string(as_text(data, size))};
        return read_ply_map(in, "fuzz.ply");
      },
      false);
}

}  // namespace lmalign::fuzz
