// Basic linear-algebra types used throughout lmalign.
//
// Conventions (docs/conventions.md):
//   - Transforms are rigid (SE(3)) Eigen::Isometry3d, named T_<to>_<from>, so that
//     p_to = T_to_from * p_from. The registration result is T_target_source.
//   - Positions are in metres, angles in radians unless a name ends in _deg.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/StdVector>

namespace lmalign {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Mat4 = Eigen::Matrix4d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;
/// A pose perturbation with scale, (rho, phi, sigma = log scale), and its 7x7 covariance.
using Vec7 = Eigen::Matrix<double, 7, 1>;
using Mat7 = Eigen::Matrix<double, 7, 7>;
using Quat = Eigen::Quaterniond;
using Isometry3 = Eigen::Isometry3d;

/// A list of 3-D points (metres). Vector3d has no alignment requirement, so a plain std::vector.
using Points3 = std::vector<Vec3>;

/// Identifier of a frame or a landmark as written in the map file (non-negative).
using Id = std::int64_t;

}  // namespace lmalign
