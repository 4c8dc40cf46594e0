#include "lmalign/map/transform.hpp"

namespace lmalign {

Map transform_map(const Map& map, const Similarity3& S_new_old) {
  const Mat3 R = S_new_old.rigid.linear();
  const double s2 = S_new_old.scale * S_new_old.scale;
  Map out = map;
  for (Frame& f : out.frames) {
    Quat q(R * f.q_world_camera.toRotationMatrix());
    q.normalize();
    if (q.w() < 0.0) q.coeffs() = -q.coeffs();
    f.q_world_camera = q;
    f.p_world_camera = S_new_old * f.p_world_camera;
  }
  for (Landmark& l : out.landmarks) {
    l.p_world = S_new_old * l.p_world;
    const Mat3 cov = s2 * (R * l.cov_world_m2 * R.transpose());
    l.cov_world_m2 = 0.5 * (cov + cov.transpose());
  }
  return out;
}

}  // namespace lmalign
