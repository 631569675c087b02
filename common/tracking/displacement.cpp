#include "common/tracking/displacement.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include <pcl/octree/octree_pointcloud_changedetector.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "common/clustering.hpp"

namespace fogmap::tracking {
namespace {

// A grid coarser than this, or a neighbourhood wider, sees no single object; the bound also keeps
// the octree's extent and DBSCAN's neighbour lists finite.
constexpr double kMaxLengthM = 100.0;
// Voxels either side of the sensor a point may lie within: far beyond any LiDAR's range, and an
// octree of about 21 levels at most, well inside PCL's 32-bit keys (a point at 1e30 m would
// overflow them).
constexpr double kReachVoxels = 1 << 19;

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
