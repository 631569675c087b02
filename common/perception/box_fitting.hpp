#pragma once
// L-shape fitting of an oriented box to a cluster's points (Zhang et al. 2017, "Efficient L-Shape
// Fitting for Vehicle Detection Using Laser Scanners"; the closeness criterion as Autoware's
// shape_estimation computes it). A LiDAR sees one or two faces of a vehicle: the footprint's yaw
// is the one whose rectangle has the points closest to its edges.
//
// The criterion (the specification): for a yaw t, project the points' (x, y) on e1 = (cos t,
// sin t) and e2 = (-sin t, cos t); with c1, c2 the projections and [min, max] their ranges,
// d_i = max(min(max1 - c1_i, c1_i - min1, max2 - c2_i, c2_i - min2), min_distance_m) and the
// score is the sum of 1 / d_i. The yaw of highest score over [0, 90) degrees is searched on a
// coarse grid, then refined: steps of about a quarter of the last, whole numbers of fine steps, down
// to the fine step, within one last step either side of the best so far (as a brute force on the fine grid would find it when the
// score has one peak within a coarse step). The box spans the points' extents along e1 and e2 (the
// longer axis is the length) and in z.
#include <optional>
#include <span>

#include <Eigen/Core>

#include "common/base/status.hpp"
#include "common/geometry/cloud.hpp"
#include "common/geometry/object_class.hpp"
#include "common/geometry/oriented_box.hpp"

namespace fogmap {

struct BoxFitParams {
  double coarse_step_deg = 5.0;
  double fine_step_deg = 0.25;   // the last refinement's step (steps 5, 1.25, 0.5, 0.25 by default)
  double min_distance_m = 0.01;  // d0 of the criterion: a point on an edge scores 1 / d0
};

// Errors (invalid argument, naming the field) for steps not positive and finite, a fine step
// above the coarse one, a coarse step above 90 degrees, or a min_distance_m not positive and finite.
Status validateBoxFitParams(const BoxFitParams& params);

// The criterion's score of `yaw` on the points (double, the specification's formula): for tests.
double closenessScore(std::span<const Point> points, double yaw, double min_distance_m);

// The box of the finite points of `points`; with `sensor` (in the points' frame) its anchor is the
// face or corner nearest the sensor, else kNone. Errors when no point is finite or the parameters
// are refused.
Expected<OrientedBox> fitOrientedBox(std::span<const Point> points, const std::optional<Eigen::Vector3d>& sensor,
                                     const BoxFitParams& params = {});

// The box of the finite points of `points` with its axes at `yaw` (radians; the longer extent is
// the length, and the yaw follows it), anchored as fitOrientedBox does. Errors when no point is
// finite or the yaw is not.
Expected<OrientedBox> orientedBoxAtYaw(std::span<const Point> points, double yaw, const std::optional<Eigen::Vector3d>& sensor);

// What a class's boxes measure, for the faces a sensor cannot see (a car seen from behind shows
// its width and little of its length).
struct BoxPrior {
  double length_m = 4.4;     // typical length and width: a shorter extent is taken as unseen
  double width_m = 1.8;
  double max_width_m = 2.2;  // no object of the class is wider
};

// The box grown to the prior, its seen faces kept where they are. With the extents a >= b of the
// fit: when a is shorter than the prior's length and no wider than its max width, the seen long
// edge is the object's width (the length runs across it); otherwise the length runs along it. Each
// axis then takes max(extent, prior) and grows away from the sensor when the sensor lies beyond
// the box on that axis (the near face stays), else on both sides alike. Yaw follows the length,
// and the anchor is recomputed.
// With a heading (radians; a tracked vehicle's direction of motion), the box's axis nearer the
// heading is the length, whatever the extents say.
OrientedBox grownToPrior(const OrientedBox& box, const Eigen::Vector3d& sensor, const BoxPrior& prior,
                         std::optional<double> heading = std::nullopt);

// grownToPrior where the sensor is not known but the box's anchor is (a view on the map): as if the
// sensor lay far beyond the anchor, so the anchor face or corner stays; without an anchor (a box of
// several sensors' views) each short axis grows on both sides alike.
OrientedBox grownFromAnchor(const OrientedBox& box, const BoxPrior& prior, std::optional<double> heading = std::nullopt);

// The typical box of a vehicle class: cars 4.4 x 1.8 m (at most 2.2 wide), trucks and buses
// 8 x 2.5 m (at most 3); nothing for the other classes.
std::optional<BoxPrior> vehiclePrior(ObjectClass object_class);

// Boxes of at least this length are vehicles whatever their class says: a car's partial view is
// classed otherwise now and then, and where it is measured must not jump with its class.
inline constexpr double kVehicleMinLengthM = 1.5;
// The prior of an object's box: its class's (vehiclePrior), or a car's for a box of at least
// kVehicleMinLengthM; nothing for the others (people, poles: measured where their points are).
std::optional<BoxPrior> vehiclePriorFor(const OrientedBox& box, const std::optional<ObjectLabel>& label);

}  // namespace fogmap
