// Bundler v0.3 reader (include/lmalign/map/formats/bundler.hpp; conventions in
// docs/map-format.md, "Bundler").
#include "lmalign/map/formats/bundler.hpp"

#include <cmath>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "lmalign/core/error.hpp"
#include "text_tokens.hpp"

namespace lmalign {

namespace {

using formats_detail::TokenReader;

constexpr std::string_view kHeader = "# Bundle file v0.3";
// Smallest text of one camera (15 numbers, each at least 1 byte plus a separator) and of one
// point (3 + 3 numbers and a view count): counts beyond what the file can hold are refused
// before anything is allocated.
constexpr std::size_t kMinCameraBytes = 15 * 2;
constexpr std::size_t kMinPointBytes = 7 * 2;
constexpr std::size_t kMinViewBytes = 4 * 2;

}  // namespace

Map read_bundler(std::istream& in, const std::string& name, const BundlerReadOptions& options) {
  const bool sized = options.width_px != 0 || options.height_px != 0;
  if (sized && (options.width_px <= 0 || options.height_px <= 0)) {
    throw InvalidArgument("Bundler image size " + std::to_string(options.width_px) + "x" +
                          std::to_string(options.height_px) +
                          ": width_px and height_px must both be > 0, or both 0 (unknown: the "
                          "pixels stay relative to the image centre)");
  }
  const std::string text = formats_detail::slurp(in, name);
  const std::size_t eol = text.find('\n');
  std::string_view first(text.data(), eol == std::string::npos ? text.size() : eol);
  if (!first.empty() && first.back() == '\r') first.remove_suffix(1);
  if (first != kHeader) {
    throw ParseError(
        name, 1, "expected the header '# Bundle file v0.3', got " + formats_detail::quoted(first));
  }
  TokenReader tokens(std::string_view(text).substr(first.size()), name);
  const long long kMaxCount = std::numeric_limits<int>::max();
  const auto num_cameras = static_cast<std::size_t>(tokens.integer("num_cameras", 0, kMaxCount));
  const auto num_points = static_cast<std::size_t>(tokens.integer("num_points", 0, kMaxCount));
  if (num_cameras > tokens.remaining_bytes() / kMinCameraBytes ||
      num_points > tokens.remaining_bytes() / kMinPointBytes) {
    tokens.fail("num_cameras " + std::to_string(num_cameras) + " and num_points " +
                std::to_string(num_points) + " cannot fit in the " +
                std::to_string(tokens.remaining_bytes()) + " bytes that follow (truncated file?)");
  }

  // Without an image size the principal point is (0, 0): pixels (x, -y), centred, v down.
  const double w = static_cast<double>(options.width_px);
  const double h = static_cast<double>(options.height_px);
  Map map;
  map.header.scale = MapScale::kArbitrary;  // structure from motion
  // D maps Bundler's camera axes (x right, y up, z backward) to ours (x right, y down, z forward).
  const Mat3 D = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  std::vector<bool> reconstructed(num_cameras, false);
  for (std::size_t c = 0; c < num_cameras; ++c) {
    const std::string cam = "camera " + std::to_string(c) + " ";
    const double f = tokens.number(cam + "f");
    const double k1 = tokens.number(cam + "k1");
    const double k2 = tokens.number(cam + "k2");
    Mat3 R;
    for (int r = 0; r < 3; ++r) {
      for (int col = 0; col < 3; ++col) {
        R(r, col) = tokens.number(cam + "R" + std::to_string(r) + std::to_string(col));
      }
    }
    Vec3 t;
    for (int i = 0; i < 3; ++i) t(i) = tokens.number(cam + "t" + std::to_string(i));
    if (f == 0.0) continue;  // Bundler writes zeros for a camera it could not reconstruct
    if (!(f > 0.0)) tokens.fail(cam + "focal length f is " + std::to_string(f) + ", expected > 0");
    const double orth = (R.transpose() * R - Mat3::Identity()).cwiseAbs().maxCoeff();
    if (!(orth <= options.rotation_tolerance) || !(R.determinant() > 0.0)) {
      tokens.fail(cam + "rotation is not orthonormal with det +1 (max |R^T R - I| = " +
                  std::to_string(orth) + ", det = " + std::to_string(R.determinant()) + ")");
    }
    const Mat3 R_camera_world = D * R;
    const Vec3 t_camera_world = D * t;
    Frame frame;
    frame.id = static_cast<Id>(c);
    frame.q_world_camera = Quat(R_camera_world.transpose()).normalized();
    frame.p_world_camera = -(R_camera_world.transpose() * t_camera_world);
    CameraIntrinsics k;
    k.model = CameraModel::kRadial;
    k.width_px = options.width_px;
    k.height_px = options.height_px;
    k.params = {f, w / 2.0, h / 2.0, k1, k2};
    k.centred_pixels = !sized;
    frame.camera = k;
    map.frames.push_back(frame);
    reconstructed[c] = true;
  }

  map.landmarks.reserve(num_points);
  for (std::size_t p = 0; p < num_points; ++p) {
    const std::string pt = "point " + std::to_string(p) + " ";
    Landmark landmark;
    landmark.id = static_cast<Id>(p);
    for (int i = 0; i < 3; ++i) landmark.p_world(i) = tokens.number(pt + "xyz"[i]);
    for (int i = 0; i < 3; ++i) tokens.integer(pt + "colour", 0, 255);
    const auto n = static_cast<std::size_t>(tokens.integer(pt + "view count", 0, kMaxCount));
    if (n > tokens.remaining_bytes() / kMinViewBytes) {
      tokens.fail(pt + "view count " + std::to_string(n) + " cannot fit in the " +
                  std::to_string(tokens.remaining_bytes()) + " bytes that follow");
    }
    landmark.observations.reserve(n);
    for (std::size_t v = 0; v < n; ++v) {
      const std::string view = pt + "view " + std::to_string(v) + " ";
      const long long camera = tokens.integer(view + "camera", 0, kMaxCount);
      if (static_cast<std::size_t>(camera) >= num_cameras) {
        tokens.fail(view + "names camera " + std::to_string(camera) + " but the file has " +
                    std::to_string(num_cameras) + " cameras");
      }
      if (!reconstructed[static_cast<std::size_t>(camera)]) {
        tokens.fail(view + "names camera " + std::to_string(camera) +
                    ", which Bundler did not reconstruct (f = 0)");
      }
      tokens.integer(view + "key", 0, std::numeric_limits<long long>::max());
      const double x = tokens.number(view + "x");
      const double y = tokens.number(view + "y");
      landmark.observations.push_back({static_cast<Id>(camera), x + w / 2.0, h / 2.0 - y});
    }
    landmark.covariance_unknown = true;
    map.landmarks.push_back(std::move(landmark));
  }
  if (!tokens.at_end()) {
    tokens.fail("unexpected content after the " + std::to_string(num_points) +
                " points declared in the header");
  }
  return map;
}

Map read_bundler(const std::string& path, const BundlerReadOptions& options) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot open Bundler file '" + path + "'");
  return read_bundler(in, path, options);
}

}  // namespace lmalign
