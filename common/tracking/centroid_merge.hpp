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
// the mean, weighted by its point count; a group without points keeps its first covariance).
// Observations come in the order of their groups' first centroids; `radius_m` <= 0 keeps every
// centroid as its own observation.
std::vector<CloudObservation> mergeCentroids(std::span<const DisplacementCentroid> centroids, double radius_m);

}  // namespace fogmap::tracking
