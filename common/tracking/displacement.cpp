#include "common/tracking/displacement.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <pcl/octree/octree_pointcloud_changedetector.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "common/perception/clustering.hpp"

namespace fogmap::tracking {
namespace {

// Voxels either side of the sensor a point may lie within: far beyond any LiDAR's range, and an
// octree of about 21 levels at most, well inside PCL's 32-bit keys (a point at 1e30 m would
// overflow them).
constexpr double kReachVoxels = 1 << 19;

}  // namespace

// The octree keeps two buffers, the previous frame's voxels and the current one's, and swaps them
// on each frame, so each frame is inserted once (Algorithm 1 builds the previous frame's tree anew).
struct DisplacementDetector::ChangeDetector {
  using Octree = pcl::octree::OctreePointCloudChangeDetector<pcl::PointXYZ>;
  using PclCloud = pcl::PointCloud<pcl::PointXYZ>;

  // The tree starts as [-voxel, voxel)^3, so voxels are aligned to the sensor origin rather than to
  // the first point. PCL grows it by doubling around the old root, which keeps that alignment and
  // both buffers (the test against a brute-force voxel set covers frames far beyond the first).
  explicit ChangeDetector(double voxel_m) : octree(voxel_m) {
    octree.defineBoundingBox(-voxel_m, -voxel_m, -voxel_m, voxel_m, voxel_m, voxel_m);
  }

  Octree octree;
  bool has_previous = false;
};

DisplacementDetector::DisplacementDetector(const DisplacementParams& params)
    : params_(params), change_(std::make_unique<ChangeDetector>(params.voxel_m)) {}

DisplacementDetector::DisplacementDetector(DisplacementDetector&&) noexcept = default;
DisplacementDetector& DisplacementDetector::operator=(DisplacementDetector&&) noexcept = default;
DisplacementDetector::~DisplacementDetector() = default;

Expected<DisplacementDetector> DisplacementDetector::create(const DisplacementParams& params) {
  if (Status s = validateDisplacementParams(params); !s.ok()) return s.error();
  return DisplacementDetector(params);
}

double DisplacementDetector::reachM() const {
  return params_.voxel_m * kReachVoxels;
}

DisplacementResult DisplacementDetector::push(std::span<const Point> frame) {
  DisplacementResult result;
  const double reach = reachM();
  auto cloud = std::make_shared<ChangeDetector::PclCloud>();
  cloud->reserve(frame.size());
  std::vector<std::size_t> source;  // the frame index of each point of `cloud`
  source.reserve(frame.size());
  for (std::size_t i = 0; i < frame.size(); ++i) {
    const Point& p = frame[i];
    if (!isFinitePoint(p)) {
      ++result.non_finite;
      continue;
    }
    const double m = std::max({std::abs(p.x), std::abs(p.y), std::abs(p.z)});
    if (m >= reach) {
      ++result.beyond_reach;
      continue;
    }
    cloud->push_back(pcl::PointXYZ(p.x, p.y, p.z));
    source.push_back(i);
  }

  // Step 1 to 10: the points in voxels empty in the previous frame (all of them on the first).
  ChangeDetector& change = *change_;
  if (change.has_previous) change.octree.switchBuffers();
  change.octree.setInputCloud(cloud);
  change.octree.addPointsFromInputCloud();
  pcl::Indices moved;
  if (change.has_previous) {
    change.octree.getPointIndicesFromNewVoxels(moved);
    // The octree lists points voxel by voxel; acquisition order makes DBSCAN's border points go
    // to the same cluster as they would on the raw scan.
    std::sort(moved.begin(), moved.end());
  } else {
    moved.resize(cloud->size());
    for (std::size_t k = 0; k < moved.size(); ++k) moved[k] = static_cast<pcl::index_t>(k);
  }
  change.has_previous = true;

  Cloud displaced;
  displaced.reserve(moved.size());
  for (const auto k : moved) displaced.push_back(frame[source[static_cast<std::size_t>(k)]]);
  result.displacement_points = displaced.size();

  // Step 11 to 18: DBSCAN, then keep the clusters that are not flat in z.
  DbscanParams dbscan_params;
  dbscan_params.eps_m = params_.neighbour_m;
  dbscan_params.min_neighbours = params_.min_neighbours;
  dbscan_params.min_cluster_points = params_.min_points;
  const Clustering clustering = dbscan(displaced, dbscan_params);
  result.clusters = static_cast<std::size_t>(clustering.cluster_count);
  for (const ClusterSummary& summary : summarizeClusters(displaced, clustering)) {
    const auto n = static_cast<double>(summary.count());
    // min_points >= 2 (validated), so n - 1 > 0.
    const Eigen::Matrix3d covariance = summary.covariance() * (n / (n - 1.0));
    if (covariance(2, 2) <= params_.min_z_variance_m2) {
      ++result.dropped_flat;
      continue;
    }
    result.centroids.push_back({summary.mean(), covariance, static_cast<std::size_t>(summary.count())});
  }
  return result;
}

}  // namespace fogmap::tracking
