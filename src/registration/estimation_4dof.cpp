#include "lmalign/registration/estimation_4dof.hpp"

#include <cmath>

#include "lmalign/core/error.hpp"

namespace lmalign {

namespace {

void check_up(const Vec3& up) {
  if (!up.allFinite() || std::abs(up.norm() - 1.0) > 1e-9) {
    throw InvalidArgument("4-DoF estimation: the up axis must be a finite unit vector");
  }
}

/// Indices (u, v, w) of a right-handed frame whose third axis is the coordinate axis `up`, when
/// it is one (exactly x, y or z); false otherwise.
bool coordinate_axes(const Vec3& up, int* u, int* v, int* w) {
  if (up == Vec3::UnitX()) {
    *u = 1, *v = 2, *w = 0;
  } else if (up == Vec3::UnitY()) {
    *u = 2, *v = 0, *w = 1;
  } else if (up == Vec3::UnitZ()) {
    *u = 0, *v = 1, *w = 2;
  } else {
    return false;
  }
  return true;
}

/// Two unit axes (e_u, e_v) of the plane orthogonal to `up`, right-handed with it.
void plane_axes(const Vec3& up, Vec3* eu, Vec3* ev) {
  int u, v, w;
  if (coordinate_axes(up, &u, &v, &w)) {
    *eu = Vec3::Unit(u);
    *ev = Vec3::Unit(v);
    return;
  }
  *eu = up.unitOrthogonal();
  *ev = up.cross(*eu);
}

}  // namespace

Mat3 rotation_about_up(const Vec3& up, double angle_rad) {
  check_up(up);
  int u, v, w;
  if (!coordinate_axes(up, &u, &v, &w)) {
    return Eigen::AngleAxisd(angle_rad, up).toRotationMatrix();
  }
  const double c = std::cos(angle_rad);
  const double s = std::sin(angle_rad);
  Mat3 R = Mat3::Zero();
  R(u, u) = c;
  R(u, v) = -s;
  R(v, u) = s;
  R(v, v) = c;
  R(w, w) = 1.0;
  return R;
}

Isometry3 estimate_4dof_transform(const Points3& source_points, const Points3& target_points,
                                  const Correspondences& correspondences,
                                  const std::vector<double>* weights, const Vec3& up) {
  check_up(up);
  if (correspondences.empty()) {
    throw InvalidArgument("estimate_4dof_transform: no correspondences");
  }
  if (weights != nullptr && weights->size() != correspondences.size()) {
    throw InvalidArgument("estimate_4dof_transform: " + std::to_string(weights->size()) +
                          " weights for " + std::to_string(correspondences.size()) +
                          " correspondences");
  }
  double wsum = 0.0;
  Vec3 ms = Vec3::Zero(), mt = Vec3::Zero();
  for (std::size_t i = 0; i < correspondences.size(); ++i) {
    const double wi = weights ? (*weights)[i] : 1.0;
    if (!(wi >= 0.0) || !std::isfinite(wi)) {
      throw InvalidArgument("estimate_4dof_transform: weight " + std::to_string(i) +
                            " is negative or not finite");
    }
    wsum += wi;
    ms += wi * source_points[correspondences[i].source_index];
    mt += wi * target_points[correspondences[i].target_index];
  }
  if (!(wsum > 0.0)) throw InvalidArgument("estimate_4dof_transform: the weights sum to 0");
  ms /= wsum;
  mt /= wsum;
  // About a coordinate axis, its coordinates are read as they are (bit for bit as before).
  int u, v, w;
  const bool coordinate = coordinate_axes(up, &u, &v, &w);
  Vec3 eu, ev;
  plane_axes(up, &eu, &ev);
  double sin_sum = 0.0, cos_sum = 0.0;
  for (std::size_t i = 0; i < correspondences.size(); ++i) {
    const double wi = weights ? (*weights)[i] : 1.0;
    const Vec3 a = source_points[correspondences[i].source_index] - ms;
    const Vec3 b = target_points[correspondences[i].target_index] - mt;
    const double au = coordinate ? a[u] : a.dot(eu), av = coordinate ? a[v] : a.dot(ev);
    const double bu = coordinate ? b[u] : b.dot(eu), bv = coordinate ? b[v] : b.dot(ev);
    sin_sum += wi * (au * bv - av * bu);
    cos_sum += wi * (au * bu + av * bv);
  }
  const double theta = (sin_sum == 0.0 && cos_sum == 0.0) ? 0.0 : std::atan2(sin_sum, cos_sum);
  Isometry3 T = Isometry3::Identity();
  T.linear() = rotation_about_up(up, theta);
  T.translation() = mt - T.linear() * ms;
  return T;
}

}  // namespace lmalign
