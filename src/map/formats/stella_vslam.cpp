// stella_vslam / OpenVSLAM map database reader (include/lmalign/map/formats/stella_vslam.hpp).
// MessagePack is decoded by nlohmann::json::from_msgpack, the codec stella_vslam writes with.
#include "lmalign/map/formats/stella_vslam.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
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

CameraIntrinsics read_camera(const Reader& r, const Json& camera, const std::string& where) {
  const Json& model = r.member(camera, "model_type", where);
  if (!model.is_string() || model.get<std::string>() != "perspective") {
    r.fail(where + ".model_type",
           "unknown camera model " +
               (model.is_string() ? formats_detail::quoted(model.get<std::string>())
                                  : std::string(model.type_name())) +
               " (expected perspective)");
  }
  CameraIntrinsics k;
  k.width_px = r.integer(r.member(camera, "cols", where), where + ".cols");
  k.height_px = r.integer(r.member(camera, "rows", where), where + ".rows");
  const double fx = r.number(camera, "fx", where);
  const double fy = r.number(camera, "fy", where);
  const double cx = r.number(camera, "cx", where);
  const double cy = r.number(camera, "cy", where);
  const double k1 = r.number(camera, "k1", where);
  const double k2 = r.number(camera, "k2", where);
  const double p1 = r.number(camera, "p1", where);
  const double p2 = r.number(camera, "p2", where);
  const double k3 = r.number(camera, "k3", where);
  if (k3 != 0.0) {
    r.fail(where + ".k3", "is " + std::to_string(k3) +
                              "; only k3 = 0 is supported (COLMAP's OPENCV model has no k3)");
  }
  if (k1 == 0.0 && k2 == 0.0 && p1 == 0.0 && p2 == 0.0) {
    k.model = CameraModel::kPinhole;
    k.params = {fx, fy, cx, cy};
  } else {
    k.model = CameraModel::kOpenCv;
    k.params = {fx, fy, cx, cy, k1, k2, p1, p2};
  }
  std::string why;
  if (!k.is_valid(&why)) r.fail(where, why);
  return k;
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

  std::unordered_map<std::string, CameraIntrinsics> cameras;
  const Json& json_cameras = r.member(root, "cameras", top);
  if (!json_cameras.is_object()) r.fail("cameras", "expected a map of camera name -> camera");
  for (const auto& [camera_name, camera] : json_cameras.items()) {
    cameras.emplace(camera_name,
                    read_camera(r, camera, "camera " + formats_detail::quoted(camera_name)));
  }

  Map map;
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
    frame.camera = cameras.at(cam.get<std::string>());
    map.frames.push_back(frame);

    const Json& keypts = r.member(*keyframe, "keypts", where);
    const Json& lm_ids = r.member(*keyframe, "lm_ids", where);
    if (!keypts.is_array() || !lm_ids.is_array() || keypts.size() != lm_ids.size()) {
      r.fail(where,
             "expected arrays keypts and lm_ids of the same length (one landmark id per "
             "keypoint), got " +
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
          r.numbers(keypts[i], "pt", 2, where + ".keypts[" + std::to_string(i) + "]");
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
