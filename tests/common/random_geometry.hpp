#pragma once
// Seeded random rotations and directions shared by the geometry tests.
#include <random>

#include <Eigen/Geometry>

namespace fogmap::testing {

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

}  // namespace fogmap::testing
