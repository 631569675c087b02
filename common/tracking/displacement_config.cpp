#include "common/tracking/displacement_config.hpp"

#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

namespace fogmap::tracking {
namespace {

// A grid coarser than this, or a neighbourhood wider, sees no single object; the bound also keeps
// the octree's extent and DBSCAN's neighbour lists finite.
constexpr double kMaxLengthM = 100.0;

std::string num(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6g", v);
  return buffer;
}

}  // namespace

DisplacementParams DisplacementParams::indoor() { return {}; }

// Measured on the bundled KITTI raw scans 0 to 4 (frames 1 to 4 against their predecessors, about
// 2k displacement points each). The HDL-64E's rings are 0.4 degrees apart, 0.15 m at 20 m and
// 0.45 m at 65 m, so the indoor 0.05 m joins points only along a ring: no centroid at all, every
// cluster a flat arc. 0.5 m joins neighbouring rings out to about 70 m and gives 13 to 20 centroids
// a frame, among them cars on the cross street 20 m and 65 m away, found in every frame 1.3 m
// further on; 0.3 m gives 8 to 11 (rings farther than 40 m no longer join), 1.0 m 13 to 25 from
// clusters that join objects up to 1 m apart. The far cars have 27 to 37 points and the near one
// drops to 10 in one frame, hence 10 points a cluster; 5 neighbours and 3 or 10 differ little.
DisplacementParams DisplacementParams::outdoor() {
  DisplacementParams p;
  p.voxel_m = 1.0;
  p.neighbour_m = 0.5;
  p.min_neighbours = 5;
  p.min_points = 10;
  return p;
}

Status validateDisplacementParams(const DisplacementParams& p) {
  for (const auto& [name, value] : {std::pair{"voxel_m", p.voxel_m}, std::pair{"neighbour_m", p.neighbour_m}}) {
    if (!std::isfinite(value) || value <= 0.0 || value > kMaxLengthM) {
      return invalidArgument(std::string("displacement ") + name + " must be above 0 and at most " + num(kMaxLengthM) +
                             " m, got " + num(value));
    }
  }
  if (p.min_neighbours < 1) {
    return invalidArgument("displacement min_neighbours must be at least 1 (a point is its own neighbour), got 0");
  }
  if (p.min_points < 2) {
    return invalidArgument("displacement min_points must be at least 2 (a cluster's covariance needs two points), got " +
                           std::to_string(p.min_points));
  }
  if (!std::isfinite(p.min_z_variance_m2) || p.min_z_variance_m2 < 0.0) {
    return invalidArgument("displacement min_z_variance_m2 must be a finite number at least 0, got " +
                           num(p.min_z_variance_m2));
  }
  return {};
}

}  // namespace fogmap::tracking
