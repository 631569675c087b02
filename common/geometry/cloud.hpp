#pragma once
// The point cloud in fogmap's own terms: packed float32 points, metres.
#include <cmath>
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

// True when x, y and z are all finite: no NaN, no infinity (intensity is not looked at).
inline bool isFinitePoint(const Point& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

}  // namespace fogmap
