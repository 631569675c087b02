#pragma once
// Virtual LiDARs from one real scan: azimuth sectors with overlap, each in its own sensor frame.
#include <span>

#include <Eigen/Geometry>

#include "common/cloud.hpp"
#include "common/topology.hpp"

namespace fogmap {

// The pose (sensor -> scan frame) of sector `split.index`: a rotation about z by the sector's
// central azimuth, so every virtual sensor looks along its own +x.
Eigen::Isometry3d sectorPose(const SectorSplit& split);

// Points of the scan whose azimuth lies in the sector widened by overlap_deg / 2 on each side,
// expressed in the sector's sensor frame (apply sectorPose to return to the scan frame).
Cloud sectorView(std::span<const Point> scan, const SectorSplit& split);

}  // namespace fogmap
