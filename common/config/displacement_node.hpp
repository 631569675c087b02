#pragma once
// An edge's displacement section of the topology (`displacement:`). NodeConfig::displacement holds
// one; include this header to look inside it.
#include <string>

#include "common/config/topology.hpp"
#include "common/tracking/displacement_config.hpp"

namespace fogmap {

// An edge's displacement centroids (`displacement:`, DESIGN.md 2.4): the edge runs the displacement
// detector on each scan it cleaned (in the common frame) and streams the centroids to `tracker`,
// whose input must be centroids. The sensor must stand still.
struct DisplacementNodeConfig {
  std::string tracker;  // the tracker node that fuses them
  // `preset: indoor` (the default; 0.1 m voxels) or `outdoor` (1.0 m voxels, KITTI's HDL-64E),
  // then every key given: voxel_m, neighbour_m, min_neighbours, min_points, min_z_variance_m2.
  tracking::DisplacementParams params;
};

}  // namespace fogmap
