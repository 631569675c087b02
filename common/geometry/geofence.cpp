#include "common/geometry/geofence.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

namespace fogmap {
namespace {

enum class Side { kNegative, kCrossing, kPositive };

// The support function of the ellipsoid along n is n.c + sqrt(n^T M n); comparing the plane's
// signed value at the centre with the half-width needs no unit normal because both scale with |n|.
Side sideOf(const Ellipsoid& e, const HalfSpace& h) {
  const double s = h.normal.dot(e.center) + h.offset;
  // Rounding can push n^T M n of a flat (PSD) shape slightly below zero.
  const double half_width = std::sqrt(std::max(0.0, h.normal.dot(e.shape * h.normal)));
  if (s - half_width > 0.0) return Side::kPositive;
  if (s + half_width < 0.0) return Side::kNegative;
  return Side::kCrossing;
}

std::string fenceLabel(const Geofence& fence) {
  return "geofence '" + fence.name + "'";
}

}  // namespace

const char* containmentName(Containment c) {
  switch (c) {
    case Containment::kOutside: return "outside";
    case Containment::kCrossing: return "crossing";
    case Containment::kInside: return "inside";
  }
  return "unknown";
}

Status validateGeofence(const Geofence& fence) {
  if (fence.name.size() > kMaxGeofenceNameBytes) {
    return invalidArgument("a geofence name has " + std::to_string(fence.name.size()) + " bytes, more than " +
                           std::to_string(kMaxGeofenceNameBytes));
  }
  if (fence.half_spaces.empty()) {
    return invalidArgument(fenceLabel(fence) + " has no half-spaces");
  }
  if (fence.half_spaces.size() > kMaxHalfSpaces) {
    return invalidArgument(fenceLabel(fence) + " has " + std::to_string(fence.half_spaces.size()) +
                           " half-spaces, more than " + std::to_string(kMaxHalfSpaces));
  }
  for (std::size_t i = 0; i < fence.half_spaces.size(); ++i) {
    const HalfSpace& h = fence.half_spaces[i];
    if (!h.normal.allFinite()) {
      return invalidArgument(fenceLabel(fence) + ": half-space " + std::to_string(i) +
                             " has a non-finite normal");
    }
    if ((h.normal.array() == 0.0).all()) {
      return invalidArgument(fenceLabel(fence) + ": half-space " + std::to_string(i) +
                             " has a zero normal");
    }
    // classify() squares the normal; a length whose square underflows or overflows would turn
    // the half-width into 0 or infinity.
    if (!std::isnormal(h.normal.squaredNorm())) {
      return invalidArgument(fenceLabel(fence) + ": half-space " + std::to_string(i) +
                             " has a normal too short or too long to square; rescale it and the "
                             "offset");
    }
    if (!std::isfinite(h.offset)) {
      return invalidArgument(fenceLabel(fence) + ": half-space " + std::to_string(i) +
                             " has a non-finite offset");
    }
  }
  return {};
}

Geofence boxGeofence(std::string name, const Eigen::Vector3d& min, const Eigen::Vector3d& max) {
  Geofence fence{std::move(name), {}};
  fence.half_spaces.reserve(6);
  for (int d = 0; d < 3; ++d) {
    const Eigen::Vector3d axis = Eigen::Vector3d::Unit(d);
    fence.half_spaces.push_back({axis, -min[d]});   // x_d >= min_d
    fence.half_spaces.push_back({-axis, max[d]});   // x_d <= max_d
  }
  return fence;
}

Containment classify(const Ellipsoid& e, const Geofence& fence) {
  bool inside = true;
  for (const HalfSpace& h : fence.half_spaces) {
    const Side side = sideOf(e, h);
    // One separating plane proves the ellipsoid outside, whatever the other planes say.
    if (side == Side::kNegative) return Containment::kOutside;
    if (side == Side::kCrossing) inside = false;
  }
  return inside ? Containment::kInside : Containment::kCrossing;
}

Containment classify(const MapObject& object, const Geofence& fence) {
  // An object without ellipsoids occupies no space, so it cannot intrude.
  if (object.ellipsoids.empty()) return Containment::kOutside;
  bool all_inside = true;
  bool all_outside = true;
  for (const Ellipsoid& e : object.ellipsoids) {
    const Containment c = classify(e, fence);
    all_inside = all_inside && c == Containment::kInside;
    all_outside = all_outside && c == Containment::kOutside;
    if (!all_inside && !all_outside) return Containment::kCrossing;
  }
  return all_inside ? Containment::kInside : Containment::kOutside;
}

std::vector<GeofenceHit> intrusions(const Map& map, const Geofence& fence) {
  std::vector<GeofenceHit> hits;
  for (std::size_t i = 0; i < map.objects.size(); ++i) {
    const Containment c = classify(map.objects[i], fence);
    if (c != Containment::kOutside) hits.push_back({i, c});
  }
  return hits;
}

}  // namespace fogmap
