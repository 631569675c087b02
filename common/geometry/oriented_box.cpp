#include "common/geometry/oriented_box.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace fogmap {

std::string_view boxAnchorName(BoxAnchor anchor) {
  switch (anchor) {
    case BoxAnchor::kNone: return "none";
    case BoxAnchor::kFrontFace: return "front";
    case BoxAnchor::kRearFace: return "rear";
    case BoxAnchor::kLeftFace: return "left";
    case BoxAnchor::kRightFace: return "right";
    case BoxAnchor::kFrontLeft: return "front_left";
    case BoxAnchor::kFrontRight: return "front_right";
    case BoxAnchor::kRearLeft: return "rear_left";
    case BoxAnchor::kRearRight: return "rear_right";
  }
  return "none";
}

double foldedYaw(double yaw) {
  constexpr double pi = std::numbers::pi;
  double folded = std::remainder(yaw, pi);  // [-pi/2, pi/2]
  if (folded >= 0.5 * pi) folded -= pi;
  return folded;
}

double axisAngleBetween(double yaw_a, double yaw_b) { return std::abs(std::remainder(yaw_a - yaw_b, std::numbers::pi)); }
double headingAngleBetween(double heading_a, double heading_b) {
  return std::abs(std::remainder(heading_a - heading_b, 2.0 * std::numbers::pi));
}

Eigen::Vector3d OrientedBox::anchorPoint() const {
  double u = 0.0;  // along length
  double v = 0.0;  // along width
  switch (anchor) {
    case BoxAnchor::kNone: break;
    case BoxAnchor::kFrontFace: u = 1; break;
    case BoxAnchor::kRearFace: u = -1; break;
    case BoxAnchor::kLeftFace: v = 1; break;
    case BoxAnchor::kRightFace: v = -1; break;
    case BoxAnchor::kFrontLeft: u = 1; v = 1; break;
    case BoxAnchor::kFrontRight: u = 1; v = -1; break;
    case BoxAnchor::kRearLeft: u = -1; v = 1; break;
    case BoxAnchor::kRearRight: u = -1; v = -1; break;
  }
  const double c = std::cos(yaw);
  const double s = std::sin(yaw);
  const double a = 0.5 * length * u;
  const double b = 0.5 * width * v;
  return centre + Eigen::Vector3d(c * a - s * b, s * a + c * b, 0.0);
}

BoxAnchor OrientedBox::anchorFor(const Eigen::Vector3d& sensor) const {
  const double c = std::cos(yaw);
  const double s = std::sin(yaw);
  const double dx = sensor.x() - centre.x();
  const double dy = sensor.y() - centre.y();
  const double u = c * dx + s * dy;
  const double v = -s * dx + c * dy;
  const bool beyond_length = std::abs(u) > 0.5 * length;
  const bool beyond_width = std::abs(v) > 0.5 * width;
  if (beyond_length && beyond_width) {
    if (u > 0) return v > 0 ? BoxAnchor::kFrontLeft : BoxAnchor::kFrontRight;
    return v > 0 ? BoxAnchor::kRearLeft : BoxAnchor::kRearRight;
  }
  if (beyond_length) return u > 0 ? BoxAnchor::kFrontFace : BoxAnchor::kRearFace;
  if (beyond_width) return v > 0 ? BoxAnchor::kLeftFace : BoxAnchor::kRightFace;
  return BoxAnchor::kNone;
}

std::array<Eigen::Vector2d, 4> OrientedBox::footprint() const {
  const Eigen::Vector2d along = 0.5 * length * Eigen::Vector2d(std::cos(yaw), std::sin(yaw));
  const Eigen::Vector2d across = 0.5 * width * Eigen::Vector2d(-std::sin(yaw), std::cos(yaw));
  const Eigen::Vector2d c = centre.head<2>();
  return {c + along + across, c - along + across, c - along - across, c + along - across};
}

std::array<Eigen::Vector3d, 8> OrientedBox::corners() const {
  const auto corners_2d = footprint();
  std::array<Eigen::Vector3d, 8> out;
  for (std::size_t k = 0; k < 4; ++k) {
    out[k] = {corners_2d[k].x(), corners_2d[k].y(), centre.z() - height / 2.0};
    out[k + 4] = {corners_2d[k].x(), corners_2d[k].y(), centre.z() + height / 2.0};
  }
  return out;
}

bool footprintsOverlap(const OrientedBox& a, const OrientedBox& b) {
  const auto corners_a = a.footprint();
  const auto corners_b = b.footprint();
  for (const OrientedBox* box : {&a, &b}) {
    for (const Eigen::Vector2d& axis : {Eigen::Vector2d(std::cos(box->yaw), std::sin(box->yaw)),
                                       Eigen::Vector2d(-std::sin(box->yaw), std::cos(box->yaw))}) {
      double a_lo = corners_a[0].dot(axis), a_hi = a_lo, b_lo = corners_b[0].dot(axis), b_hi = b_lo;
      for (int k = 1; k < 4; ++k) {
        a_lo = std::min(a_lo, corners_a[k].dot(axis));
        a_hi = std::max(a_hi, corners_a[k].dot(axis));
        b_lo = std::min(b_lo, corners_b[k].dot(axis));
        b_hi = std::max(b_hi, corners_b[k].dot(axis));
      }
      if (a_hi < b_lo || b_hi < a_lo) return false;
    }
  }
  return true;
}

}  // namespace fogmap
