#pragma once
// The truth of points that pre-processing made from a simulated frame: transformed, cropped,
// downsampled (a voxel's centroid) and freed of the ground, a processed point keeps the true
// object of the nearest simulated return.
#include <cstdint>
#include <span>
#include <vector>

#include "common/geometry/cloud.hpp"

namespace fogmap::sim {

// For every point of `points`: the truth of the nearest point of `returns` (both in the same
// frame) within `reach_m`, or -1 when there is none (also for kGroundId: ground is no object).
// Exact nearest neighbour on a hashed grid of cell reach_m. `truth` has one entry per return.
std::vector<std::int64_t> truthOfPoints(std::span<const Point> points, std::span<const Point> returns,
                                        std::span<const std::uint32_t> truth, double reach_m);

}  // namespace fogmap::sim
