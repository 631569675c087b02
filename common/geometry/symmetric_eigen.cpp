#include "common/geometry/symmetric_eigen.hpp"

#include <Eigen/Eigenvalues>

namespace fogmap {
namespace {

template <int N>
SymmetricEigen<N> decompose(const Eigen::Matrix<double, N, N>& m, int options) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> solver(m, options);
  SymmetricEigen<N> out;
  out.converged = solver.info() == Eigen::Success;
  out.values = solver.eigenvalues();
  if (options == Eigen::ComputeEigenvectors) out.vectors = solver.eigenvectors();
  return out;
}

}  // namespace

SymmetricEigen<2> symmetricEigen(const Eigen::Matrix2d& m) { return decompose<2>(m, Eigen::ComputeEigenvectors); }
SymmetricEigen<3> symmetricEigen(const Eigen::Matrix3d& m) { return decompose<3>(m, Eigen::ComputeEigenvectors); }
SymmetricEigen<3> symmetricEigenvalues(const Eigen::Matrix3d& m) { return decompose<3>(m, Eigen::EigenvaluesOnly); }

}  // namespace fogmap
