// Eigen::SelfAdjointEigenSolver for 6x6 and 7x7, instantiated here once
// (include/lmalign/core/symmetric_eigen.hpp).
#include "lmalign/core/symmetric_eigen.hpp"

#include <Eigen/Eigenvalues>

namespace lmalign {

namespace {
template <int N>
SymmetricEigen<N> decompose(const Eigen::Matrix<double, N, N>& m, bool with_vectors) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eig(
      m, with_vectors ? Eigen::ComputeEigenvectors : Eigen::EigenvaluesOnly);
  SymmetricEigen<N> out;
  out.ok = eig.info() == Eigen::Success;
  out.values = eig.eigenvalues();
  if (with_vectors) out.vectors = eig.eigenvectors();
  return out;
}
}  // namespace

SymmetricEigen<6> symmetric_eigen(const Mat6& m, bool with_vectors) {
  return decompose<6>(m, with_vectors);
}

SymmetricEigen<7> symmetric_eigen(const Mat7& m, bool with_vectors) {
  return decompose<7>(m, with_vectors);
}

}  // namespace lmalign
