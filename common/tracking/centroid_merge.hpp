#pragma once
// Displacement centroids of one instant from several LiDARs as one LiDAR frame's observations: an
// object seen by several LiDARs must be one measurement (fed one per LiDAR, the tracker spawns a
// track per extra view and overlays each detection on one LiDAR's centroids only), and the mean of
// views from different sides cancels each view's bias towards its LiDAR. Pure.
#include <span>
#include <vector>

#include "common/tracking/track.hpp"

namespace fogmap::tracking {

// Single linkage on the ground plane: centroids joined by chains of x-y gaps below `radius_m` are
// one observation, at the mean of their positions (each view counts once, however many points it
// has) with the pooled covariance of their points (each centroid's covariance plus its offset from
// the mean, weighted by its point count; a group without points keeps its first covariance) and
// the sum of their point counts.
// Observations come in the order of their groups' first centroids; `radius_m` <= 0 keeps every
// centroid as its own observation.
//
// With `located` (the same centroids, one for one, as the observations should place them, e.g.
// visibleSideCorrected), the groups are still found on `centroids` as the LiDARs saw them, and each
// observation is made of its members' `located` positions and covariances.
std::vector<CloudObservation> mergeCentroids(std::span<const DisplacementCentroid> centroids, double radius_m,
                                             std::span<const DisplacementCentroid> located = {});

// A LiDAR sees the near side of an object, so a centroid lies between the object's centre and the
// sensor. For a narrow upright object (a person, a pole: an upright cylinder of radius r seen from
// afar), the points are spread evenly across the line of sight over [-r, r], so their spread across
// it is r / sqrt(3), and their mean lies pi r / 4 nearer the sensor than the axis. This moves a
// centroid that narrow (r at most `max_radius_m`) that far away from `sensor` on the ground plane;
// wider clusters (a car's side or face) are returned as they are. Same frame for both.
//
// 0.4 m (kVisibleSideMaxRadiusM) takes in people (radius 0.2 to 0.3 m) and keeps out a car's face
// (half its width, 0.9 m); fogctl track-eval measured it on people with 4 VLP-16s, 30 % of the
// detections missing (docs/tracking.md).
inline constexpr double kVisibleSideMaxRadiusM = 0.4;
DisplacementCentroid visibleSideCorrected(const DisplacementCentroid& centroid, const Eigen::Vector3d& sensor,
                                          double max_radius_m);

}  // namespace fogmap::tracking
