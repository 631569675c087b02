#pragma once
// One published set of tracks: what a tracker's subscribers receive (services/tracker publishes
// it; fogctl view and watch read it back through proto_convert).
#include <cstdint>
#include <vector>

#include "common/tracking/track.hpp"
#include "common/tracking/tracker_config.hpp"

namespace fogmap::tracking {

struct TrackSnapshot {
  std::int64_t lidar_time_ns = 0;      // the sensor time of the fused LiDAR frame (global map or epoch)
  std::int64_t published_time_ns = 0;
  Association association = Association::kKalman;
  std::vector<Track> tracks;  // every live track (subscribers choose which to show)
};

}  // namespace fogmap::tracking
