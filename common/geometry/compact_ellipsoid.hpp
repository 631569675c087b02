#pragma once
// A compact, quantised ellipsoid record: 22 bytes instead of the ~53 of float centre, float shape
// and varint ids, with field sizes on the lines of V2X object messages (ETSI CPM: 1 cm positions,
// fine sizes and angles). A pure codec: the caller carries node, frame and origin once per block and
// sends an ellipsoid that does not fit (fitsCompact false) exactly instead.
//
// Record layout (little-endian, fixed kCompactEllipsoidBytes = 22 bytes, no padding):
//   bytes  0..5   centre: 3 x int16, x y z in cm relative to the block's origin (itself an int32 cm
//                 triple): +-327.67 m around it. The encoder writes -32767..32767.
//   bytes  6..11  semi-axes: 3 x uint16 in mm (1 mm .. 65.535 m), ascending (smallest first): the
//                 square roots of the shape's eigenvalues. 0 is refused; the decoder does not
//                 require the order.
//   bytes 12..17  orientation: the rotation R whose column i is the direction of semi-axis i
//                 (det R = +1), as the unit quaternion q = (w, x, y, z), "smallest three": the
//                 component of largest magnitude is dropped (q negated if needed so that it is
//                 positive) and rebuilt as sqrt(1 - sum of the others^2). Read as one 48-bit
//                 little-endian word W:
//                   bits  0..14  first kept component  } in (w, x, y, z) order without the dropped
//                   bits 15..29  second kept component } one; each is k in 0..32766 standing for
//                   bits 30..44  third kept component  } (k - 16383) / 16383 / sqrt(2), so 0 is exact
//                   bits 45..46  index of the dropped component (0 w, 1 x, 2 y, 3 z)
//                   bit  47      reserved, 0 (a record with it set is refused)
//                 Of the four rotations that describe the same shape (flipping two axes), the
//                 encoder writes the one with the largest |w|, so its dropped component is always w
//                 and (for distinct semi-axes) the record does not depend on the eigen-solver's
//                 choice of signs; an axis-aligned shape with ascending x, y, z extents has
//                 q = (1, 0, 0, 0) exactly. Decoders accept any dropped index; 32767 reads as
//                 16384 / 16383 / sqrt(2) and is never written.
//   bytes 18..19  point_count: uint16.
//   bytes 20..21  local index: uint16, the ellipsoid's id.index (node and frame come from the block).
// A block whose records' indices run consecutively (first, first + 1, ...: an edge's local map) may
// leave bytes 20..21 out of every record (CompactIndex::kImplicit, kCompactRecordBytesWithoutIndex =
// 20 bytes) and carry the first index once; the decoder is then given each record's index.
// The decoded shape is R diag(a^2) R^T, symmetrised exactly, with every a >= 1 mm: always finite,
// symmetric and positive definite, whatever the 22 bytes. Packing a decoded ellipsoid again gives
// the same bytes when its semi-axes differ; where two are equal in mm (needles, discs) the rotation
// about the third is free, comes back off the grid and is rounded anew, so the shape may move by up
// to d (below) per repacking: a relay should forward records rather than repack them.
//
// Error bound. Centre: rounding to 1 cm, at most 0.5 cm per axis, 5 sqrt(3) mm = 8.66 mm in all.
// Semi-axes: rounding to 1 mm, at most 0.5 mm each. Orientation: each kept quaternion component is
// off by at most delta = 1 / (sqrt(2) 32766) = 2.158e-5 (half a step), so the kept three by at most
// sqrt(3) delta; the dropped one, m >= 1/2, is rebuilt as sqrt(1 - |v|^2), whose slope |v| / m is
// at most L = 1.7324 between the exact and the stored v (sqrt(3) where |v|^2 = 3/4, m = 1/2, a hair
// more where m dips below 1/2 on the way), so |q' - q| <= sqrt(1 + L^2) sqrt(3) delta = 7.477e-5,
// and the rotation taking q to q' turns by at most 4 asin(|q' - q| / 2) = 1.4954e-4 rad:
// theta = 1.5e-4 rad. The exact surface point c + R diag(a) u (|u| = 1) and the decoded one
// c' + R' diag(a') u are then at most |c - c'| + max |a_i - a'_i| + |diag(a) u| theta apart, and
// the same holds the other way round, so every point of either surface lies within
//   d(a_max) = 5 sqrt(3) mm + 0.5 mm + 1 um + (a_max + 0.5 mm) theta
// of the other surface (Hausdorff distance), a_max the largest semi-axis of the exact ellipsoid
// (the 0.5 mm covers the decoded one's; 1 um covers rounding in double arithmetic). About 9.2 mm
// plus 0.15 mm per metre of a_max: 13.7 mm at a_max = 30 m.
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "common/base/status.hpp"
#include "common/geometry/ellipsoid.hpp"

namespace fogmap {

inline constexpr std::size_t kCompactEllipsoidBytes = 22;
inline constexpr std::size_t kCompactRecordBytesWithoutIndex = 20;
inline constexpr double kCompactCentreErrorM = 0.005;       // per axis
inline constexpr double kCompactSemiAxisErrorM = 0.0005;    // per semi-axis
inline constexpr double kCompactOrientationErrorRad = 1.5e-4;
inline constexpr double kCompactMinSemiAxisM = 0.0005;      // rounds to 1 mm
inline constexpr double kCompactMaxSemiAxisM = 65.535;

// The distance d(a_max) within which the decoded surface lies of the exact one (see above).
constexpr double compactSurfaceErrorBound(double max_semi_axis_m) {
  return kCompactCentreErrorM * std::numbers::sqrt3 + kCompactSemiAxisErrorM + 1e-6 +
         (max_semi_axis_m + kCompactSemiAxisErrorM) * kCompactOrientationErrorRad;
}

// The point that records' centres are measured from, in whole cm (a sensor's position, a map's first
// centre, rounded).
struct CompactOrigin {
  std::int32_t x_cm = 0;
  std::int32_t y_cm = 0;
  std::int32_t z_cm = 0;
  bool operator==(const CompactOrigin&) const = default;
};

// p rounded to cm; a non-finite coordinate gives 0 and one beyond the int32 range is clamped (the
// origin is only a reference: fitsCompact decides whether an ellipsoid is near enough to it).
CompactOrigin compactOriginNear(const Eigen::Vector3d& p);

// True when e can be packed: finite, symmetric positive definite shape, centre within +-327.67 m of
// origin per axis, every semi-axis in [0.5 mm, 65.5355 m) (what rounds to 1 .. 65,535 mm),
// point_count and id.index at most 65535.
bool fitsCompact(const Ellipsoid& e, const CompactOrigin& origin);
// The centre condition of fitsCompact alone (no eigen-decomposition): within +-327.67 m per axis.
bool compactCentreFits(const Eigen::Vector3d& centre, const CompactOrigin& origin);

// Whether a record holds its ellipsoid's index (22 bytes) or leaves it to its block (20 bytes).
enum class CompactIndex { kInRecord, kImplicit };
constexpr std::size_t compactRecordBytes(CompactIndex index) {
  return index == CompactIndex::kInRecord ? kCompactEllipsoidBytes : kCompactRecordBytesWithoutIndex;
}

// Appends e's record to out and returns true when fitsCompact(e, origin); otherwise appends nothing
// and returns false (the caller then sends e exactly).
[[nodiscard]] bool appendCompact(const Ellipsoid& e, const CompactOrigin& origin, std::string& out,
                                 CompactIndex index = CompactIndex::kInRecord);

// Decodes one record into an ellipsoid with id (node, frame, index): the record's own index (22
// bytes), or `implicit_index` for a record without one (20 bytes). Refuses, naming the ellipsoid and
// the field, a record of another size, a semi-axis of 0, stored quaternion components with squared
// norm above 1, or the reserved orientation bit set.
Expected<Ellipsoid> decodeCompact(std::string_view record, const CompactOrigin& origin, std::uint32_t node,
                                  std::uint64_t frame, std::optional<std::uint32_t> implicit_index = std::nullopt);

// Decodes concatenated records, all with the same origin, node and frame: 22 bytes each, or 20 each
// with indices first_index, first_index + 1, ... Refuses a size that is not a multiple of the
// record's, indices beyond 2^32 - 1, or the first bad record, naming its position.
Expected<std::vector<Ellipsoid>> decodeCompactBlock(std::string_view records, const CompactOrigin& origin,
                                                    std::uint32_t node, std::uint64_t frame,
                                                    std::optional<std::uint32_t> first_index = std::nullopt);

}  // namespace fogmap
