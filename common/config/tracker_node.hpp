#pragma once
// A tracker node's section of the topology (`tracker:`): the fusion settings and its LiDAR input.
// NodeConfig::tracker holds one; include this header to look inside it.
#include <string>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "common/tracking/centroid_merge.hpp"
#include "common/tracking/tracker_config.hpp"

namespace fogmap {

// Which LiDAR observations a tracker fuses with its cameras' detections (`tracker: {input: ...}`).
// One input, not both: the global map and the centroids see the same objects at the same instants,
// so together they would give each object two measurements a frame.
enum class TrackerInput {
  // The root's global map (every obstacle a measurement: the centroid of its ellipsoids, their
  // spread as covariance). Sees parked and moving objects alike; works with moving sensors.
  kGlobalMap,
  // The displacement centroids its edges stream (the edges whose displacement.tracker names it),
  // merged per epoch across edges. Moving objects only, from static sensors; needs no root.
  kCentroids,
};
// "global_map" or "centroids", as the topology writes it.
const char* trackerInputName(TrackerInput input);
Expected<TrackerInput> parseTrackerInput(const std::string& name);

// A tracker node's settings (`tracker:`): the fusion (common/tracking/tracker_config.hpp) and its
// LiDAR input.
struct TrackerNodeConfig {
  tracking::TrackerConfig tracking;
  TrackerInput input = TrackerInput::kGlobalMap;
  // Input centroids: centroids of one epoch (from any edges) closer than this on the ground are one
  // observation (common/tracking/centroid_merge.hpp); 0 keeps every centroid. Only with centroids.
  double centroid_merge_m = 1.0;
  // Input centroids: each edge's centroids narrower than this radius are placed on the object's
  // axis instead of the side its LiDAR sees (tracking::visibleSideCorrected: people and poles; the
  // merge still groups them as seen); 0 leaves them as Algorithm 1 gives them. Only with centroids.
  double visible_side_max_radius_m = tracking::kVisibleSideMaxRadiusM;
};

}  // namespace fogmap
