#pragma once
// An obstacle's oriented box (docs/design.md "Oriented boxes"): a footprint rectangle turned by a
// yaw about the vertical axis of the common frame, with a height. A box fitted from one sensor's
// points also says which of its faces or corners that sensor sees nearest: the part of the box
// whose position a tracker can trust when the far side is hidden.
#include <array>
#include <string_view>

#include <Eigen/Core>

namespace fogmap {

// The part of a box nearest its sensor, in the box's own frame: +length is the direction of yaw,
// +width is 90 degrees counter-clockwise from it. A sensor beyond one face only sees that face
// (its middle is the anchor); beyond two, it sees their corner; inside the footprint, nothing.
enum class BoxAnchor {
  kNone = 0,
  kFrontFace,   // +length face
  kRearFace,    // -length face
  kLeftFace,    // +width face
  kRightFace,   // -width face
  kFrontLeft,   // corners: (+length, +width), ...
  kFrontRight,
  kRearLeft,
  kRearRight,
};
std::string_view boxAnchorName(BoxAnchor anchor);

struct OrientedBox {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();  // middle of the footprint and of the height
  double length = 0.0;  // along yaw; length >= width
  double width = 0.0;
  double height = 0.0;
  double yaw = 0.0;     // radians in [-pi/2, pi/2): a box has no heading, only an axis
  BoxAnchor anchor = BoxAnchor::kNone;
  bool operator==(const OrientedBox&) const = default;

  // The anchor's point on the footprint (at the centre's height): the middle of the anchor face,
  // the anchor corner, or the centre for kNone.
  Eigen::Vector3d anchorPoint() const;
  // Which part of this box is nearest a sensor at `sensor` (only x and y count).
  BoxAnchor anchorFor(const Eigen::Vector3d& sensor) const;
  // The footprint's corners (x, y) counter-clockwise from (+length, +width).
  std::array<Eigen::Vector2d, 4> footprint() const;
  // The box's 8 corners: the footprint's at the bottom (centre z - height / 2), then at the top.
  std::array<Eigen::Vector3d, 8> corners() const;
};

// True when the two boxes' footprints overlap (touching counts): separating axes of both.
bool footprintsOverlap(const OrientedBox& a, const OrientedBox& b);

// Yaw folded into [-pi/2, pi/2) (a box's axis is the same turned by pi).
double foldedYaw(double yaw);
// The smallest angle between two box axes, in [0, pi/2].
double axisAngleBetween(double yaw_a, double yaw_b);
// The smallest angle between two headings (directions, unlike axes), in [0, pi].
double headingAngleBetween(double heading_a, double heading_b);

}  // namespace fogmap
