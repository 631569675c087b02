#pragma once
// The only place that translates between fogmap's domain types and the generated protobuf types.
// FromProto validates once at the boundary: a malformed message becomes an Error naming the field.
#include "common/config/admission.hpp"
#include "common/geometry/geofence.hpp"
#include "common/io/messages.hpp"
#include "common/base/status.hpp"
#include "common/tracking/track.hpp"
#include "common/tracking/track_snapshot.hpp"
#include "fogmap/v1/fogmap.pb.h"

namespace fogmap {

// How a map's ellipsoids travel: kCompact as below; kExact every one as v1::Ellipsoid (about 55
// bytes), which a decoder accepts as well (the demo compares the two; tests forge wire faults on it).
enum class EllipsoidWire { kCompact, kExact };

// Maps and global maps: every ellipsoid that fits (fitsCompact) travels as a 22-byte compact record
// (20 bytes in a block whose records' indices run consecutively: the block carries first_index) in
// an EllipsoidBlock of its (node, frame), whose origin is the common frame's (left off the wire)
// when every centre of the (node, frame) lies within a record's reach of it, else the block's first centre in
// canonical order, rounded to cm; an ellipsoid beyond reach (327.67 m per axis) of the newest 4
// blocks of its (node, frame) opens another around its centre. An ellipsoid no record holds (a
// semi-axis of 65.5355 m or more, or below 0.5 mm, more than 65,535 points or a local index above
// 65,535) travels exactly, as v1::Ellipsoid with float32 geometry, in its object.
// Objects on the wire: `objects` lists the objects with exact ellipsoids; the objects whose
// ellipsoids are all records follow them unlisted (`packed_objects` counts them); a block names the
// object of each record as steps from the previous record's (object_step), or names nothing when each
// of its records is an object of its own, numbered after both (an edge's local map is one block per
// frame and no objects).
// Round trip: fromProto(toProto(x)) has x's header, ids, point counts and grouping into objects
// exactly; a packed ellipsoid's geometry within the codec's bound (centre within 0.5 cm per axis,
// semi-axes within 0.5 mm, surface within compactSurfaceErrorBound(largest semi-axis), about
// 9.2 mm + 0.15 mm per metre), an exact one's rounded once to float32. Re-encoding: for
// w = toProto(x), toProto(fromProto(w)) == w as bytes when every packed ellipsoid of x has three
// distinct semi-axes in mm, a rotation not within a quantisation step of a tie between two
// quaternion components, and no value within float rounding of a fit limit. Otherwise the codec
// may write a decoded ellipsoid anew, its geometry again within the bound of the decoded one: a
// sphere, needle or disc (the rotation about an equal pair of axes is free), an axis-aligned
// ellipsoid whose extents are not ascending in x, y, z (an exact tie), and about 2 in 100,000
// random rotations (near ties). An id's frame is left out (of a block or an exact id) when it
// equals the header epoch.
// Points travel as little-endian float32 (intensity is not transmitted).
v1::Map toProto(const MapMessage& message, EllipsoidWire wire = EllipsoidWire::kCompact);
// A position as float64 x, y, z.
void toProto(const Eigen::Vector3d& v, v1::Vec3* out);
Eigen::Vector3d fromProto(const v1::Vec3& v);
v1::PointChunk toProto(const PointChunk& chunk);
v1::GlobalMap toProto(const GlobalMapMessage& message, EllipsoidWire wire = EllipsoidWire::kCompact);
v1::Geofence toProto(const Geofence& fence);
v1::Containment toProto(Containment containment);
v1::DetectionFrame toProto(const tracking::DetectionFrame& frame);
v1::Track toProto(const tracking::Track& track);
// Centroid geometry travels as float32, as ellipsoids do.
v1::CentroidFrame toProto(const tracking::CentroidFrame& frame);

// A map after a trip through a GlobalMap's wire, as a subscriber decodes it (ellipsoids within the
// compact codec's bound): what an oracle compares a published global map with.
Expected<Map> throughGlobalWire(const Map& map);

// The serialised size of the uploads (v1::Upload, as ParentLink counts them) that would carry
// `points` pre-processed points of a frame with `header` in baseline mode, cut into chunks of at
// most `max_points_per_chunk` points, as if numbered from `first_sequence`. Computed from the
// encoding rules without building the points, so an edge in madc mode can report what baseline
// would have cost.
std::size_t baselineUploadBytes(const MapHeader& header, std::size_t points, std::size_t max_points_per_chunk,
                                std::uint64_t first_sequence);

// The answer to upload `sequence` (docs/design.md "Delivery"). Applied and late answers carry
// code 0 (OK); a refusal carries its message as the reason and the gRPC code of its error kind
// (refusalCode, then toGrpcCode): INVALID_ARGUMENT, or RESOURCE_EXHAUSTED for too_large.
v1::Ack appliedAck(std::uint64_t sequence, bool late);
v1::Ack refusedAck(std::uint64_t sequence, const Refused& refused);
// A refusal decided outside the admission rules (a relay that cannot forward), by error kind.
v1::Ack refusedAck(std::uint64_t sequence, const Error& error);

// Every fromProto returns kInvalidArgument with the offending field (and object / ellipsoid /
// "blocks[b] record r" / point index) in the message. Rejects: missing ellipsoid ids or centres,
// shapes that are not 6 finite values of a symmetric positive definite matrix, non-finite centres
// or points, block records not a multiple of 22 bytes (20 with first_index), a first_index whose
// records run past index 2^32 - 1, packed_objects above the number of records, a
// block's object_step neither empty nor one entry per record, steps that name an object outside
// `objects` and `packed_objects`, records decodeCompact
// refuses (a semi-axis of 0 mm, a bad orientation), objects with no ellipsoid (exact or packed),
// duplicate ellipsoid ids (across exact and packed ones), xyz size not a multiple of 12, labels
// not 4 bytes per point, chunk_count 0, chunk index >= chunk count, points beyond total_points,
// unknown modes, geofences that validateGeofence rejects. Boxes do not travel: the map is rebuilt
// in canonical form with boxes computed from the ellipsoids. Header node lists come back sorted.
Expected<MapMessage> fromProto(const v1::Map& message);
Expected<PointChunk> fromProto(const v1::PointChunk& chunk);
Expected<GlobalMapMessage> fromProto(const v1::GlobalMap& message);
Expected<Geofence> fromProto(const v1::Geofence& fence);
Expected<Containment> fromProto(v1::Containment containment);  // rejects UNSPECIFIED and unknown values
// A camera's detections: the camera a name, at most kMaxDetectionsPerFrame detections, every box
// finite with left <= right and top <= bottom, within 1e6 pixels, a finite score, a label of 1 to 64
// printable characters. Each detection is stamped with the frame's camera and capture time.
// More detections than the bound is a kResourceExhausted error (the tracker counts it as too_large).
// The bounds are what one fusion step can take in a period of 100 ms (docs/design.md, "Tracker"):
// 1,000 detections overlaid on 2,000 observations cost about 45 ms, 2,000 observations about 50 ms.
inline constexpr int kMaxDetectionsPerFrame = 1000;
Expected<tracking::DetectionFrame> fromProto(const v1::DetectionFrame& frame);
// An edge's displacement centroids: the edge a name, at most kMaxCentroidsPerFrame centroids, each
// a position of 3 finite values within kMaxCentroidCoordinateM, a covariance of 6 finite values
// (upper triangle) that is positive semi-definite with variances at most kMaxCentroidVarianceM2,
// and at least 2 points; the sensor position finite and within the same bound. More centroids than
// the bound is a kResourceExhausted error.
inline constexpr int kMaxCentroidsPerFrame = 2000;
inline constexpr double kMaxCentroidCoordinateM = 1e6;
inline constexpr double kMaxCentroidVarianceM2 = 1e8;
Expected<tracking::CentroidFrame> fromProto(const v1::CentroidFrame& frame);
// A track (what fogctl watch and the tests read): finite state, a known state value.
Expected<tracking::Track> fromProto(const v1::Track& track);
// A tracker's published tracks (fogctl view): each track as above, a known association.
Expected<tracking::TrackSnapshot> fromProto(const v1::TrackList& list);

}  // namespace fogmap
