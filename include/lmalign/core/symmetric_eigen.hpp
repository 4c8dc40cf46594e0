// The eigen-decomposition of small symmetric matrices (6x6 pose covariances, 7x7 with a scale),
// compiled once. Eigen::SelfAdjointEigenSolver instantiated for a fixed size costs 10-20 s of
// compile time in every translation unit that uses it (measured with g++ 12 at -O1 under ASan +
// UBSan, 2026-11-25: 16 s for 6x6, 19 s for 7x7); these functions are that solver, instantiated
// in src/core/symmetric_eigen.cpp alone. Same algorithm, same options, same results bit for bit
// as constructing the solver where it is needed.
#pragma once

#include "lmalign/core/types.hpp"

namespace lmalign {

/// Eigenvalues (ascending) and, when asked, the eigenvectors (columns, orthonormal) of a
/// symmetric N x N matrix, as Eigen::SelfAdjointEigenSolver computes them from its lower
/// triangle. `ok` is false when the solver did not converge (Eigen::NoConvergence).
template <int N>
struct SymmetricEigen {
  Eigen::Matrix<double, N, 1> values = Eigen::Matrix<double, N, 1>::Zero();
  Eigen::Matrix<double, N, N> vectors = Eigen::Matrix<double, N, N>::Zero();  ///< if asked
  bool ok = false;
};

/// Decomposes `m` (only its lower triangle is read). No exceptions; NaN in, NaN out.
SymmetricEigen<6> symmetric_eigen(const Mat6& m, bool with_vectors = true);
SymmetricEigen<7> symmetric_eigen(const Mat7& m, bool with_vectors = true);

}  // namespace lmalign
