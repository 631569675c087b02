#pragma once
// Admission rules an aggregator applies to every map before it merges it (docs/design.md
// "Admission"): value and size bounds here (pure checks on domain types); the epoch window,
// node identity and duplicate rules in the aggregator core. Every refusal has a reason, counted
// under its name.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "common/base/status.hpp"
#include "common/geometry/map.hpp"
#include "common/perception/madc.hpp"

namespace fogmap {

struct AdmissionLimits {
  // Epochs more than this many periods ahead of the aggregator's clock, or whose deadline lies
  // more than this many periods in the past, are refused as clock skew.
  double window_periods = 3.0;
  double world_extent_m = 10000.0;             // |x|, |y|, |z| of every ellipsoid centre and box
  std::size_t max_ellipsoids_per_map = 20000;  // per upload
  std::size_t max_map_bytes = 8U << 20;        // serialised size of one upload
  double min_eigenvalue_m2 = 1e-10;            // shape eigenvalues (squared semi-axes)
  double max_eigenvalue_m2 = 1e8;              // 10 km semi-axis
  double max_condition = 1e12;                 // largest / smallest eigenvalue
  // Subscriber streams a service serves at once (the root's global maps, a tracker's tracks):
  // each holds a bounded queue (about 0.8 MB for global maps), so their number is bounded too;
  // one more is refused as RESOURCE_EXHAUSTED and counted.
  std::size_t max_subscribers = 32;
  bool operator==(const AdmissionLimits&) const = default;
};

// Errors unless every limit is finite and positive and min_eigenvalue < max_eigenvalue.
Status validateAdmissionLimits(const AdmissionLimits& limits);

// Why an upload was refused; the name is the counter's label.
enum class Refusal {
  kMalformed,           // the message does not convert (fromProto names the field)
  kWrongMode,           // a map in baseline mode or points in madc mode
  kUnknownNode,         // the sender is not a child (or a sensor below one) of this aggregator
  kForgedNode,          // the stream's identity is fixed; the upload speaks for another node
  kClockSkew,           // the epoch is outside the admission window around the aggregator's clock
  kTooLarge,            // bytes or ellipsoids per map above the bound
  kOutOfWorld,          // a centre or box outside the world extent
  kBadShape,            // eigenvalues outside the bounds, or ill-conditioned
  kSequenceConflict,    // an upload sequence seen before with other content
  kEllipsoidConflict,   // an ellipsoid id seen before in the epoch with other geometry
  kInconsistentChunks,  // point chunks that disagree with earlier chunks of the same scan
  kUnknownPeer,         // TLS: the stream's certificate names no child of this aggregator
  kBadBox,              // an oriented box or class out of range: non-finite, sides, yaw, confidence
};
inline constexpr Refusal kLastRefusal = Refusal::kBadBox;
const char* refusalName(Refusal refusal);
// The error kind a refusal is answered with, in one place: kResourceExhausted for too_large (the
// upload may be valid but is above a bound), kInvalidArgument for every other reason (the upload
// breaks a rule and would be refused again). The services turn it into the Ack's gRPC code.
ErrorCode refusalCode(Refusal refusal);

struct Refused {
  Refusal reason = Refusal::kMalformed;
  std::string message;
};

// Checks a map's size and values against the limits (ellipsoid count, world extent, shape
// eigenvalues and condition). `what` prefixes the message (e.g. "map of node 3 for epoch 17").
std::optional<Refused> checkMapBounds(const Map& map, const AdmissionLimits& limits, const std::string& what);

// The clustering radius fogmap accepts (topology eps_m, fogctl --eps): from 1 mm to 100 m. A
// radius outside would make a grid of astronomically many cells or one that clusters a city.
inline constexpr double kMinEpsM = 1e-3;
inline constexpr double kMaxEpsM = 100.0;
// Errors unless kMinEpsM <= eps_m <= kMaxEpsM, min_points >= 1 and max_points >= min_points.
Status validateClusteringParams(const ClusteringParams& params);

}  // namespace fogmap
