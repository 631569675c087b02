#pragma once
// Ellipsoids for the geometry tests: seeded random rotations, directions and shapes, and shapes and
// spheres built from their parts.
#include <random>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/geometry/ellipsoid.hpp"

namespace fogmap::test_support {

// Uniform over rotations: a normalised quaternion of four normal samples.
inline Eigen::Matrix3d randomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return q.normalized().toRotationMatrix();
}

inline Eigen::Vector3d randomUnitVector(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  Eigen::Vector3d v;
  do {
    v = {normal(rng), normal(rng), normal(rng)};
  } while (v.norm() < 1e-6);
  return v.normalized();
}

// Shape matrix R diag(semi_axes^2) R^T, exactly symmetric.
inline Eigen::Matrix3d shapeOf(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& semi_axes) {
  Eigen::Matrix3d m = rotation * semi_axes.cwiseAbs2().asDiagonal() * rotation.transpose();
  return 0.5 * (m + m.transpose());
}

// A randomly turned shape whose semi-axes are uniform in [min_axis, max_axis). The semi-axes are
// drawn last to first and then the rotation: the order in which GCC evaluated the arguments of the
// one-line form this was before, so the seeded cases stay the ones the tests were written against.
inline Eigen::Matrix3d randomShape(std::mt19937_64& rng, double min_axis, double max_axis) {
  std::uniform_real_distribution<double> axis(min_axis, max_axis);
  const double c = axis(rng);
  const double b = axis(rng);
  const double a = axis(rng);
  return shapeOf(randomRotation(rng), Eigen::Vector3d(a, b, c));
}

// A sphere of `radius` around `center` (id and point count left at their defaults).
inline Ellipsoid sphere(const Eigen::Vector3d& center, double radius) {
  Ellipsoid e;
  e.center = center;
  e.shape = radius * radius * Eigen::Matrix3d::Identity();
  return e;
}

// (p - c)^T shape^-1 (p - c): 1 on the ellipsoid's surface, below 1 inside.
inline double quadraticForm(const Ellipsoid& e, const Eigen::Vector3d& p) {
  const Eigen::Vector3d d = p - e.center;
  return d.dot(e.shape.ldlt().solve(d));
}

}  // namespace fogmap::test_support
