#pragma once
// The point cloud in fogmap's own terms: packed float32 points, metres.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace fogmap {

struct Point {
  float x = 0.0F;
  float y = 0.0F;
  float z = 0.0F;
  float intensity = 0.0F;

  Eigen::Vector3f xyz() const { return {x, y, z}; }
  bool operator==(const Point&) const = default;
};

using Cloud = std::vector<Point>;

}  // namespace fogmap
