#pragma once
// Virtual LiDARs from one real scan: azimuth sectors with overlap, each in its own sensor frame.
#include <span>

#include <Eigen/Geometry>

#include "common/geometry/cloud.hpp"

namespace fogmap {

// A virtual LiDAR cut from a real scan: azimuth sector `index` of `views`, widened by overlap.
struct SectorSplit {
  int views = 1;
  int index = 0;
  double overlap_deg = 10.0;
};

// The pose (sensor -> scan frame) of sector `split.index`: a rotation about z by the sector's
// central azimuth, so every virtual sensor looks along its own +x.
Eigen::Isometry3d sectorPose(const SectorSplit& split);

// Points of the scan whose azimuth lies in the sector widened by overlap_deg / 2 on each side,
// expressed in the sector's sensor frame (apply sectorPose to return to the scan frame).
Cloud sectorView(std::span<const Point> scan, const SectorSplit& split);

}  // namespace fogmap
