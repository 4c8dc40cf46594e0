// stella_vslam / OpenVSLAM map database reader (include/lmalign/map/formats/stella_vslam.hpp).
// MessagePack is decoded by nlohmann::json::from_msgpack, the codec stella_vslam writes with.
#include "lmalign/map/formats/stella_vslam.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "lmalign/core/error.hpp"
#include "text_tokens.hpp"

namespace lmalign {

namespace {

using Json = nlohmann::json;

class Reader {
 public:
  explicit Reader(std::string name) : name_(std::move(name)) {}

  [[noreturn]] void fail(const std::string& where, const std::string& detail) const {
    throw ParseError(name_, 0, where + ": " + detail);
  }
  const Json& member(const Json& object, const char* key, const std::string& where) const {
    if (!object.is_object()) fail(where, "expected a map");
    const auto it = object.find(key);
    if (it == object.end()) fail(where, std::string("missing field '") + key + "'");
    return *it;
  }
  double number(const Json& value, const std::string& where) const {
    if (!value.is_number()) fail(where, "expected a number, got " + std::string(value.type_name()));
    const double v = value.get<double>();
    if (!std::isfinite(v)) fail(where, "is not finite");
    return v;
  }
  double number(const Json& object, const char* key, const std::string& where) const {
    return number(member(object, key, where), where + "." + key);
  }
  long long integer(const Json& value, const std::string& where) const {
    if (!value.is_number_integer()) {
      fail(where, "expected an integer, got " + std::string(value.type_name()));
    }
    if (value.is_number_unsigned() &&
        value.get<std::uint64_t>() > static_cast<std::uint64_t>(INT64_MAX)) {
      fail(where, "integer out of range");
    }
    return value.get<long long>();
  }
  std::vector<double> numbers(const Json& object, const char* key, std::size_t count,
                              const std::string& where) const {
    const Json& array = member(object, key, where);
    const std::string at = where + "." + key;
    if (!array.is_array() || array.size() != count) {
      fail(at, "expected an array of " + std::to_string(count) + " numbers");
    }
    std::vector<double> out;
    for (std::size_t i = 0; i < count; ++i) {
      out.push_back(number(array[i], at + "[" + std::to_string(i) + "]"));
    }
    return out;
  }
  Id id_of_key(const std::string& key, const std::string& what) const {
    Id id = 0;
    const auto [ptr, ec] = std::from_chars(key.data(), key.data() + key.size(), id);
    if (ec != std::errc() || ptr != key.data() + key.size() || id < 0 || key.empty()) {
      fail(what + " " + formats_detail::quoted(key), "expected a non-negative integer id as key");
    }
    return id;
  }

 private:
  std::string name_;
};

/// A camera of the map database: its model as stored (`raw`, the camera of `keypts`) and the
/// camera of its undistorted keypoints (`undistorted`, the camera of `undist_keypts`): stella_vslam
/// undistorts perspective, fisheye and radial-division keypoints onto the pinhole (fx, fy, cx,
/// cy), and leaves equirectangular ones as they are.
struct StellaCamera {
  CameraIntrinsics raw;
  CameraIntrinsics undistorted;
  /// setup_type: Monocular -> false, Stereo / RGBD -> true; nullopt if absent or unknown.
  std::optional<bool> metric;
};

/// stella_vslam's model names: model_type_to_string writes "Perspective", "Fisheye",
/// "Equirectangular", "RadialDivision"; its YAML configs say "perspective", ... "radial_division".
std::string model_key(std::string name) {
  std::string out;
  for (const char c : name) {
    if (c != '_') out.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
  }
  return out;
}

StellaCamera read_camera(const Reader& r, const Json& camera, const std::string& where) {
  const Json& model = r.member(camera, "model_type", where);
  const std::string name = model.is_string() ? model.get<std::string>() : "";
  const std::string key = model_key(name);
  if (key != "perspective" && key != "fisheye" && key != "equirectangular" &&
      key != "radialdivision") {
    r.fail(where + ".model_type",
           "unknown camera model " +
               (model.is_string() ? formats_detail::quoted(name) : std::string(model.type_name())) +
               " (known: perspective, fisheye, equirectangular, radial_division)");
  }
  StellaCamera out;
  CameraIntrinsics& k = out.raw;
  k.width_px = r.integer(r.member(camera, "cols", where), where + ".cols");
  k.height_px = r.integer(r.member(camera, "rows", where), where + ".rows");
  if (k.width_px < 0 || k.height_px < 0 || k.width_px > 1000000 || k.height_px > 1000000) {
    r.fail(where, "image size " + std::to_string(k.width_px) + "x" + std::to_string(k.height_px) +
                      " is outside [0, 1000000] px");
  }
  if (key == "equirectangular") {
    k.model = CameraModel::kEquirectangular;
    k.params = {static_cast<double>(k.width_px), static_cast<double>(k.height_px)};
  } else {
    const double fx = r.number(camera, "fx", where);
    const double fy = r.number(camera, "fy", where);
    const double cx = r.number(camera, "cx", where);
    const double cy = r.number(camera, "cy", where);
    if (key == "perspective") {
      const double k1 = r.number(camera, "k1", where);
      const double k2 = r.number(camera, "k2", where);
      const double p1 = r.number(camera, "p1", where);
      const double p2 = r.number(camera, "p2", where);
      const double k3 = r.number(camera, "k3", where);
      if (k3 != 0.0) {
        k.model = CameraModel::kFullOpenCv;  // OpenCV's k3: FULL_OPENCV with k4 = k5 = k6 = 0
        k.params = {fx, fy, cx, cy, k1, k2, p1, p2, k3, 0.0, 0.0, 0.0};
      } else if (k1 == 0.0 && k2 == 0.0 && p1 == 0.0 && p2 == 0.0) {
        k.model = CameraModel::kPinhole;
        k.params = {fx, fy, cx, cy};
      } else {
        k.model = CameraModel::kOpenCv;
        k.params = {fx, fy, cx, cy, k1, k2, p1, p2};
      }
    } else if (key == "fisheye") {
      k.model = CameraModel::kOpenCvFisheye;  // cv::fisheye, as COLMAP's OPENCV_FISHEYE
      k.params = {fx,
                  fy,
                  cx,
                  cy,
                  r.number(camera, "k1", where),
                  r.number(camera, "k2", where),
                  r.number(camera, "k3", where),
                  r.number(camera, "k4", where)};
    } else {
      k.model = CameraModel::kDivision;  // x_u = x_d / (1 + k |x_d|^2), as COLMAP's DIVISION
      k.params = {fx, fy, cx, cy, r.number(camera, "distortion", where)};
    }
    out.undistorted.model = CameraModel::kPinhole;
    out.undistorted.params = {fx, fy, cx, cy};
  }
  std::string why;
  if (!k.is_valid(&why)) r.fail(where, why);
  if (k.model == CameraModel::kEquirectangular) {
    out.undistorted = k;
  } else {
    out.undistorted.width_px = k.width_px;
    out.undistorted.height_px = k.height_px;
  }
  const auto setup = camera.find("setup_type");
  if (setup != camera.end() && setup->is_string()) {
    const std::string value = model_key(setup->get<std::string>());
    if (value == "monocular") out.metric = false;
    if (value == "stereo" || value == "rgbd") out.metric = true;
  }
  return out;
}

/// A keypoint's pixel: {pt: [x, y], ...} (stella_vslam's convert_keypoints_to_json) or [x, y]
/// (some versions' undist_keypts).
std::vector<double> keypoint_pixel(const Reader& r, const Json& keypoint,
                                   const std::string& where) {
  if (keypoint.is_array()) {
    if (keypoint.size() != 2) r.fail(where, "expected [x, y] or {pt: [x, y]}");
    return {r.number(keypoint[0], where + "[0]"), r.number(keypoint[1], where + "[1]")};
  }
  return r.numbers(keypoint, "pt", 2, where);
}

}  // namespace

Map read_stella_vslam_bytes(std::string_view bytes, const std::string& name) {
  Json root;
  try {
    root = Json::from_msgpack(bytes.begin(), bytes.end());
  } catch (const Json::exception& e) {
    // nlohmann's messages carry "at byte N"; keep them, prefixed for our format.
    std::size_t at = 0;
    if (const auto* pe = dynamic_cast<const Json::parse_error*>(&e)) at = pe->byte;
    throw ParseError(name, 0,
                     "byte " + std::to_string(at) +
                         ": not a complete MessagePack map database (expected one MessagePack "
                         "map): " +
                         e.what());
  }
  const Reader r(name);
  const std::string top = "map database";

  std::unordered_map<std::string, StellaCamera> cameras;
  const Json& json_cameras = r.member(root, "cameras", top);
  if (!json_cameras.is_object()) r.fail("cameras", "expected a map of camera name -> camera");
  for (const auto& [camera_name, camera] : json_cameras.items()) {
    cameras.emplace(camera_name,
                    read_camera(r, camera, "camera " + formats_detail::quoted(camera_name)));
  }

  // The scale: metric when every camera is a stereo or RGB-D setup, arbitrary when one is
  // monocular, unknown when a camera does not say.
  Map map;
  map.header.scale = MapScale::kMetric;
  for (const auto& [camera_name, camera] : cameras) {
    if (!camera.metric) {
      if (map.header.scale == MapScale::kMetric) map.header.scale = MapScale::kUnknown;
    } else if (!*camera.metric) {
      map.header.scale = MapScale::kArbitrary;
    }
  }
  if (cameras.empty()) map.header.scale = MapScale::kUnknown;
  const Json& json_landmarks = r.member(root, "landmarks", top);
  if (!json_landmarks.is_object()) r.fail("landmarks", "expected a map of id -> landmark");
  std::map<Id, const Json*> landmarks_by_id;
  for (const auto& [key, landmark] : json_landmarks.items()) {
    landmarks_by_id.emplace(r.id_of_key(key, "landmark"), &landmark);
  }
  std::unordered_map<Id, std::size_t> landmark_at;
  for (const auto& [id, landmark] : landmarks_by_id) {
    Landmark l;
    l.id = id;
    const std::vector<double> p =
        r.numbers(*landmark, "pos_w", 3, "landmark " + std::to_string(id));
    l.p_world = Vec3(p[0], p[1], p[2]);
    l.covariance_unknown = true;
    landmark_at.emplace(id, map.landmarks.size());
    map.landmarks.push_back(std::move(l));
  }

  const Json& json_keyframes = r.member(root, "keyframes", top);
  if (!json_keyframes.is_object()) r.fail("keyframes", "expected a map of id -> keyframe");
  std::map<Id, const Json*> keyframes_by_id;
  for (const auto& [key, keyframe] : json_keyframes.items()) {
    keyframes_by_id.emplace(r.id_of_key(key, "keyframe"), &keyframe);
  }
  for (const auto& [id, keyframe] : keyframes_by_id) {
    const std::string where = "keyframe " + std::to_string(id);
    const Json& cam = r.member(*keyframe, "cam", where);
    if (!cam.is_string() || cameras.find(cam.get<std::string>()) == cameras.end()) {
      r.fail(where + ".cam", "names no camera of the map's 'cameras'");
    }
    const std::vector<double> q = r.numbers(*keyframe, "rot_cw", 4, where);
    const std::vector<double> t = r.numbers(*keyframe, "trans_cw", 3, where);
    Quat q_camera_world(q[3], q[0], q[1], q[2]);  // stored x y z w
    const double norm = q_camera_world.norm();
    if (!(std::abs(norm - 1.0) <= 1e-3)) {
      r.fail(where + ".rot_cw", "quaternion norm is " + std::to_string(norm) +
                                    ", expected 1 (x y z w, world-to-camera)");
    }
    q_camera_world.normalize();
    Frame frame;
    frame.id = id;
    frame.q_world_camera = q_camera_world.conjugate();
    frame.p_world_camera = -(q_camera_world.conjugate() * Vec3(t[0], t[1], t[2]));
    // Raw keypoints (OpenVSLAM) where the keyframe has them, else the undistorted ones that
    // stella_vslam writes alone; the frame's camera is the one of the pixels read.
    const bool raw = keyframe->is_object() && keyframe->contains("keypts");
    const char* keypts_key = raw ? "keypts" : "undist_keypts";
    const StellaCamera& camera = cameras.at(cam.get<std::string>());
    frame.camera = raw ? camera.raw : camera.undistorted;
    map.frames.push_back(frame);

    const Json& keypts = r.member(*keyframe, keypts_key, where);
    const Json& lm_ids = r.member(*keyframe, "lm_ids", where);
    if (!keypts.is_array() || !lm_ids.is_array() || keypts.size() != lm_ids.size()) {
      r.fail(where, std::string("expected arrays ") + keypts_key +
                        " and lm_ids of the same length (one landmark id per keypoint), got " +
                        std::to_string(keypts.is_array() ? keypts.size() : 0) + " and " +
                        std::to_string(lm_ids.is_array() ? lm_ids.size() : 0));
    }
    for (std::size_t i = 0; i < lm_ids.size(); ++i) {
      const std::string at = where + ".lm_ids[" + std::to_string(i) + "]";
      const long long landmark_id = r.integer(lm_ids[i], at);
      if (landmark_id < 0) continue;
      const auto it = landmark_at.find(landmark_id);
      if (it == landmark_at.end())
        r.fail(at, "names unknown landmark " + std::to_string(landmark_id));
      const std::vector<double> pt =
          keypoint_pixel(r, keypts[i], where + "." + keypts_key + "[" + std::to_string(i) + "]");
      map.landmarks[it->second].observations.push_back({id, pt[0], pt[1]});
    }
  }
  return map;
}

Map read_stella_vslam(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError("cannot open stella_vslam map database '" + path + "'");
  return read_stella_vslam_bytes(formats_detail::slurp(in, path), path);
}

}  // namespace lmalign
