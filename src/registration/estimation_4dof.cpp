#include "lmalign/registration/estimation_4dof.hpp"

#include <cmath>

#include "lmalign/core/error.hpp"

namespace lmalign {

namespace {
/// Indices (u, v, w) of a right-handed frame whose third axis is `up`.
void axes(UpAxis up, int* u, int* v, int* w) {
  switch (up) {
    case UpAxis::kX:
      *u = 1, *v = 2, *w = 0;
      return;
    case UpAxis::kY:
      *u = 2, *v = 0, *w = 1;
      return;
    case UpAxis::kZ:
      break;
  }
  *u = 0, *v = 1, *w = 2;
}
}  // namespace

std::string to_string(UpAxis axis) { return name_of(kUpAxisNames, axis); }

UpAxis parse_up_axis(const std::string& name) { return parse_enum(kUpAxisNames, "up axis", name); }

Mat3 rotation_about_up(UpAxis axis, double angle_rad) {
  int u, v, w;
  axes(axis, &u, &v, &w);
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
                                  const std::vector<double>* weights, UpAxis up) {
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
  int u, v, w;
  axes(up, &u, &v, &w);
  double sin_sum = 0.0, cos_sum = 0.0;
  for (std::size_t i = 0; i < correspondences.size(); ++i) {
    const double wi = weights ? (*weights)[i] : 1.0;
    const Vec3 a = source_points[correspondences[i].source_index] - ms;
    const Vec3 b = target_points[correspondences[i].target_index] - mt;
    sin_sum += wi * (a[u] * b[v] - a[v] * b[u]);
    cos_sum += wi * (a[u] * b[u] + a[v] * b[v]);
  }
  const double theta = (sin_sum == 0.0 && cos_sum == 0.0) ? 0.0 : std::atan2(sin_sum, cos_sum);
  Isometry3 T = Isometry3::Identity();
  T.linear() = rotation_about_up(up, theta);
  T.translation() = mt - T.linear() * ms;
  return T;
}

}  // namespace lmalign
