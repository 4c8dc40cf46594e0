// Closed-form 4-DoF (x, y, z and yaw about the up axis) rigid estimation for gravity-aligned
// maps (visual-inertial SLAM, ground robots). Not in the paper.
#pragma once

#include <string>
#include <vector>

#include "lmalign/core/enum_names.hpp"
#include "lmalign/core/types.hpp"
#include "lmalign/registration/correspondence.hpp"

namespace lmalign {

/// Which map axis points up (against gravity). Both maps must share it.
enum class UpAxis { kX, kY, kZ };
inline constexpr EnumName<UpAxis> kUpAxisNames[] = {
    {UpAxis::kX, "x"}, {UpAxis::kY, "y"}, {UpAxis::kZ, "z"}};
std::string to_string(UpAxis axis);  ///< "x", "y", "z"
/// Inverse of to_string. Throws InvalidArgument "unknown up axis 'NAME' (known: x, y, z)".
UpAxis parse_up_axis(const std::string& name);

/// The rotation by `angle_rad` about `axis` (right-handed), built entrywise so that the up row
/// and column are exactly (0, 0, 1) in the permuted sense: composing it onto any rotation leaves
/// that rotation's up row bit-identical (hence roll and pitch exactly unchanged).
Mat3 rotation_about_up(UpAxis axis, double angle_rad);

/// The transform T = [R_up(theta) | t] minimising sum_i w_i |T s_i - t_i|^2 over the
/// correspondences, where R_up is a rotation about the up axis only: closed form (the 2-D
/// weighted Procrustes/Umeyama problem in the plane orthogonal to `up`):
///   theta = atan2(sum w (a_u b_v - a_v b_u), sum w (a_u b_u + a_v b_v)) on demeaned coordinates,
///   t = mean_w(target) - R mean_w(source).
/// - source_points, target_points: metres, indexed by the correspondences.
/// - weights: one per correspondence (>= 0, finite, positive sum) or nullptr for uniform.
/// If the horizontal spread is zero (all points on one vertical line), theta = 0.
/// Throws InvalidArgument on empty correspondences or invalid weights.
Isometry3 estimate_4dof_transform(const Points3& source_points, const Points3& target_points,
                                  const Correspondences& correspondences,
                                  const std::vector<double>* weights = nullptr,
                                  UpAxis up = UpAxis::kZ);

}  // namespace lmalign
