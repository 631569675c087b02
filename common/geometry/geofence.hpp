#pragma once
// Geofence queries on ellipsoid maps (DESIGN.md 2.3): a geofence is a convex polyhedron, the
// intersection of half-spaces n.x + d >= 0; ellipsoids are classified against it without points.
#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/base/status.hpp"
#include "common/geometry/ellipsoid.hpp"
#include "common/geometry/map.hpp"

namespace fogmap {

struct HalfSpace {
  Eigen::Vector3d normal;  // need not be unit length
  double offset = 0.0;     // inside when normal.x + offset >= 0
};

struct Geofence {
  std::string name;
  std::vector<HalfSpace> half_spaces;
};

enum class Containment { kOutside, kCrossing, kInside };
const char* containmentName(Containment c);

// Bounds on one geofence, so that a query costs a known amount and a stored fence a known size.
inline constexpr std::size_t kMaxHalfSpaces = 256;
inline constexpr std::size_t kMaxGeofenceNameBytes = 256;

// Rejects empty geofences, more than kMaxHalfSpaces half-spaces, names longer than
// kMaxGeofenceNameBytes, and zero or non-finite normals.
Status validateGeofence(const Geofence& fence);
// An axis-aligned box as a geofence (six half-spaces).
Geofence boxGeofence(std::string name, const Eigen::Vector3d& min, const Eigen::Vector3d& max);

// Conservative: kOutside only when the ellipsoid is entirely on the negative side of some plane;
// kInside only when it is entirely on the positive side of every plane; else kCrossing.
Containment classify(const Ellipsoid& e, const Geofence& fence);
// An object is inside when all its ellipsoids are, outside when all are, else crossing.
Containment classify(const MapObject& object, const Geofence& fence);

struct GeofenceHit {
  std::size_t object_index = 0;
  Containment containment = Containment::kCrossing;
};
// Objects of the map that intrude (inside or crossing), in map order.
std::vector<GeofenceHit> intrusions(const Map& map, const Geofence& fence);

}  // namespace fogmap
