#pragma once
// Spinning LiDAR models as their makers publish them: the vertical angle of every laser, the
// horizontal steps per revolution at the default rate, the range limits.
#include <string>
#include <vector>

#include "common/base/status.hpp"

namespace fogmap {

struct LidarModel {
  std::string name;
  std::vector<double> elevations_deg;  // one per laser (ring), in ring order, up is positive
  int azimuth_steps = 0;               // rays per laser per revolution
  double rate_hz = 10.0;               // revolutions per second
  double min_range_m = 0.0;
  double max_range_m = 0.0;
  int rings() const { return static_cast<int>(elevations_deg.size()); }
  int raysPerFrame() const { return rings() * azimuth_steps; }
};

// "VLP-16", "HDL-32E", "HDL-64E" (as on KITTI's car), "OS1-64"; kNotFound names the known models.
Expected<LidarModel> lidarModel(const std::string& name);
std::vector<std::string> lidarModelNames();

}  // namespace fogmap
