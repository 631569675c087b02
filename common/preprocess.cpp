#include "common/preprocess.hpp"

#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>
#include <utility>

#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/console/print.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/sac_segmentation.h>

namespace fogmap {
namespace {

// Shortest readable form for error messages ("0.001", "15"), unlike std::to_string's "%f".
std::string str(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

bool isFinitePoint(const Point& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

// PCL reports problems on stderr; every problem we care about is returned as an Error instead.
void silencePcl() { pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS); }

// PCL's VoxelGrid packs voxel coordinates into 32-bit integers and, when they would overflow, prints a
// warning and returns the input unchanged. This mirrors PCL's own check (same float arithmetic), plus
// the per-axis int conversion PCL does not guard, so that case becomes an error instead.
bool voxelIndicesOverflow(const Eigen::Array3f& lo, const Eigen::Array3f& hi, float leaf) {
  constexpr float kIntLimit = 2147483648.0F;  // 2^31
  const float inverse_leaf = 1.0F / leaf;
  std::int64_t voxels = 1;
  for (int axis = 0; axis < 3; ++axis) {
    const float cells = (hi[axis] - lo[axis]) * inverse_leaf;
    const float lo_index = std::floor(lo[axis] * inverse_leaf);
    const float hi_index = std::floor(hi[axis] * inverse_leaf);
    if (!(cells < kIntLimit) || !(std::abs(lo_index) < kIntLimit) || !(std::abs(hi_index) < kIntLimit)) return true;
    voxels *= static_cast<std::int64_t>(cells) + 1;
    if (voxels > std::numeric_limits<std::int32_t>::max()) return true;
  }
  return false;
}

}  // namespace

Cloud transformCloud(std::span<const Point> points, const Eigen::Isometry3d& sensor_to_common) {
  Cloud out;
  out.reserve(points.size());
  for (const Point& p : points) {
    const Eigen::Vector3d q = sensor_to_common * p.xyz().cast<double>();
    out.push_back({static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()), p.intensity});
  }
  return out;
}

Cloud cropCloud(std::span<const Point> points, const CropBox& box) {
  // Compare in float, the points' precision, so a point written with the same value as a bound
  // (e.g. 0.1) counts as on the boundary and is kept.
  const Eigen::Array3f lo = box.min_m.cast<float>().array();
  const Eigen::Array3f hi = box.max_m.cast<float>().array();
  Cloud out;
  for (const Point& p : points) {
    const Eigen::Array3f xyz = p.xyz().array();
    if ((xyz >= lo).all() && (xyz <= hi).all()) out.push_back(p);
  }
  return out;
}

Expected<Cloud> voxelDownsample(std::span<const Point> points, double leaf_m) {
  const float leaf = static_cast<float>(leaf_m);  // PCL works in float
  if (!std::isfinite(leaf) || !(leaf > 0.0F)) {
    return invalidArgument("voxel leaf size must be a positive, finite number of metres (as float), got " +
                           str(leaf_m));
  }

  Eigen::Array3f lo = Eigen::Array3f::Constant(std::numeric_limits<float>::max());
  Eigen::Array3f hi = Eigen::Array3f::Constant(std::numeric_limits<float>::lowest());
  pcl::PointCloud<pcl::PointXYZI>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZI>);
  cloud->reserve(points.size());
  for (const Point& p : points) {
    if (!isFinitePoint(p)) continue;  // PCL would skip them too; skipping here keeps the bounds finite
    lo = lo.min(p.xyz().array());
    hi = hi.max(p.xyz().array());
    pcl::PointXYZI q;
    q.x = p.x;
    q.y = p.y;
    q.z = p.z;
    q.intensity = p.intensity;
    cloud->push_back(q);
  }
  if (cloud->empty()) return Cloud{};
  if (voxelIndicesOverflow(lo, hi, leaf)) {
    const Eigen::Array3f extent = hi - lo;
    return invalidArgument("voxel leaf " + str(leaf_m) + " m is too small for a cloud spanning " + str(extent.x()) +
                           " x " + str(extent.y()) + " x " + str(extent.z()) + " m between (" + str(lo.x()) + ", " +
                           str(lo.y()) + ", " + str(lo.z()) + ") and (" + str(hi.x()) + ", " + str(hi.y()) + ", " +
                           str(hi.z()) + "): PCL's 32-bit voxel indices would overflow");
  }

  silencePcl();
  pcl::VoxelGrid<pcl::PointXYZI> grid;
  grid.setInputCloud(cloud);
  grid.setLeafSize(leaf, leaf, leaf);
  pcl::PointCloud<pcl::PointXYZI> filtered;
  grid.filter(filtered);

  Cloud out;
  out.reserve(filtered.size());
  for (const pcl::PointXYZI& q : filtered) out.push_back({q.x, q.y, q.z, q.intensity});
  return out;
}

Expected<GroundRemoval> removeGround(std::span<const Point> points, const GroundParams& params) {
  if (!std::isfinite(params.distance_threshold_m) || !(params.distance_threshold_m > 0.0)) {
    return invalidArgument("ground distance threshold must be positive and finite, got " +
                           str(params.distance_threshold_m) + " m");
  }
  // PCL treats an angle of 0 as "no constraint", so it is rejected rather than silently ignored.
  if (!(params.max_tilt_deg > 0.0 && params.max_tilt_deg < 90.0)) {
    return invalidArgument("ground max tilt must be in (0, 90) degrees, got " + str(params.max_tilt_deg));
  }
  if (params.max_iterations <= 0) {
    return invalidArgument("ground RANSAC iterations must be positive, got " + std::to_string(params.max_iterations));
  }

  // Only the plane comes from PCL; points are classified below, so the fit may skip non-finite ones.
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->reserve(points.size());
  for (const Point& p : points) {
    if (isFinitePoint(p)) cloud->push_back(pcl::PointXYZ(p.x, p.y, p.z));
  }
  if (cloud->size() < 3) {
    return invalidArgument("ground removal needs at least 3 finite points, got " + std::to_string(cloud->size()));
  }

  // Limitation: the ground is one plane for the whole cloud. On sloped or stepped roads the real
  // ground departs from it with distance, so low objects far away can be cut: an object standing
  // on ground that lies below the plane has its lower part, or all of it, within the threshold. In
  // KITTI object frame 000001 the road rises ahead and the car about 59 m ahead stands on ground
  // about 0.45 m lower than the plane predicts there, so all 9 of its points more than 0.3 m above
  // its box bottom are removed. (Too few points to cluster anyway.) It is not only far objects:
  // in frame 000002 the road descends about 0.35 m over the first 35 m while the plane, fitted to
  // the dense near road, rises slightly; the car 35 m ahead stands 0.5 m below the plane and keeps
  // only 22 of its 52 points more than 0.3 m above its box bottom (its lower half is cut). No
  // threshold or iteration count fixes that with one plane. Fixing it needs a local ground model,
  // for example one plane per range/angle sector.
  silencePcl();
  // PCL seeds its RANSAC generator with a constant (12345) unless asked for randomness, so the same
  // input always gives the same plane.
  pcl::SACSegmentation<pcl::PointXYZ> segmentation;
  segmentation.setModelType(pcl::SACMODEL_PERPENDICULAR_PLANE);
  segmentation.setMethodType(pcl::SAC_RANSAC);
  segmentation.setAxis(Eigen::Vector3f::UnitZ());
  segmentation.setEpsAngle(params.max_tilt_deg * std::numbers::pi / 180.0);
  segmentation.setDistanceThreshold(params.distance_threshold_m);
  segmentation.setMaxIterations(params.max_iterations);
  segmentation.setOptimizeCoefficients(true);
  segmentation.setInputCloud(cloud);
  pcl::PointIndices inliers;
  pcl::ModelCoefficients coefficients;
  segmentation.segment(inliers, coefficients);
  if (inliers.indices.empty() || coefficients.values.size() != 4) {
    return invalidArgument("no ground plane found within " + str(params.max_tilt_deg) +
                           " degrees of horizontal among " + std::to_string(points.size()) + " points");
  }

  Eigen::Vector4d plane(coefficients.values[0], coefficients.values[1], coefficients.values[2],
                        coefficients.values[3]);
  const double normal_length = plane.head<3>().norm();
  if (!(normal_length > 0.0) || !plane.allFinite()) {
    return invalidArgument("the ground plane fit is degenerate (" + std::to_string(points.size()) + " points)");
  }
  plane /= normal_length;
  if (plane.z() < 0.0) plane = -plane;

  // Everything below the plane goes too, not only the inliers: KITTI scans contain spurious
  // returns metres below the road, and nothing real lies underground. (Non-finite points fail the
  // comparison and are removed with the ground.)
  GroundRemoval result;
  result.plane = plane;
  result.non_ground.reserve(points.size());
  for (const Point& p : points) {
    const double height = plane.head<3>().dot(p.xyz().cast<double>()) + plane.w();
    if (height > params.distance_threshold_m) {
      result.non_ground.push_back(p);
    } else {
      ++result.ground_points;
    }
  }
  return result;
}

Expected<Cloud> preprocess(std::span<const Point> points, const PreprocessConfig& config) {
  Cloud cloud = transformCloud(points, config.sensor_to_common);
  if (config.crop) cloud = cropCloud(cloud, *config.crop);
  if (config.voxel_leaf_m) {
    Expected<Cloud> downsampled = voxelDownsample(cloud, *config.voxel_leaf_m);
    if (!downsampled) return downsampled.error();
    cloud = std::move(downsampled).value();
  }
  if (config.ground) {
    Expected<GroundRemoval> ground = removeGround(cloud, *config.ground);
    if (!ground) return ground.error();
    cloud = std::move(ground->non_ground);
  }
  return cloud;
}

}  // namespace fogmap
