#include "common/sim/footprint.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

#include "common/base/angles.hpp"

namespace fogmap::sim {
namespace {

// > 0 when o -> a -> b turns counter-clockwise.
double cross(const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

}  // namespace

double footprintGap(std::span<const Eigen::Vector2d> a, std::span<const Eigen::Vector2d> b) {
  if (a.empty() || b.empty()) return std::numeric_limits<double>::infinity();
  // The gap between the projections of a and b on the unit direction n (either order).
  const auto gapAlong = [&](const Eigen::Vector2d& n) {
    double a_lo = std::numeric_limits<double>::infinity(), a_hi = -a_lo, b_lo = a_lo, b_hi = -a_lo;
    for (const auto& p : a) {
      a_lo = std::min(a_lo, n.dot(p));
      a_hi = std::max(a_hi, n.dot(p));
    }
    for (const auto& p : b) {
      b_lo = std::min(b_lo, n.dot(p));
      b_hi = std::max(b_hi, n.dot(p));
    }
    return std::max(b_lo - a_hi, a_lo - b_hi);
  };
  double gap = -std::numeric_limits<double>::infinity();
  const auto sidesOf = [&](std::span<const Eigen::Vector2d> polygon) {
    for (std::size_t i = 0; polygon.size() >= 2 && i < polygon.size(); ++i) {
      const Eigen::Vector2d side = polygon[(i + 1) % polygon.size()] - polygon[i];
      if (side.squaredNorm() > 0.0) gap = std::max(gap, gapAlong(Eigen::Vector2d(-side.y(), side.x()).normalized()));
    }
  };
  sidesOf(a);
  sidesOf(b);
  Eigen::Vector2d centre_a = Eigen::Vector2d::Zero(), centre_b = Eigen::Vector2d::Zero();
  for (const auto& p : a) centre_a += p / static_cast<double>(a.size());
  for (const auto& p : b) centre_b += p / static_cast<double>(b.size());
  const Eigen::Vector2d between = centre_b - centre_a;
  if (between.squaredNorm() > 0.0) gap = std::max(gap, gapAlong(between.normalized()));
  if (!std::isfinite(gap)) return 0.0;  // one point on another
  return gap;
}

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
