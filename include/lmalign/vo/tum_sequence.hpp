// TUM RGB-D sequence folders (https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats):
// rgb.txt and depth.txt ("timestamp filename" per line, '#' comments), the PNG images they name,
// and groundtruth.txt ("timestamp tx ty tz qx qy qz qw") when present. Part of lmalign::vo.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lmalign/eval/trajectory.hpp"
#include "lmalign/map/camera.hpp"

namespace lmalign::vo {

/// One entry of rgb.txt or depth.txt.
struct TimedFile {
  double timestamp_s = 0.0;
  std::string path;      ///< as resolved against the sequence folder
  std::size_t line = 0;  ///< 1-based line in the list file
};

/// One associated RGB-D pair.
struct RgbdFrameRef {
  double rgb_timestamp_s = 0.0;
  std::string rgb_path;
  double depth_timestamp_s = 0.0;
  std::string depth_path;
};

/// A TUM RGB-D sequence: the associated frames in time order and the ground truth if present.
struct TumSequence {
  std::string folder;
  std::vector<RgbdFrameRef> frames;
  std::string ground_truth_path;           ///< empty if groundtruth.txt is absent
  std::optional<Trajectory> ground_truth;  ///< read from groundtruth.txt when present
};

struct TumSequenceOptions {
  /// Largest RGB-depth time difference of an associated pair, seconds (TUM's associate.py: 0.02).
  double max_difference_s = 0.02;
  /// Read groundtruth.txt if it exists.
  bool read_ground_truth = true;
  bool is_valid(std::string* why = nullptr) const;
};

/// Reads rgb.txt / depth.txt. File names are resolved against `folder`. Throws IoError if the file
/// cannot be opened and ParseError (file, line) on a line that is not "timestamp filename", a
/// timestamp that is not a finite non-negative number, or timestamps that do not strictly
/// increase.
std::vector<TimedFile> read_tum_file_list(const std::string& list_path, const std::string& folder);

/// Associates RGB and depth entries by nearest time stamp within max_difference_s, each entry used
/// at most once (TUM's associate.py), in RGB time order.
std::vector<RgbdFrameRef> associate_rgbd(const std::vector<TimedFile>& rgb,
                                         const std::vector<TimedFile>& depth,
                                         double max_difference_s = 0.02);

/// Reads a sequence folder. Throws IoError if rgb.txt or depth.txt is missing, ParseError on
/// malformed lists or ground truth, and InvalidArgument (naming the folder) if no pair associates.
/// Images are not opened here (see build_map); only the lists are checked.
TumSequence load_tum_sequence(const std::string& folder, const TumSequenceOptions& options = {});

/// An RGB-D camera: pinhole intrinsics (no distortion), image size, depth scale.
struct RgbdCamera {
  PinholeIntrinsics pinhole = PinholeIntrinsics::tum_fr1();
  int width_px = 640;
  int height_px = 480;
  /// Depth PNG units per metre (TUM: 5000).
  double depth_units_per_m = 5000.0;
  bool is_valid(std::string* why = nullptr) const;
};

/// TUM presets, pinhole part of the published calibration (depth scale 5000, 640x480):
///   "fr1" 517.3 516.5 318.6 255.3; "fr2" 520.9 521.0 325.1 249.7; "fr3" 535.4 539.2 320.1 247.6.
/// Throws InvalidArgument for another name.
RgbdCamera tum_camera_preset(const std::string& name);

/// Reads a small YAML camera file of flat "key: value" lines: fx, fy, cx, cy (required), width,
/// height, depth_scale (optional, defaults 640, 480, 5000); '#' comments. Throws IoError if it
/// cannot be opened; ParseError (file, line) on an unknown key, a bad value, a duplicate key, or
/// (line 0) a missing required key or invalid camera.
RgbdCamera read_camera_yaml(const std::string& path);

}  // namespace lmalign::vo
