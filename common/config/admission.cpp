#include "common/config/admission.hpp"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <optional>
#include <string>
#include <utility>

#include "common/geometry/symmetric_eigen.hpp"

namespace fogmap {
namespace {

std::string num(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", v);
  return buffer;
}

bool within(const Eigen::Vector3d& v, double extent) {
  return v.allFinite() && v.cwiseAbs().maxCoeff() <= extent;
}

// What is wrong with an ellipsoid's box or label, if anything: a box is finite, inside the world,
// with sides in [0, 2 x world extent], yaw in [-pi/2, pi/2) and length >= width; a confidence is in
// [0, 1].
std::optional<std::string> viewProblem(const Ellipsoid& e, const AdmissionLimits& limits) {
  if (e.box) {
    const OrientedBox& b = *e.box;
    if (!within(b.centre, limits.world_extent_m)) {
      return "box centre (" + num(b.centre.x()) + ", " + num(b.centre.y()) + ", " + num(b.centre.z()) +
             ") is not finite or lies outside the world extent of " + num(limits.world_extent_m) + " m";
    }
    const double largest = 2.0 * limits.world_extent_m;
    for (const auto& [name, side] : {std::pair{"length", b.length}, std::pair{"width", b.width}, std::pair{"height", b.height}}) {
      if (!(side >= 0.0 && side <= largest)) {
        return std::string("box ") + name + " " + num(side) + " m is not in [0, " + num(largest) + "]";
      }
    }
    if (b.width > b.length) return "box width " + num(b.width) + " m exceeds its length " + num(b.length) + " m";
    if (!(b.yaw >= -0.5 * std::numbers::pi && b.yaw < 0.5 * std::numbers::pi)) {
      return "box yaw " + num(b.yaw) + " rad is not in [-pi/2, pi/2)";
    }
  }
  if (e.label && !(e.label->confidence >= 0.0 && e.label->confidence <= 1.0)) {
    return "class confidence " + num(e.label->confidence) + " is not in [0, 1]";
  }
  return std::nullopt;
}

}  // namespace

Status validateAdmissionLimits(const AdmissionLimits& l) {
  for (const auto& [name, value] : {std::pair{"window_periods", l.window_periods},
                                    std::pair{"world_extent_m", l.world_extent_m},
                                    std::pair{"min_eigenvalue_m2", l.min_eigenvalue_m2},
                                    std::pair{"max_eigenvalue_m2", l.max_eigenvalue_m2},
                                    std::pair{"max_condition", l.max_condition}}) {
    if (!std::isfinite(value) || value <= 0.0) {
      return invalidArgument(std::string("admission ") + name + " must be a positive number, got " + num(value));
    }
  }
  if (l.max_ellipsoids_per_map == 0 || l.max_map_bytes == 0 || l.max_subscribers == 0) {
    return invalidArgument("admission max_ellipsoids_per_map, max_map_bytes and max_subscribers must be at least 1");
  }
  if (l.min_eigenvalue_m2 >= l.max_eigenvalue_m2) {
    return invalidArgument("admission min_eigenvalue_m2 (" + num(l.min_eigenvalue_m2) +
                           ") must be below max_eigenvalue_m2 (" + num(l.max_eigenvalue_m2) + ")");
  }
  return {};
}

const char* refusalName(Refusal refusal) {
  switch (refusal) {
    case Refusal::kMalformed: return "malformed";
    case Refusal::kWrongMode: return "wrong_mode";
    case Refusal::kUnknownNode: return "unknown_node";
    case Refusal::kForgedNode: return "forged_node";
    case Refusal::kClockSkew: return "clock_skew";
    case Refusal::kTooLarge: return "too_large";
    case Refusal::kOutOfWorld: return "out_of_world";
    case Refusal::kBadShape: return "bad_shape";
    case Refusal::kSequenceConflict: return "sequence_conflict";
    case Refusal::kEllipsoidConflict: return "ellipsoid_conflict";
    case Refusal::kInconsistentChunks: return "inconsistent_chunks";
    case Refusal::kUnknownPeer: return "unknown_peer";
    case Refusal::kBadBox: return "bad_box";
  }
  return "unknown";
}

ErrorCode refusalCode(Refusal refusal) {
  return refusal == Refusal::kTooLarge ? ErrorCode::kResourceExhausted : ErrorCode::kInvalidArgument;
}

std::optional<Refused> checkMapBounds(const Map& map, const AdmissionLimits& limits, const std::string& what) {
  const std::size_t count = map.ellipsoidCount();
  if (count > limits.max_ellipsoids_per_map) {
    return Refused{Refusal::kTooLarge, what + " has " + std::to_string(count) + " ellipsoids, more than the bound of " +
                                           std::to_string(limits.max_ellipsoids_per_map)};
  }
  for (const auto& object : map.objects) {
    for (const auto& e : object.ellipsoids) {
      const std::string which = what + ", ellipsoid " + toString(e.id);
      if (!within(e.center, limits.world_extent_m)) {
        return Refused{Refusal::kOutOfWorld, which + ": centre (" + num(e.center.x()) + ", " + num(e.center.y()) +
                                                 ", " + num(e.center.z()) + ") lies outside the world extent of " +
                                                 num(limits.world_extent_m) + " m"};
      }
      const SymmetricEigen<3> eigen = symmetricEigenvalues(e.shape);
      const Eigen::Vector3d values = eigen.values;  // ascending
      if (!eigen.converged || !values.allFinite() || values[0] < limits.min_eigenvalue_m2 ||
          values[2] > limits.max_eigenvalue_m2 || values[2] > limits.max_condition * values[0]) {
        return Refused{Refusal::kBadShape, which + ": shape eigenvalues " + num(values[0]) + ", " + num(values[1]) +
                                               ", " + num(values[2]) + " m^2 are outside [" +
                                               num(limits.min_eigenvalue_m2) + ", " + num(limits.max_eigenvalue_m2) +
                                               "] or more ill-conditioned than " + num(limits.max_condition)};
      }
    }
    for (const auto& e : object.ellipsoids) {
      if (auto problem = viewProblem(e, limits)) {
        return Refused{Refusal::kBadBox, what + ", ellipsoid " + toString(e.id) + ": " + *problem};
      }
    }
    if (!within(object.box.min, limits.world_extent_m) || !within(object.box.max, limits.world_extent_m)) {
      return Refused{Refusal::kOutOfWorld, what + ": an object's box reaches outside the world extent of " +
                                               num(limits.world_extent_m) + " m"};
    }
  }
  return std::nullopt;
}

Status validateClusteringParams(const ClusteringParams& params) {
  if (!std::isfinite(params.eps_m) || params.eps_m < kMinEpsM || params.eps_m > kMaxEpsM) {
    return invalidArgument("eps_m must be between " + num(kMinEpsM) + " and " + num(kMaxEpsM) + " m, got " +
                           num(params.eps_m));
  }
  if (params.min_points < 1) return invalidArgument("min_points must be at least 1");
  if (params.max_points < params.min_points) {
    return invalidArgument("max_points (" + std::to_string(params.max_points) + ") must be at least min_points (" +
                           std::to_string(params.min_points) + ")");
  }
  return {};
}

}  // namespace fogmap
