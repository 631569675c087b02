#pragma once
// What a sensor saw of a cluster beyond its ellipsoid (its oriented box and LiDAR class), as a
// compact entry beside the ellipsoid's 22-byte record (compact_ellipsoid.hpp). A pure codec: a block
// of records carries, when any of them has a view, one entry per record in record order.
//
// Entry layout (little-endian, 1, 2, 15 or 16 bytes):
//   byte 0        flags: bit 0 box present; bits 1..4 the box's anchor (BoxAnchor, 0..8; 0 without a
//                 box); bits 5..7 class code: 0 no label, 1..6 ObjectClass + 1.
//   [byte]        with a label: confidence k in 0..255 standing for k / 255.
//   [14 bytes]    with a box:
//                   centre: 3 x int16, in cm from the ellipsoid's centre rounded to cm (what its
//                           record decodes to): +-327.67 m around it;
//                   length, width, height: 3 x uint16 cm (0 .. 655.35 m);
//                   yaw: uint16 k standing for -pi/2 + k pi / 65536 ([-pi/2, pi/2)).
// Error bound: box centre and sizes 0.5 cm, yaw pi / 131072 rad (0.0014 degrees), confidence 1/510.
// A view that does not fit (non-finite fields, a centre beyond reach, a side above 655.35 m, a yaw
// outside [-pi/2, pi/2), a confidence outside [0, 1]) is not written: its ellipsoid travels exactly.
#include <cstddef>
#include <string>
#include <string_view>

#include "common/base/status.hpp"
#include "common/geometry/ellipsoid.hpp"

namespace fogmap {

inline constexpr double kCompactViewLengthErrorM = 0.005;
inline constexpr double kCompactViewYawErrorRad = 2.4e-5;
inline constexpr double kCompactViewConfidenceError = 1.0 / 510.0 + 1e-12;

// True when e has a box or a label.
inline bool hasView(const Ellipsoid& e) { return e.box.has_value() || e.label.has_value(); }
// True when e's box and label (if any) can be written as an entry.
bool viewFitsCompact(const Ellipsoid& e);
// Appends e's entry (1 byte when it has no view) and returns true, or appends nothing and returns
// false when !viewFitsCompact(e).
[[nodiscard]] bool appendCompactView(const Ellipsoid& e, std::string& out);
// Reads the entry at `offset` of `entries` into e (whose centre is the decoded record's) and moves
// offset past it. Refuses, naming the field, an entry cut short, a class code of 7, or an anchor
// above 8 or set without a box.
Status readCompactView(std::string_view entries, std::size_t& offset, Ellipsoid& e);

}  // namespace fogmap
