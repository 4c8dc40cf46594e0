// Writes a Map as a stella_vslam map database (.msg) with the test's own MessagePack encoder
// (msgpack_writer.hpp): one perspective camera, keyframes with rot_cw (x y z w) / trans_cw
// (world-to-camera), keypts and lm_ids, landmarks with pos_w. Keys in sorted order, as stella_vslam
// (nlohmann::json) writes them.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "lmalign/map/camera.hpp"
#include "lmalign/map/map.hpp"
#include "support/msgpack_writer.hpp"

namespace lmalign::test {

inline std::string stella_map_bytes(const Map& map, const PinholeIntrinsics& k) {
  // Per frame: its keypoints (u, v) and their landmark ids.
  std::map<Id, std::vector<std::pair<Observation, Id>>> keypoints;
  for (const Frame& f : map.frames) keypoints[f.id];
  for (const Landmark& l : map.landmarks) {
    for (const Observation& o : l.observations) keypoints[o.frame_id].push_back({o, l.id});
  }
  MsgpackWriter w;
  w.map_header(3);
  w.str("cameras");
  w.map_header(1);
  w.str("tum");
  w.map_header(12);
  for (const auto& [key, value] : std::vector<std::pair<std::string, double>>{{"cols", 640},
                                                                              {"cx", k.cx_px},
                                                                              {"cy", k.cy_px},
                                                                              {"fx", k.fx_px},
                                                                              {"fy", k.fy_px},
                                                                              {"k1", 0},
                                                                              {"k2", 0},
                                                                              {"k3", 0}}) {
    w.str(key);
    if (key == "cols") {
      w.integer(static_cast<std::int64_t>(value));
    } else {
      w.f64(value);
    }
  }
  w.str("model_type");
  w.str("perspective");
  w.str("p1");
  w.f64(0);
  w.str("p2");
  w.f64(0);
  w.str("rows");
  w.integer(480);
  w.str("keyframes");
  w.map_header(static_cast<std::uint32_t>(map.frames.size()));
  for (const Frame& f : map.frames) {
    w.str(std::to_string(f.id));
    w.map_header(5);
    w.str("cam");
    w.str("tum");
    w.str("keypts");
    const auto& kp = keypoints[f.id];
    w.array_header(static_cast<std::uint32_t>(kp.size()));
    for (const auto& [obs, id] : kp) {
      w.map_header(3);
      w.str("ang");
      w.f64(0);
      w.str("oct");
      w.integer(0);
      w.str("pt");
      w.array_header(2);
      w.f64(obs.u_px);
      w.f64(obs.v_px);
    }
    w.str("lm_ids");
    w.array_header(static_cast<std::uint32_t>(kp.size()));
    for (const auto& entry : kp) w.integer(entry.second);
    const Quat q_cw = f.q_world_camera.normalized().conjugate();
    const Vec3 t_cw = -(q_cw * f.p_world_camera);
    w.str("rot_cw");
    w.array_header(4);
    for (double v : {q_cw.x(), q_cw.y(), q_cw.z(), q_cw.w()}) w.f64(v);
    w.str("trans_cw");
    w.array_header(3);
    for (int i = 0; i < 3; ++i) w.f64(t_cw(i));
  }
  w.str("landmarks");
  w.map_header(static_cast<std::uint32_t>(map.landmarks.size()));
  for (const Landmark& l : map.landmarks) {
    w.str(std::to_string(l.id));
    w.map_header(2);
    w.str("n_vis");
    w.integer(static_cast<std::int64_t>(l.observations.size()));
    w.str("pos_w");
    w.array_header(3);
    for (int i = 0; i < 3; ++i) w.f64(l.p_world(i));
  }
  return w.bytes();
}

}  // namespace lmalign::test
