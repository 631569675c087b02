#include "common/perception/preprocess.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <cstdint>
#include <limits>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include <pcl/console/print.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/ransac.h>
#include <pcl/sample_consensus/sac_model_perpendicular_plane.h>

#include "common/base/angles.hpp"
#include "common/base/text.hpp"

namespace fogmap {
namespace {

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

// The global plane the local ground is measured from. Errors when there are fewer than 3 finite
// points or no plane within max_tilt_deg of horizontal.
Expected<std::optional<Eigen::Vector4d>> fitPriorPlane(std::span<const Point> points, const GroundParams& params) {
  // The prior only anchors the local ground, so an evenly strided sample is enough and keeps
  // RANSAC at a few milliseconds on a full scan (all points: 50 to 350 ms).
  const std::size_t stride = std::max<std::size_t>(1, points.size() / std::max<std::size_t>(params.prior_sample_points, 3));
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->reserve(points.size() / stride + 1);
  for (std::size_t i = 0; i < points.size(); i += stride) {
    const Point& p = points[i];
    if (isFinitePoint(p)) cloud->push_back(pcl::PointXYZ(p.x, p.y, p.z));
  }
  // Where the ground is roughly known (a mounted sensor: its height), fit only near it, so that
  // walls, roofs and car bodies cannot win the RANSAC vote; else keep the sample near its bottom
  // (from the 5th percentile of z, robust to spurious deep returns).
  if (cloud->size() >= 20) {
    float lo = 0.0F;
    float hi = 0.0F;
    if (params.ground_z_hint_m) {
      lo = static_cast<float>(*params.ground_z_hint_m - params.hint_band_m);
      hi = static_cast<float>(*params.ground_z_hint_m + params.hint_band_m);
    } else {
      std::vector<float> z;
      z.reserve(cloud->size());
      for (const auto& p : *cloud) z.push_back(p.z);
      auto nth = z.begin() + static_cast<std::ptrdiff_t>(z.size() / 20);
      std::nth_element(z.begin(), nth, z.end());
      lo = -std::numeric_limits<float>::infinity();
      hi = *nth + static_cast<float>(params.prior_band_m);
    }
    pcl::PointCloud<pcl::PointXYZ>::Ptr near(new pcl::PointCloud<pcl::PointXYZ>);
    for (const auto& p : *cloud) {
      if (p.z >= lo && p.z <= hi) near->push_back(p);
    }
    if (near->size() >= 3) cloud = near;
  }
  if (cloud->size() < 3) {
    return invalidArgument("ground removal needs at least 3 finite points, got " + std::to_string(cloud->size()));
  }

  silencePcl();
  // RANSAC over planes within max_tilt_deg of horizontal, then a least-squares refit on the
  // inliers (what pcl::SACSegmentation does, without linking pcl_segmentation and pcl_features:
  // 55 MB the services do not otherwise need). PCL seeds its generator with a constant (12345)
  // unless asked for randomness, so the same input always gives the same plane.
  pcl::SampleConsensusModelPerpendicularPlane<pcl::PointXYZ>::Ptr model(
      new pcl::SampleConsensusModelPerpendicularPlane<pcl::PointXYZ>(cloud));
  model->setAxis(Eigen::Vector3f::UnitZ());
  model->setEpsAngle(params.max_tilt_deg * kDegToRad);
  pcl::RandomSampleConsensus<pcl::PointXYZ> ransac(model, params.distance_threshold_m);
  ransac.setMaxIterations(params.max_iterations);
  // A view of walls only (a virtual LiDAR facing a building) has no ground to remove.
  if (!ransac.computeModel(0)) return std::optional<Eigen::Vector4d>{};
  pcl::Indices inliers;
  ransac.getInliers(inliers);
  if (inliers.empty()) return std::optional<Eigen::Vector4d>{};
  Eigen::VectorXf found(4);
  ransac.getModelCoefficients(found);
  Eigen::VectorXf refined(4);
  model->optimizeModelCoefficients(inliers, found, refined);
  model->selectWithinDistance(refined, params.distance_threshold_m, inliers);
  if (refined.size() != 4 || inliers.empty()) return std::optional<Eigen::Vector4d>{};

  Eigen::Vector4d plane = refined.cast<double>();
  const double normal_length = plane.head<3>().norm();
  if (!(normal_length > 0.0) || !plane.allFinite()) {
    return invalidArgument("the ground plane fit is degenerate (" + std::to_string(points.size()) + " points)");
  }
  plane /= normal_length;
  if (plane.z() < 0.0) plane = -plane;
  return std::optional<Eigen::Vector4d>(plane);
}

// Height of the local ground above the prior plane on a flat x-y grid.
struct GroundGrid {
  double min_x = 0.0;
  double min_y = 0.0;
  double inverse_cell = 1.0;
  std::int64_t nx = 0;
  std::int64_t ny = 0;
  std::vector<float> height;  // row-major in y; +inf where no estimate is within reach

  // 0 (the prior plane) off the grid or where no estimate is within reach.
  float heightAt(const Point& p) const {
    const double fx = std::floor((p.x - min_x) * inverse_cell);
    const double fy = std::floor((p.y - min_y) * inverse_cell);
    if (!(fx >= 0.0 && fx < static_cast<double>(nx) && fy >= 0.0 && fy < static_cast<double>(ny))) return 0.0F;
    const auto cell = static_cast<std::size_t>(static_cast<std::int64_t>(fy) * nx + static_cast<std::int64_t>(fx));
    const float h = height[cell];
    return std::isfinite(h) ? h : 0.0F;
  }
};

// One plane cannot follow a road that bends (KITTI 000002: the car 35 m ahead stands 0.5 m below the
// plane fitted to the near road, which cut 58 % of it), so the plane is only a prior and a cell's
// ground is the lowest plausible point nearby. Lowest, since nothing real lies below the ground;
// nearby, since objects hide the ground under themselves, but only a few metres, since real ground
// varies by more than the threshold over longer distances (a 10 x 10 m minimum left 21-23 % of the
// KITTI road ring standing); plausible, since KITTI has spurious returns metres below the road.
// Heights are taken from the prior, not in z, so that a tilted ground does not sink the minimum.
Expected<GroundGrid> localGround(std::span<const Point> points, std::span<const float> height,
                                 const GroundParams& params) {
  const auto below = static_cast<float>(-params.max_below_prior_m);
  const auto above = static_cast<float>(params.max_above_prior_m);
  // A finite height implies finite coordinates.
  const auto isEstimate = [&](std::size_t i) { return height[i] >= below && height[i] <= above; };

  GroundGrid grid;
  double lo_x = std::numeric_limits<double>::infinity();
  double lo_y = lo_x;
  double hi_x = -lo_x;
  double hi_y = -lo_x;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!isEstimate(i)) continue;
    lo_x = std::min(lo_x, static_cast<double>(points[i].x));
    lo_y = std::min(lo_y, static_cast<double>(points[i].y));
    hi_x = std::max(hi_x, static_cast<double>(points[i].x));
    hi_y = std::max(hi_y, static_cast<double>(points[i].y));
  }
  if (!(lo_x <= hi_x)) return grid;  // no estimates: the prior everywhere

  // Padded by the neighbourhood so that points just outside the estimates still see them.
  const double reach_m = params.neighbourhood_cells * params.cell_m;
  grid.min_x = lo_x - reach_m;
  grid.min_y = lo_y - reach_m;
  grid.inverse_cell = 1.0 / params.cell_m;
  const double cells_x = std::floor((hi_x + reach_m - grid.min_x) * grid.inverse_cell) + 1.0;
  const double cells_y = std::floor((hi_y + reach_m - grid.min_y) * grid.inverse_cell) + 1.0;
  constexpr double kMaxCells = 16777216.0;  // 2^24: 64 MiB of heights
  if (!(cells_x * cells_y <= kMaxCells)) {
    return invalidArgument("ground cell " + readableNumber(params.cell_m) + " m is too small for ground spanning " +
                           readableNumber(hi_x - lo_x) + " x " + readableNumber(hi_y - lo_y) + " m: the grid would exceed 2^24 cells");
  }
  grid.nx = static_cast<std::int64_t>(cells_x);
  grid.ny = static_cast<std::int64_t>(cells_y);
  const auto cellOf = [&](const Point& p) {
    const auto clamp = [](double f, std::int64_t n) {
      return std::clamp(static_cast<std::int64_t>(f), std::int64_t{0}, n - 1);
    };
    const std::int64_t ix = clamp(std::floor((p.x - grid.min_x) * grid.inverse_cell), grid.nx);
    const std::int64_t iy = clamp(std::floor((p.y - grid.min_y) * grid.inverse_cell), grid.ny);
    return static_cast<std::size_t>(iy * grid.nx + ix);
  };

  constexpr float kNone = std::numeric_limits<float>::infinity();
  const auto cells = static_cast<std::size_t>(grid.nx * grid.ny);
  std::vector<float> lowest(cells, kNone);
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!isEstimate(i)) continue;
    float& cell = lowest[cellOf(points[i])];
    cell = std::min(cell, height[i]);
  }

  // Square neighbourhood minimum, separably: along x into `along_x`, then along y.
  const std::int64_t r = params.neighbourhood_cells;
  std::vector<float> along_x(cells, kNone);
  for (std::int64_t y = 0; y < grid.ny; ++y) {
    const float* row = lowest.data() + y * grid.nx;
    float* out = along_x.data() + y * grid.nx;
    for (std::int64_t x = 0; x < grid.nx; ++x) {
      const std::int64_t end = std::min(grid.nx, x + r + 1);
      out[x] = *std::min_element(row + std::max<std::int64_t>(0, x - r), row + end);
    }
  }
  grid.height.assign(cells, kNone);
  for (std::int64_t y = 0; y < grid.ny; ++y) {
    const std::int64_t end = std::min(grid.ny, y + r + 1);
    float* out = grid.height.data() + y * grid.nx;
    for (std::int64_t from = std::max<std::int64_t>(0, y - r); from < end; ++from) {
      const float* in = along_x.data() + from * grid.nx;
      for (std::int64_t x = 0; x < grid.nx; ++x) out[x] = std::min(out[x], in[x]);
    }
  }
  return grid;
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
                           readableNumber(leaf_m));
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
    return invalidArgument("voxel leaf " + readableNumber(leaf_m) + " m is too small for a cloud spanning " + readableNumber(extent.x()) +
                           " x " + readableNumber(extent.y()) + " x " + readableNumber(extent.z()) + " m between (" + readableNumber(lo.x()) + ", " +
                           readableNumber(lo.y()) + ", " + readableNumber(lo.z()) + ") and (" + readableNumber(hi.x()) + ", " + readableNumber(hi.y()) + ", " +
                           readableNumber(hi.z()) + "): PCL's 32-bit voxel indices would overflow");
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
                           readableNumber(params.distance_threshold_m) + " m");
  }
  // PCL treats an angle of 0 as "no constraint", so it is rejected rather than silently ignored.
  if (!(params.max_tilt_deg > 0.0 && params.max_tilt_deg < 90.0)) {
    return invalidArgument("ground max tilt must be in (0, 90) degrees, got " + readableNumber(params.max_tilt_deg));
  }
  if (params.max_iterations <= 0) {
    return invalidArgument("ground RANSAC iterations must be positive, got " + std::to_string(params.max_iterations));
  }
  if (!std::isfinite(params.cell_m) || !(params.cell_m > 0.0)) {
    return invalidArgument("ground cell size must be positive and finite, got " + readableNumber(params.cell_m) + " m");
  }
  if (params.neighbourhood_cells < 0) {
    return invalidArgument("ground neighbourhood must be at least 0 cells, got " +
                           std::to_string(params.neighbourhood_cells));
  }
  if (!std::isfinite(params.max_below_prior_m) || !(params.max_below_prior_m >= 0.0) ||
      !std::isfinite(params.max_above_prior_m) || !(params.max_above_prior_m >= 0.0)) {
    return invalidArgument("ground band around the prior plane must be non-negative and finite, got " +
                           readableNumber(params.max_below_prior_m) + " m below and " + readableNumber(params.max_above_prior_m) +
                           " m above");
  }

  const Expected<std::optional<Eigen::Vector4d>> prior = fitPriorPlane(points, params);
  if (!prior) return prior.error();
  if (!prior->has_value()) {
    GroundRemoval none;
    none.ground_found = false;
    for (const Point& p : points) {
      if (isFinitePoint(p)) none.non_ground.push_back(p);
    }
    none.ground_points = points.size() - none.non_ground.size();
    return none;
  }
  const Eigen::Vector4d* plane = &**prior;

  // Heights above the prior; NaN for non-finite points, which then fail every comparison below.
  std::vector<float> height(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    height[i] = static_cast<float>(plane->head<3>().dot(points[i].xyz().cast<double>()) + plane->w());
  }
  const Expected<GroundGrid> grid = localGround(points, height, params);
  if (!grid) return grid.error();

  // Everything below the local ground goes too, not only the ground itself: KITTI scans contain
  // spurious returns metres below the road, and nothing real lies underground.
  const auto below = static_cast<float>(-params.max_below_prior_m);
  const auto threshold = static_cast<float>(params.distance_threshold_m);
  GroundRemoval result;
  result.plane = *plane;
  result.non_ground.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const float h = height[i];
    if (h >= below && h >= grid->heightAt(points[i]) + threshold) {
      result.non_ground.push_back(points[i]);
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

Expected<Cloud> preprocessScan(std::span<const Point> scan, const PreprocessConfig& config) {
  // Ground removal runs apart from preprocess(): a scan with fewer than 3 points left (all cropped
  // away, or a narrow virtual sensor) has no ground to establish and keeps nothing.
  PreprocessConfig without_ground = config;
  without_ground.ground.reset();
  Expected<Cloud> cloud = preprocess(scan, without_ground);
  if (!cloud || !config.ground) return cloud;
  if (cloud->size() < 3) return Cloud{};
  Expected<GroundRemoval> ground = removeGround(*cloud, *config.ground);
  if (!ground) return ground.error();
  return std::move(ground->non_ground);
}

}  // namespace fogmap
