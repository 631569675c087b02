#pragma once
// The displacement detector's settings (common/tracking/displacement.hpp): the octree voxel, the
// DBSCAN on displacement points and the z-variance filter, as a plain struct with units in the
// names, two presets and its check. Read from an edge's `displacement:` section
// (common/config/displacement_node.hpp).
#include <cstddef>

#include "common/base/status.hpp"

namespace fogmap::tracking {

// The defaults are the paper's indoor settings (its Table 1).
struct DisplacementParams {
  double voxel_m = 0.1;             // octree voxel edge l_voxel; voxels are aligned to the frame's origin
  double neighbour_m = 0.05;        // DBSCAN d_neighbor: points closer than this (strictly) are neighbours
  std::size_t min_neighbours = 5;   // DBSCAN n_dense: a core point has this many neighbours, itself included
  std::size_t min_points = 10;      // N_cluster: smaller clusters are noise (at least 2: a covariance needs two)
  double min_z_variance_m2 = 0.01;  // sigma_zfilter: clusters whose z sample variance is at most this are dropped

  // The paper's indoor setting (the defaults above).
  static DisplacementParams indoor();
  // Outdoors with a Velodyne HDL-64E (KITTI): 1 m voxels and a DBSCAN that connects its rings.
  static DisplacementParams outdoor();

  bool operator==(const DisplacementParams&) const = default;
};

// Ok, or kInvalidArgument naming the first field out of range.
Status validateDisplacementParams(const DisplacementParams& params);

}  // namespace fogmap::tracking
