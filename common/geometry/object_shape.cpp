#include "common/geometry/object_shape.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

namespace fogmap {

std::optional<OrientedBox> objectBox(const MapObject& object) {
  const Ellipsoid* best = nullptr;
  std::size_t with_box = 0;
  for (const Ellipsoid& e : object.ellipsoids) {  // sorted by id: the first of equal counts wins
    if (!e.box) continue;
    ++with_box;
    if (best == nullptr || e.point_count > best->point_count) best = &e;
  }
  if (best == nullptr) return std::nullopt;
  if (with_box == 1) return best->box;

  const double yaw = best->box->yaw;
  const Eigen::Vector2d u(std::cos(yaw), std::sin(yaw));
  const Eigen::Vector2d v(-u.y(), u.x());
  constexpr double inf = std::numeric_limits<double>::infinity();
  double u_min = inf, u_max = -inf, v_min = inf, v_max = -inf, z_min = inf, z_max = -inf;
  for (const Ellipsoid& e : object.ellipsoids) {
    if (!e.box) continue;
    for (const Eigen::Vector2d& corner : e.box->footprint()) {
      u_min = std::min(u_min, corner.dot(u));
      u_max = std::max(u_max, corner.dot(u));
      v_min = std::min(v_min, corner.dot(v));
      v_max = std::max(v_max, corner.dot(v));
    }
    z_min = std::min(z_min, e.box->centre.z() - 0.5 * e.box->height);
    z_max = std::max(z_max, e.box->centre.z() + 0.5 * e.box->height);
  }
  OrientedBox out;
  const Eigen::Vector2d middle = 0.5 * (u_min + u_max) * u + 0.5 * (v_min + v_max) * v;
  out.centre = Eigen::Vector3d(middle.x(), middle.y(), 0.5 * (z_min + z_max));
  out.length = u_max - u_min;
  out.width = v_max - v_min;
  out.height = z_max - z_min;
  out.yaw = yaw;
  if (out.width > out.length) {
    std::swap(out.length, out.width);
    out.yaw = foldedYaw(yaw + 0.5 * std::numbers::pi);
  }
  out.anchor = BoxAnchor::kNone;
  return out;
}

std::optional<ObjectLabel> objectLabel(const MapObject& object) {
  std::array<double, kObjectClassCount> weight{};
  double points = 0.0;
  bool labelled = false;
  for (const Ellipsoid& e : object.ellipsoids) {
    if (!e.label) continue;
    const auto k = static_cast<std::size_t>(e.label->object_class);
    if (k >= kObjectClassCount) continue;
    labelled = true;
    const auto n = static_cast<double>(e.point_count);
    weight[k] += e.label->confidence * n;
    points += n;
  }
  if (!labelled) return std::nullopt;
  const auto winner = static_cast<std::size_t>(std::max_element(weight.begin(), weight.end()) - weight.begin());
  ObjectLabel out;
  out.object_class = static_cast<ObjectClass>(winner);
  out.confidence = points > 0.0 ? std::clamp(weight[winner] / points, 0.0, 1.0) : 0.0;
  return out;
}

}  // namespace fogmap
