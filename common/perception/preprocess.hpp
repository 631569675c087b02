#pragma once
// Scan pre-processing at the edge: rigid pose transform to the common frame, crop box,
// optional voxel downsampling, ground removal.
#include <cstddef>
#include <optional>
#include <span>

#include <Eigen/Geometry>

#include "common/base/status.hpp"
#include "common/geometry/cloud.hpp"

namespace fogmap {

// Applies the sensor pose (sensor frame -> common frame) to every point; intensity kept.
Cloud transformCloud(std::span<const Point> points, const Eigen::Isometry3d& sensor_to_common);

struct CropBox {
  Eigen::Vector3d min_m{-50.0, -50.0, -3.0};
  Eigen::Vector3d max_m{50.0, 50.0, 3.0};
};
// Keeps points inside the closed box.
Cloud cropCloud(std::span<const Point> points, const CropBox& box);

// Replaces the points of each occupied voxel of edge `leaf_m` by their centroid (PCL VoxelGrid).
Expected<Cloud> voxelDownsample(std::span<const Point> points, double leaf_m);

struct GroundParams {
  double distance_threshold_m = 0.20;  // points at most this far above the local ground (or below it) are ground;
                                       // also the inlier distance of the prior plane's RANSAC fit
  double max_tilt_deg = 15.0;          // the prior plane's normal is within this angle of +z
  int max_iterations = 50;            // RANSAC iterations for the prior plane (50 % inliers: 35 give p = 0.99)
  std::size_t prior_sample_points = 4096;  // the prior is fitted on an evenly strided sample of about this size
  double prior_band_m = 2.5;           // ... of the points at most this far above the sample's 5th percentile of z,
  std::optional<double> ground_z_hint_m;  // ... or, when the ground height in the common frame is known
  double hint_band_m = 0.6;               // (a mounted sensor), of the points this close to it
  double cell_m = 1.0;                 // edge of the square x-y cells of the local ground grid
  int neighbourhood_cells = 1;         // a cell's ground is the lowest estimate within this many cells (1: 3 x 3)
  double max_below_prior_m = 1.5;      // points further below the prior plane are spurious returns:
                                       // always ground, never ground estimates
  double max_above_prior_m = 0.5;      // points further above it (roofs, canopies) are never ground estimates
};

struct GroundRemoval {
  Cloud non_ground;                           // the input order is kept
  Eigen::Vector4d plane{0.0, 0.0, 1.0, 0.0};  // prior plane a x + b y + c z + d = 0, unit normal up (c > 0)
  std::size_t ground_points = 0;              // removed points, non-finite ones included
  bool ground_found = true;                   // false: no near-horizontal plane, nothing but non-finite points removed
};
// Removes the ground and everything below it: a global near-horizontal RANSAC plane (the prior),
// refined per x-y cell to the lowest point within [-max_below, +max_above] of the prior found in the
// cell's neighbourhood (the prior where the neighbourhood has none). Non-finite points are removed.
// Without a near-horizontal plane (a view of walls) nothing else is removed and ground_found is false.
// Errors on invalid parameters, fewer than 3 finite points, or a grid over the
// points of more than 2^24 cells (crop the cloud first).
Expected<GroundRemoval> removeGround(std::span<const Point> points, const GroundParams& params);

struct PreprocessConfig {
  Eigen::Isometry3d sensor_to_common = Eigen::Isometry3d::Identity();
  std::optional<CropBox> crop;            // applied in the common frame
  std::optional<double> voxel_leaf_m;     // no downsampling when empty
  std::optional<GroundParams> ground;     // no ground removal when empty
};
// transform -> crop -> voxel -> ground, in this order.
Expected<Cloud> preprocess(std::span<const Point> points, const PreprocessConfig& config);
// preprocess() as a scan is prepared for clustering (at an edge, or at a baseline root that gets
// the scans whole): with fewer than 3 points left before ground removal nothing above a ground can
// be established, and the scan is a legitimate empty frame rather than an error.
Expected<Cloud> preprocessScan(std::span<const Point> scan, const PreprocessConfig& config);

}  // namespace fogmap
