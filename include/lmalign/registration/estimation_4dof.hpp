// Closed-form 4-DoF (x, y, z and yaw about the up axis) rigid estimation for gravity-aligned
// maps (visual-inertial SLAM, ground robots). Not in the paper.
#pragma once

#include <vector>

#include "lmalign/core/types.hpp"
#include "lmalign/registration/correspondence.hpp"

namespace lmalign {

/// The rotation by `angle_rad` about the unit axis `up` (right-handed). About a coordinate axis
/// (up exactly x, y or z) it is built entrywise, so that its up row and column are exactly that
/// axis: composing it onto any rotation leaves that rotation's up row bit-identical (roll and
/// pitch exactly unchanged). Throws InvalidArgument unless `up` is finite and of unit length
/// (to 1e-9).
Mat3 rotation_about_up(const Vec3& up, double angle_rad);

/// The transform T = [R_up(theta) | t] minimising sum_i w_i |T s_i - t_i|^2 over the
/// correspondences, where R_up is a rotation about the unit axis `up` only (the maps' shared
/// vertical, each in its own frame): closed form (the 2-D weighted Procrustes/Umeyama problem in
/// the plane orthogonal to `up`, with a_u, a_v the coordinates along two unit axes of that plane):
///   theta = atan2(sum w (a_u b_v - a_v b_u), sum w (a_u b_u + a_v b_v)) on demeaned coordinates,
///   t = mean_w(target) - R mean_w(source).
/// - source_points, target_points: metres, indexed by the correspondences.
/// - weights: one per correspondence (>= 0, finite, positive sum) or nullptr for uniform.
/// If the horizontal spread is zero (all points on one vertical line), theta = 0.
/// Throws InvalidArgument on empty correspondences, invalid weights or an up axis that is not a
/// finite unit vector.
Isometry3 estimate_4dof_transform(const Points3& source_points, const Points3& target_points,
                                  const Correspondences& correspondences,
                                  const std::vector<double>* weights = nullptr,
                                  const Vec3& up = Vec3::UnitZ());

}  // namespace lmalign
