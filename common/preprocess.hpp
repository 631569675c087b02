#pragma once
// Scan pre-processing at the edge: rigid pose transform to the common frame, crop box,
// optional voxel downsampling, ground removal.
#include <cstddef>
#include <optional>
#include <span>

#include <Eigen/Geometry>

#include "common/cloud.hpp"
#include "common/status.hpp"

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
  double distance_threshold_m = 0.20;  // points at most this far above the ground plane (or below it) are ground
  double max_tilt_deg = 15.0;          // the ground plane's normal is within this angle of +z
  int max_iterations = 200;            // RANSAC iterations
};

struct GroundRemoval {
  Cloud non_ground;
  Eigen::Vector4d plane{0.0, 0.0, 1.0, 0.0};  // a x + b y + c z + d = 0, unit normal pointing up (c > 0)
  std::size_t ground_points = 0;
};
// Fits the dominant near-horizontal plane (RANSAC) and removes it and everything below it.
// Errors when the cloud has fewer than 3 points or no plane is found.
Expected<GroundRemoval> removeGround(std::span<const Point> points, const GroundParams& params);

struct PreprocessConfig {
  Eigen::Isometry3d sensor_to_common = Eigen::Isometry3d::Identity();
  std::optional<CropBox> crop;            // applied in the common frame
  std::optional<double> voxel_leaf_m;     // no downsampling when empty
  std::optional<GroundParams> ground;     // no ground removal when empty
};
// transform -> crop -> voxel -> ground, in this order.
Expected<Cloud> preprocess(std::span<const Point> points, const PreprocessConfig& config);

}  // namespace fogmap
