#include "common/sim/footprint.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "common/base/angles.hpp"

namespace fogmap::sim {
namespace {

// > 0 when o -> a -> b turns counter-clockwise.
double cross(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

}  // namespace

std::vector<Eigen::Vector2d> convexHull(std::vector<Eigen::Vector2d> points) {
  const auto lexicographic = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  };
  std::sort(points.begin(), points.end(), lexicographic);
  points.erase(std::unique(points.begin(), points.end()), points.end());
  if (points.size() < 3) return points;
  // Andrew's monotone chain: the lower hull left to right, then the upper hull back.
  std::vector<Eigen::Vector2d> hull(2 * points.size());
  std::size_t k = 0;
  for (const auto& p : points) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], p) <= 0.0) --k;
    hull[k++] = p;
  }
  for (std::size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && cross(hull[k - 2], hull[k - 1], points[i]) <= 0.0) --k;
    hull[k++] = points[i];
  }
  hull.resize(k - 1);  // the last point is the first again
  return hull;
}

std::vector<Eigen::Vector2d> footprint(const SceneObject& object, double time_s) {
  const ObjectPose pose = poseAt(object, time_s);
  const Eigen::Rotation2Dd heading(pose.yaw_rad);
  std::vector<Eigen::Vector2d> corners;
  // The same placement as the ray caster: part centres turn with the object, boxes also by their own yaw.
  for (const Part& part : object.parts) {
    const Eigen::Vector2d centre = pose.xy + heading * part.at.head<2>();
    if (part.shape == Shape::kCylinder) {
      const double r = part.size.x() / 2.0;
      for (int i = 0; i < kFootprintCylinderSides; ++i) {
        const double a = 2.0 * M_PI * i / kFootprintCylinderSides;
        corners.push_back(centre + r * Eigen::Vector2d(std::cos(a), std::sin(a)));
      }
      continue;
    }
    const Eigen::Rotation2Dd yaw(pose.yaw_rad + part.yaw_deg * kDegToRad);
    const Eigen::Vector2d ax = yaw * Eigen::Vector2d(part.size.x() / 2.0, 0.0);
    const Eigen::Vector2d ay = yaw * Eigen::Vector2d(0.0, part.size.y() / 2.0);
    for (const double sx : {-1.0, 1.0}) {
      for (const double sy : {-1.0, 1.0}) corners.push_back(centre + sx * ax + sy * ay);
    }
  }
  return convexHull(std::move(corners));
}

}  // namespace fogmap::sim
