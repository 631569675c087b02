#pragma once
// Eigenvalues and eigenvectors of small symmetric matrices, as Eigen's SelfAdjointEigenSolver
// computes them (from the lower triangle), behind plain functions: the solver's templates cost a
// translation unit several seconds of compile time, so they are instantiated once, in
// symmetric_eigen.cpp, for every caller.
#include <Eigen/Core>

namespace fogmap {

template <int N>
struct SymmetricEigen {
  Eigen::Matrix<double, N, 1> values = Eigen::Matrix<double, N, 1>::Zero();   // ascending
  Eigen::Matrix<double, N, N> vectors = Eigen::Matrix<double, N, N>::Zero();  // column k: values[k]'s
  bool converged = false;  // false for a matrix the iteration cannot take (e.g. one that is not finite)
};

SymmetricEigen<2> symmetricEigen(const Eigen::Matrix2d& m);
SymmetricEigen<3> symmetricEigen(const Eigen::Matrix3d& m);

// The eigenvalues alone, ascending (vectors left zero).
SymmetricEigen<3> symmetricEigenvalues(const Eigen::Matrix3d& m);

}  // namespace fogmap
