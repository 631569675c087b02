#include "common/perception/sensor_clustering.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "common/geometry/map.hpp"
#include "common/perception/madc.hpp"
#include "common/base/angles.hpp"

namespace fogmap {
namespace {

// `count` angles from `first` in steps of `step` degrees.
std::vector<double> evenly(double first, double step, int count) {
  std::vector<double> out;
  for (int i = 0; i < count; ++i) out.push_back(first + step * i);
  return out;
}

// Velodyne VLP-16: 16 rings from -15 to +15 degrees, 0.2 degrees between rays.
BeamTable vlp16() { return {evenly(-15.0, 2.0, 16), 0.2}; }

// A small world to cast rays into: axis-aligned boxes, vertical cylinders, optionally a ground.
struct Box {
  Eigen::Vector3d lo, hi;
};
struct Cylinder {
  Eigen::Vector2d centre;
  double radius = 0.25;
  double z0 = 0.0, z1 = 1.8;
};
struct World {
  std::vector<Box> boxes;
  std::vector<Cylinder> cylinders;
  std::optional<double> ground_z;
};

// Slab test: the entry distance of the ray o + t d into the box, t > 0.
std::optional<double> hitBox(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Box& box) {
  double t0 = 0.0;
  double t1 = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (o[a] < box.lo[a] || o[a] > box.hi[a]) return std::nullopt;
      continue;
    }
    double near = (box.lo[a] - o[a]) / d[a];
    double far = (box.hi[a] - o[a]) / d[a];
    if (near > far) std::swap(near, far);
    t0 = std::max(t0, near);
    t1 = std::min(t1, far);
  }
  if (t0 > t1 || t0 <= 0.0) return std::nullopt;
  return t0;
}

// The nearest hit of the ray on the cylinder's side or its top and bottom discs.
std::optional<double> hitCylinder(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Cylinder& c) {
  std::optional<double> best;
  auto keep = [&](double t) {
    if (t > 0.0 && (!best || t < *best)) best = t;
  };
  const Eigen::Vector2d oc = o.head<2>() - c.centre;
  const Eigen::Vector2d dh = d.head<2>();
  const double a = dh.squaredNorm();
  const double b = 2.0 * oc.dot(dh);
  const double k = oc.squaredNorm() - c.radius * c.radius;
  const double disc = b * b - 4.0 * a * k;
  if (a > 0.0 && disc >= 0.0) {
    for (const double t : {(-b - std::sqrt(disc)) / (2.0 * a), (-b + std::sqrt(disc)) / (2.0 * a)}) {
      const double z = o.z() + t * d.z();
      if (z >= c.z0 && z <= c.z1) keep(t);
    }
  }
  if (d.z() != 0.0) {
    for (const double zc : {c.z0, c.z1}) {
      const double t = (zc - o.z()) / d.z();
      if ((o.head<2>() + t * dh - c.centre).squaredNorm() <= c.radius * c.radius) keep(t);
    }
  }
  return best;
}

struct Hit {
  double t = 0.0;
  int object = -1;  // boxes first, then cylinders; the ground is -1
};

std::optional<Hit> castRay(const World& world, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  std::optional<Hit> best;
  auto keep = [&](std::optional<double> t, int object) {
    if (t && (!best || *t < best->t)) best = Hit{*t, object};
  };
  for (std::size_t i = 0; i < world.boxes.size(); ++i) keep(hitBox(o, d, world.boxes[i]), static_cast<int>(i));
  for (std::size_t i = 0; i < world.cylinders.size(); ++i) {
    keep(hitCylinder(o, d, world.cylinders[i]), static_cast<int>(world.boxes.size() + i));
  }
  if (world.ground_z && d.z() < 0.0) keep((*world.ground_z - o.z()) / d.z(), -1);
  return best;
}

// A frame as a LiDAR sees it: for every ring, rays at the given azimuths (degrees from the
// sensor's +x towards +y), returns between the range limits with Gaussian range noise, in the
// world frame; `truth` gets the object hit per point.
struct Scan {
  Cloud points;
  std::vector<int> truth;
};
Scan scanWorld(const World& world, const BeamTable& beams, const Eigen::Isometry3d& pose,
               const std::vector<std::vector<double>>& azimuths_per_ring, double min_range, double max_range,
               double noise_m, std::mt19937_64& rng) {
  std::normal_distribution<double> noise(0.0, noise_m);
  Scan scan;
  for (std::size_t r = 0; r < beams.elevations_deg.size(); ++r) {
    const double e = beams.elevations_deg[r] * kDegToRad;
    for (const double az_deg : azimuths_per_ring[r]) {
      const double az = az_deg * kDegToRad;
      const Eigen::Vector3d d = pose.linear() * Eigen::Vector3d(std::cos(e) * std::cos(az), std::cos(e) * std::sin(az), std::sin(e));
      const auto hit = castRay(world, pose.translation(), d);
      if (!hit) continue;
      const double range = hit->t + (noise_m > 0.0 ? noise(rng) : 0.0);
      if (range < min_range || range > max_range) continue;
      const Eigen::Vector3d p = pose.translation() + range * d;
      scan.points.push_back({static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()), 0.0F});
      scan.truth.push_back(hit->object);
    }
  }
  return scan;
}

// Every ring at every azimuth step of a whole revolution, as a spinning LiDAR fires.
std::vector<std::vector<double>> regularAzimuths(const BeamTable& beams) {
  const int steps = static_cast<int>(std::lround(360.0 / beams.azimuth_step_deg));
  std::vector<double> ring;
  for (int s = 0; s < steps; ++s) ring.push_back(s * beams.azimuth_step_deg);
  return std::vector<std::vector<double>>(beams.elevations_deg.size(), ring);
}

// Boxes and person-sized to pole-sized cylinders at 3 to 45 m from the sensor, in its azimuth
// sector [-sector_deg, sector_deg], a ground below it, seen through rays at random azimuths in
// that sector: `rays` per ring.
Scan randomLidarScan(std::mt19937_64& rng, const BeamTable& beams, const Eigen::Isometry3d& pose, int rays,
                     double max_range, double sector_deg = 60.0) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  World world;
  world.ground_z = pose.translation().z() - 1.5 - 0.3 * uni(rng);
  const int objects = 4 + static_cast<int>(uni(rng) * 10.0);
  for (int k = 0; k < objects; ++k) {
    const double range = 3.0 + uni(rng) * (std::min(max_range, 45.0) - 3.0);
    const double az = (2.0 * uni(rng) - 1.0) * sector_deg * kDegToRad;
    const Eigen::Vector3d at = pose * Eigen::Vector3d(range * std::cos(az), range * std::sin(az), 0.0);
    const double floor = *world.ground_z;
    if (uni(rng) < 0.5) {
      const Eigen::Vector3d half(0.2 + uni(rng) * 1.5, 0.2 + uni(rng) * 1.5, 0.3 + uni(rng) * 1.5);
      world.boxes.push_back({Eigen::Vector3d(at.x() - half.x(), at.y() - half.y(), floor),
                             Eigen::Vector3d(at.x() + half.x(), at.y() + half.y(), floor + 2.0 * half.z())});
    } else {
      world.cylinders.push_back({at.head<2>(), 0.1 + uni(rng) * 0.5, floor, floor + 0.5 + uni(rng) * 3.0});
    }
  }
  std::vector<std::vector<double>> azimuths(beams.elevations_deg.size());
  for (auto& ring : azimuths) {
    for (int i = 0; i < rays; ++i) ring.push_back((2.0 * uni(rng) - 1.0) * sector_deg);
  }
  return scanWorld(world, beams, pose, azimuths, 0.5, max_range, 0.01, rng);
}

// A sensor pose that is not the identity: somewhere, turned about z, slightly tilted.
Eigen::Isometry3d randomPose(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translate(Eigen::Vector3d(20.0 * uni(rng), 20.0 * uni(rng), 1.8 + 0.5 * uni(rng)));
  pose.rotate(Eigen::AngleAxisd(std::numbers::pi * uni(rng), Eigen::Vector3d::UnitZ()));
  pose.rotate(Eigen::AngleAxisd(0.05 * uni(rng), Eigen::Vector3d::UnitX()));
  pose.rotate(Eigen::AngleAxisd(0.05 * uni(rng), Eigen::Vector3d::UnitY()));
  return pose;
}

// Oracle: the linking rule over all pairs, written out from its specification in the header.
// Rule (a) as PCL decides it (eps cast to float and squared in float, FLANN's float distance);
// rule (b) in double from the points' BeamIndex.
Clustering bruteForceSensorClusters(std::span<const Point> points, const SensorClusteringParams& params) {
  const auto geometry = BeamGeometry::make(params);
  EXPECT_TRUE(geometry.ok());
  const std::size_t n = points.size();
  std::vector<BeamIndex> beam(n);
  for (std::size_t i = 0; i < n; ++i) beam[i] = geometry->index(points[i]);
  const double eps = params.clustering.eps_m;
  const auto eps_f = static_cast<float>(eps);
  const float eps2_f = eps_f * eps_f;
  const int bins = geometry->azimuthBins();
  auto euclidean = [&](const Point& p, const Point& q) {
    float d2 = 0.0F;
    float d = p.x - q.x;
    d2 += d * d;
    d = p.y - q.y;
    d2 += d * d;
    d = p.z - q.z;
    d2 += d * d;
    return d2 < eps2_f;
  };
  auto vertical = [&](std::size_t i, std::size_t j) {
    const BeamIndex& a = beam[i];
    const BeamIndex& b = beam[j];
    if (a.ring == BeamIndex::kNoBeam || b.ring == BeamIndex::kNoBeam || std::abs(a.ring - b.ring) != 1) return false;
    const int d = std::abs(a.azimuth_bin - b.azimuth_bin);
    if (std::min(d, bins - d) > params.links.azimuth_window) return false;
    if (!(std::abs(a.range_m - b.range_m) < eps)) return false;
    const int lower = std::min(a.ring, b.ring);
    const double gap_rad = geometry->elevationRad(lower + 1) - geometry->elevationRad(lower);
    const double reach = (params.links.ring_gap_slack * gap_rad) * std::min(a.range_m, b.range_m);
    if (!(reach > eps)) return false;
    const double dx = static_cast<double>(points[i].x) - static_cast<double>(points[j].x);
    const double dy = static_cast<double>(points[i].y) - static_cast<double>(points[j].y);
    const double dz = static_cast<double>(points[i].z) - static_cast<double>(points[j].z);
    return dx * dx + dy * dy + dz * dz < reach * reach;
  };
  DisjointSets sets(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (!isFinitePoint(points[i])) continue;
    for (std::size_t j = i + 1; j < n; ++j) {
      if (!isFinitePoint(points[j])) continue;
      if (euclidean(points[i], points[j]) || vertical(i, j)) sets.unite(i, j);
    }
  }
  std::vector<std::size_t> size(n, 0);
  for (std::size_t i = 0; i < n; ++i) ++size[sets.find(i)];
  std::vector<std::int32_t> labels(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    const auto s = size[sets.find(i)];
    if (isFinitePoint(points[i]) && s >= params.clustering.min_points && s <= params.clustering.max_points) {
      labels[i] = static_cast<std::int32_t>(sets.find(i));
    }
  }
  return canonicalize(labels);
}

Clustering sensorAware(std::span<const Point> points, const SensorClusteringParams& params) {
  auto c = sensorAwareClusters(points, params);
  EXPECT_TRUE(c.ok()) << c.error().message;
  return c.ok() ? std::move(*c) : Clustering{};
}

// What rule (b) does on a cloud, over pairs on adjacent rings within the azimuth window: links
// further apart than eps (that rule (a) cannot make), of them those across the seam of the bins,
// and pairs within the distance bound that depth continuity refuses. The tests' clouds must
// exercise all three.
struct RuleBCounts {
  std::size_t beyond_eps = 0;
  std::size_t across_seam = 0;
  std::size_t depth_refused = 0;
  std::size_t near_points = 0;  // points with a beam whose every ring link reaches no further than eps
};
RuleBCounts ruleBCounts(std::span<const Point> points, const SensorClusteringParams& params) {
  const auto geometry = BeamGeometry::make(params);
  const double eps = params.clustering.eps_m;
  const int bins = geometry->azimuthBins();
  std::vector<BeamIndex> beam;
  for (const auto& p : points) beam.push_back(geometry->index(p));
  RuleBCounts counts;
  const int rings = geometry->rings();
  for (const auto& a : beam) {
    if (a.ring == BeamIndex::kNoBeam) continue;
    double widest_gap = 0.0;
    if (a.ring > 0) widest_gap = geometry->elevationRad(a.ring) - geometry->elevationRad(a.ring - 1);
    if (a.ring + 1 < rings) widest_gap = std::max(widest_gap, geometry->elevationRad(a.ring + 1) - geometry->elevationRad(a.ring));
    counts.near_points += params.links.ring_gap_slack * widest_gap * a.range_m <= eps ? 1 : 0;
  }
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& a = beam[i];
    for (std::size_t j = 0; j < points.size(); ++j) {
      const auto& b = beam[j];
      if (a.ring == BeamIndex::kNoBeam || b.ring != a.ring + 1) continue;
      const int d = std::abs(a.azimuth_bin - b.azimuth_bin);
      if (std::min(d, bins - d) > params.links.azimuth_window) continue;
      const double dist = (points[i].xyz() - points[j].xyz()).cast<double>().norm();
      const double gap = geometry->elevationRad(a.ring + 1) - geometry->elevationRad(a.ring);
      if (!(dist < params.links.ring_gap_slack * gap * std::min(a.range_m, b.range_m))) continue;
      if (!(std::abs(a.range_m - b.range_m) < eps)) {
        ++counts.depth_refused;
      } else if (dist >= eps) {
        ++counts.beyond_eps;
        counts.across_seam += 2 * d > bins ? 1 : 0;
      }
    }
  }
  return counts;
}

TEST(SensorClustering, EqualsBruteForceOnSimulatedLidarClouds) {
  std::mt19937_64 rng(20250611);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const std::vector<BeamTable> tables{
      vlp16(),
      {evenly(-92.0 / 3.0, 4.0 / 3.0, 32), 0.5},                            // HDL-32E, coarser azimuth
      {{7.0, -3.5, -12.0, 1.0, -1.5, 3.0, -6.0, 12.0, -0.2, 10.0}, 0.8},   // irregular, unsorted
  };
  RuleBCounts counts;
  int trials_changed = 0;
  for (int trial = 0; trial < 24; ++trial) {
    const BeamTable& beams = tables[static_cast<std::size_t>(trial) % tables.size()];
    const Eigen::Isometry3d pose = randomPose(rng);
    const int rays = 1800 / static_cast<int>(beams.elevations_deg.size());
    Scan scan = randomLidarScan(rng, beams, pose, rays, 45.0);
    // A few points without a return: non-finite ones are noise and connect to nothing.
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (std::size_t i = 7; i < scan.points.size(); i += 211) scan.points[i].y = nan;
    SensorClusteringParams params;
    params.links.beams = beams;
    params.links.sensor_pose = pose;
    params.clustering.eps_m = 0.2 + 0.4 * uni(rng);
    params.clustering.min_points = 1 + static_cast<std::size_t>(uni(rng) * 8.0);
    params.clustering.max_points = trial % 3 == 0 ? 150 : params.clustering.max_points;
    params.links.ring_gap_slack = 1.0 + 1.5 * uni(rng);
    params.links.azimuth_window = trial % 4;
    ASSERT_GE(scan.points.size(), 300U) << "trial " << trial;
    const Clustering expected = bruteForceSensorClusters(scan.points, params);
    const Clustering actual = sensorAware(scan.points, params);
    ASSERT_EQ(actual.cluster_count, expected.cluster_count) << "trial " << trial;
    ASSERT_EQ(actual.labels, expected.labels) << "trial " << trial;
    const RuleBCounts c = ruleBCounts(scan.points, params);
    counts.beyond_eps += c.beyond_eps;
    counts.depth_refused += c.depth_refused;
    counts.near_points += c.near_points;
    trials_changed += actual.labels != euclideanClusters(scan.points, params.clustering).labels ? 1 : 0;
  }
  // The clouds need rule (b), and its depth test; and they hold points too near for a ring link
  // to reach past eps, which the range image leaves out.
  EXPECT_GT(counts.beyond_eps, 1000U);
  EXPECT_GT(counts.near_points, 1000U);
  EXPECT_GT(counts.depth_refused, 20U);
  EXPECT_GT(trials_changed, 18);
}

// The range image is sorted by counting with a table of where each cell starts where it has few
// cells per point (at most 8, plus 1024), and by a radix sort with cursors over the windows where
// it has many. Both ways, across the seam: a VLP-16's 16 rings of 120 bins (3 degrees: 1,920 cells
// for 600 to 1,700 points) and of 36,000 bins (0.01 degrees: 576,000 cells), with windows of about
// the same angle, and wide enough (+-1.5 degrees) at the fine step for the random rays to link.
TEST(SensorClustering, EqualsBruteForceWithFewAndWithManyCellsPerPoint) {
  std::mt19937_64 rng(4417);
  std::size_t fine_links = 0, coarse_links = 0, across_seam = 0;  // rule (b) links beyond eps
  for (int trial = 0; trial < 8; ++trial) {
    const bool fine = trial % 2 == 1;
    BeamTable beams{evenly(-15.0, 2.0, 16), fine ? 0.01 : 3.0};
    const Eigen::Isometry3d pose = randomPose(rng);
    // The last four turned by half a turn: their rays' sector, +-20 degrees, is across the seam.
    const Scan scan = randomLidarScan(rng, beams, pose, 110, 40.0, trial < 4 ? 60.0 : 20.0);
    SensorClusteringParams params;
    params.links.beams = beams;
    params.links.sensor_pose = trial < 4 ? pose : pose * Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ());
    params.links.azimuth_window = fine ? 150 : 1;
    params.links.ring_gap_slack = 2.0;
    params.clustering.min_points = 2;
    ASSERT_GE(scan.points.size(), 600U) << "trial " << trial;
    const Clustering expected = bruteForceSensorClusters(scan.points, params);
    EXPECT_EQ(sensorAware(scan.points, params).labels, expected.labels) << "trial " << trial;
    const RuleBCounts c = ruleBCounts(scan.points, params);
    (fine ? fine_links : coarse_links) += c.beyond_eps;
    across_seam += c.across_seam;
  }
  EXPECT_GT(fine_links, 100U);
  EXPECT_GT(coarse_links, 100U);
  EXPECT_GT(across_seam, 5U);
}

// The seam of the azimuth bins (behind the sensor, atan2 = +-pi) is crossed by the windows, and
// windows as wide as the ring take every pair of adjacent rings.
TEST(SensorClustering, EqualsBruteForceAcrossTheAzimuthSeamAndWithWholeRingWindows) {
  std::mt19937_64 rng(77);
  std::size_t across_seam = 0;
  for (int trial = 0; trial < 8; ++trial) {
    BeamTable beams{evenly(-15.0, 2.0, 16), trial < 4 ? 3.0 : 7.0};  // 120 or 52 bins (the last one partial)
    const Eigen::Isometry3d pose = randomPose(rng);
    const Scan scan = randomLidarScan(rng, beams, pose, 40, 30.0, 20.0);
    SensorClusteringParams params;
    params.links.beams = beams;
    // The same sensor turned about z by half a turn: the rays' sector [-20, 20] degrees is behind it.
    params.links.sensor_pose = pose * Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::UnitZ());
    params.clustering.min_points = 2;
    params.links.azimuth_window = trial % 4 == 3 ? 100 : trial % 4;
    const Clustering expected = bruteForceSensorClusters(scan.points, params);
    EXPECT_EQ(sensorAware(scan.points, params).labels, expected.labels) << "trial " << trial;
    across_seam += ruleBCounts(scan.points, params).across_seam;
  }
  EXPECT_GT(across_seam, 10U);
}

// Two ring slices of a thin pole straight behind the sensor, one on either side of the bins'
// seam (atan2 = +-pi): adjacent rings, 0.7 m apart at 20 m, linked only across the seam; the
// lower slice in the last bin and the upper one in the first, and at 30 m the other way round.
TEST(SensorClustering, LinksCrossTheAzimuthSeam) {
  auto at = [](double range, double elevation_deg, double azimuth_deg) {
    const double e = elevation_deg * kDegToRad;
    const double a = azimuth_deg * kDegToRad;
    return Point{static_cast<float>(range * std::cos(e) * std::cos(a)), static_cast<float>(range * std::cos(e) * std::sin(a)),
                 static_cast<float>(range * std::sin(e)), 0.0F};
  };
  const Cloud cloud{at(20.0, -1.0, 179.95), at(20.0, 1.0, -179.95), at(30.0, -1.0, -179.9), at(30.0, 1.0, 179.9)};
  SensorClusteringParams params;
  params.links.beams = vlp16();
  params.clustering.min_points = 1;
  const auto geometry = BeamGeometry::make(params);
  ASSERT_TRUE(geometry.ok());
  EXPECT_EQ(geometry->index(cloud[0]).azimuth_bin, 1799);
  EXPECT_EQ(geometry->index(cloud[1]).azimuth_bin, 0);
  EXPECT_EQ(geometry->index(cloud[2]).azimuth_bin, 0);
  EXPECT_EQ(geometry->index(cloud[3]).azimuth_bin, 1799);
  EXPECT_EQ(euclideanClusters(cloud, params.clustering).cluster_count, 4);
  EXPECT_EQ(sensorAware(cloud, params).labels, (std::vector<std::int32_t>{0, 0, 1, 1}));
  EXPECT_EQ(bruteForceSensorClusters(cloud, params).labels, (std::vector<std::int32_t>{0, 0, 1, 1}));
  params.links.azimuth_window = 0;  // bins 1799 and 0 are one apart
  EXPECT_EQ(sensorAware(cloud, params).cluster_count, 4);
}

// The person of the problem: 0.5 m across, 1.8 m tall, 20 m from a VLP-16 mounted at `pose` (1.2 m
// up). Its three ring slices are 0.7 m apart, further than eps 0.35: three components for the exact
// mode, one object for the sensor-aware mode.
const Eigen::Isometry3d kPersonLidarPose(Eigen::Translation3d(0.0, 0.0, 1.2));
Scan personAt20m() {
  World world;
  world.cylinders.push_back({Eigen::Vector2d(20.0, 0.0), 0.25, 0.0, 1.8});
  std::mt19937_64 rng(1);
  return scanWorld(world, vlp16(), kPersonLidarPose, regularAzimuths(vlp16()), 0.5, 100.0, 0.0, rng);
}

TEST(SensorClustering, PersonAt20mIsOneClusterWhereExactModeSplitsIt) {
  const Eigen::Isometry3d pose = kPersonLidarPose;
  const Scan scan = personAt20m();
  ASSERT_GE(scan.points.size(), 12U);
  SensorClusteringParams params;
  params.links.beams = vlp16();
  params.links.sensor_pose = pose;
  params.clustering.min_points = 1;
  const Clustering exact = euclideanClusters(scan.points, params.clustering);
  EXPECT_GE(exact.cluster_count, 3);
  const Clustering aware = sensorAware(scan.points, params);
  EXPECT_EQ(aware.cluster_count, 1);
  EXPECT_EQ(aware.labels, std::vector<std::int32_t>(scan.points.size(), 0));
  // min/max points apply to the object, not to its slices.
  params.clustering.min_points = scan.points.size();
  EXPECT_EQ(sensorAware(scan.points, params).cluster_count, 1);
  EXPECT_EQ(euclideanClusters(scan.points, params.clustering).cluster_count, 0);
  params.clustering.min_points = 1;
  params.clustering.max_points = scan.points.size() - 1;
  EXPECT_EQ(sensorAware(scan.points, params).labels, std::vector<std::int32_t>(scan.points.size(), -1));
}

// MAD-C's GENLOCALMAP clusters as its parameters say: exactly without sensor links, sensor-aware
// with them (one ellipsoid for the person instead of one per ring slice); bad links are an error.
TEST(SensorClustering, GenLocalMapUsesTheSensorAwareModeWhenGivenSensorLinks) {
  const Eigen::Isometry3d pose = kPersonLidarPose;
  const Scan scan = personAt20m();
  MadcParams madc;
  madc.clustering.min_points = 1;
  const auto exact = genLocalMap(scan.points, 7, 3, madc);
  ASSERT_TRUE(exact.ok());
  EXPECT_EQ(exact->clustering.labels, euclideanClusters(scan.points, madc.clustering).labels);
  EXPECT_GE(exact->map.ellipsoidCount(), 3U);

  madc.sensor_links = SensorLinks{vlp16(), pose};
  const auto aware = genLocalMap(scan.points, 7, 3, madc);
  ASSERT_TRUE(aware.ok()) << aware.error().message;
  EXPECT_EQ(aware->clustering.labels, sensorAware(scan.points, SensorClusteringParams{madc.clustering, *madc.sensor_links}).labels);
  ASSERT_EQ(aware->map.ellipsoidCount(), 1U);
  EXPECT_EQ(aware->map.objects[0].ellipsoids[0].point_count, scan.points.size());
  EXPECT_EQ(aware->map.objects[0].ellipsoids[0].id, (EllipsoidId{7, 3, 0}));

  madc.sensor_links->beams.elevations_deg = {1.0};
  const auto bad = genLocalMap(scan.points, 7, 3, madc);
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("beams.elevations_deg needs at least 2 rings"), std::string::npos) << bad.error().message;
}

// An edge prepares its clusterer once and clusters frame after frame with it.
TEST(SensorClustering, APreparedClustererAndLocalMapperGiveEachFrameItsOwnClusters) {
  std::mt19937_64 rng(77);
  SensorClusteringParams params;
  params.links.beams = vlp16();
  params.links.sensor_pose = randomPose(rng);
  params.clustering.min_points = 3;
  const auto clusterer = SensorClusterer::create(params);
  ASSERT_TRUE(clusterer.ok()) << clusterer.error().message;
  MadcParams madc;
  madc.clustering = params.clustering;
  madc.sensor_links = params.links;
  const LocalMapper mapper(madc);
  for (int frame = 0; frame < 5; ++frame) {
    const Scan scan = randomLidarScan(rng, params.links.beams, params.links.sensor_pose, 120, 45.0);
    const Clustering expected = bruteForceSensorClusters(scan.points, params);
    const auto prepared = clusterer->cluster(scan.points);
    ASSERT_TRUE(prepared.ok());
    EXPECT_EQ(prepared->labels, expected.labels) << "frame " << frame;
    const auto local = mapper.map(scan.points, 4, static_cast<std::uint64_t>(frame));
    ASSERT_TRUE(local.ok());
    EXPECT_EQ(local->clustering.labels, expected.labels) << "frame " << frame;
    EXPECT_EQ(local->map, genLocalMap(scan.points, 4, static_cast<std::uint64_t>(frame), madc)->map) << "frame " << frame;
  }
  // Parameters it refuses are refused on every frame, naming the field.
  madc.sensor_links->azimuth_window = -1;
  const LocalMapper refused(madc);
  for (int frame = 0; frame < 2; ++frame) {
    const auto local = refused.map(personAt20m().points, 4, static_cast<std::uint64_t>(frame));
    ASSERT_FALSE(local.ok());
    EXPECT_NE(local.error().message.find("azimuth_window"), std::string::npos) << local.error().message;
  }
}

// Each object of `world` one cluster, nothing else (min_points 1).
void expectObjectsApart(const World& world, const Eigen::Isometry3d& pose, const std::string& what) {
  std::mt19937_64 rng(2);
  const Scan scan = scanWorld(world, vlp16(), pose, regularAzimuths(vlp16()), 0.5, 100.0, 0.0, rng);
  SensorClusteringParams params;
  params.links.beams = vlp16();
  params.links.sensor_pose = pose;
  params.clustering.min_points = 1;
  const Clustering aware = sensorAware(scan.points, params);
  EXPECT_EQ(aware.cluster_count, static_cast<std::int32_t>(world.boxes.size() + world.cylinders.size())) << what;
  EXPECT_EQ(aware.labels, canonicalize(scan.truth).labels) << what;
}

TEST(SensorClustering, PeopleOneBehindTheOtherStayApart) {
  // The second person 2 m further, at the same azimuth but for 0.4 m to the side, so that part of
  // it shows past the first one: their edges meet in the range image, 2 m apart in depth.
  World world;
  world.cylinders.push_back({Eigen::Vector2d(20.0, 0.0), 0.25, 0.0, 1.8});
  world.cylinders.push_back({Eigen::Vector2d(22.0, 0.4), 0.25, 0.0, 1.8});
  expectObjectsApart(world, Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, 1.2)), "2 m in depth");
}

TEST(SensorClustering, PeopleSideBySideStayApart) {
  World world;
  world.cylinders.push_back({Eigen::Vector2d(20.0, -0.5), 0.25, 0.0, 1.8});
  world.cylinders.push_back({Eigen::Vector2d(20.0, 0.5), 0.25, 0.0, 1.8});
  expectObjectsApart(world, Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, 1.2)), "1 m apart side by side");
}

// A crate 20 m away in front of a wall 0.5 m behind it: the crate's top ring and the wall's next
// ring are closer than the vertical bound (about 1 m there), only the depth continuity of rule (b)
// keeps them apart.
TEST(SensorClustering, DepthDiscontinuityKeepsObjectsApart) {
  World world;
  world.boxes.push_back({Eigen::Vector3d(20.0, -0.5, 0.0), Eigen::Vector3d(20.4, 0.5, 1.2)});  // crate
  world.boxes.push_back({Eigen::Vector3d(20.5, -3.0, 0.0), Eigen::Vector3d(20.8, 3.0, 3.0)});  // wall behind
  const Eigen::Isometry3d pose(Eigen::Translation3d(0.0, 0.0, 1.2));
  expectObjectsApart(world, pose, "crate before a wall");

  // The premise: some crate point and wall point on adjacent rings, within the window, are closer
  // than the vertical bound, further apart in range than eps.
  std::mt19937_64 rng(2);
  const Scan scan = scanWorld(world, vlp16(), pose, regularAzimuths(vlp16()), 0.5, 100.0, 0.0, rng);
  SensorClusteringParams params;
  params.links.beams = vlp16();
  params.links.sensor_pose = pose;
  const auto geometry = BeamGeometry::make(params);
  ASSERT_TRUE(geometry.ok());
  bool premise = false;
  for (std::size_t i = 0; i < scan.points.size(); ++i) {
    for (std::size_t j = 0; j < scan.points.size(); ++j) {
      if (scan.truth[i] != 0 || scan.truth[j] != 1) continue;
      const auto a = geometry->index(scan.points[i]);
      const auto b = geometry->index(scan.points[j]);
      const double dist = (scan.points[i].xyz() - scan.points[j].xyz()).cast<double>().norm();
      const double gap = 2.0 * kDegToRad;
      premise = premise || (std::abs(a.ring - b.ring) == 1 && std::abs(a.azimuth_bin - b.azimuth_bin) <= params.links.azimuth_window &&
                            dist < params.links.ring_gap_slack * gap * std::min(a.range_m, b.range_m) &&
                            std::abs(a.range_m - b.range_m) >= params.clustering.eps_m);
    }
  }
  EXPECT_TRUE(premise);
}

// HDL-64E's upper block: 1/3 degree between rings, 1.5 x 1/3 degree x 38 m is 0.33 m, under eps.
// No vertical link can reach past eps, so the sensor-aware mode is the exact one.
TEST(SensorClustering, EqualsExactModeWhereRingsAreCloserThanEps) {
  std::mt19937_64 rng(64);
  const BeamTable upper_block{evenly(2.0, -1.0 / 3.0, 32), 0.1};
  for (int trial = 0; trial < 12; ++trial) {
    const Eigen::Isometry3d pose = randomPose(rng);
    const Scan scan = randomLidarScan(rng, upper_block, pose, 120, 38.0);
    SensorClusteringParams params;
    params.links.beams = upper_block;
    params.links.sensor_pose = pose;
    params.links.azimuth_window = trial % 4;
    params.clustering.min_points = 1 + static_cast<std::size_t>(trial % 5);
    params.clustering.max_points = trial % 3 == 0 ? 100 : params.clustering.max_points;
    const auto geometry = BeamGeometry::make(params);
    ASSERT_TRUE(geometry.ok());
    for (const auto& p : scan.points) {
      ASSERT_LT(params.links.ring_gap_slack * (1.0 / 3.0 + 1e-9) * kDegToRad * geometry->index(p).range_m, params.clustering.eps_m);
    }
    const Clustering exact = euclideanClusters(scan.points, params.clustering);
    EXPECT_GT(exact.cluster_count, 0) << "trial " << trial;
    const Clustering aware = sensorAware(scan.points, params);
    EXPECT_EQ(aware.cluster_count, exact.cluster_count) << "trial " << trial;
    EXPECT_EQ(aware.labels, exact.labels) << "trial " << trial;
  }
}

// The per-point helper: the nearest ring in elevation, the azimuth bin by its formula, whatever
// the order of the table and the pose.
TEST(SensorClustering, BeamIndexIsNearestRingAndAzimuthBin) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  SensorClusteringParams params;
  params.links.beams = {{7.0, -3.5, -12.0, 1.0, -1.5, 3.0, -6.0, 12.0, -0.2, 10.0}, 0.7};
  params.links.sensor_pose = randomPose(rng);
  const auto geometry = BeamGeometry::make(params);
  ASSERT_TRUE(geometry.ok());
  std::vector<double> sorted = params.links.beams.elevations_deg;
  std::sort(sorted.begin(), sorted.end());
  ASSERT_EQ(geometry->rings(), 10);
  EXPECT_EQ(geometry->azimuthBins(), 515);  // 514.3 steps: the last bin partial
  for (int r = 0; r < geometry->rings(); ++r) EXPECT_DOUBLE_EQ(geometry->elevationRad(r), sorted[static_cast<std::size_t>(r)] * kDegToRad);
  const double step = 0.7 * kDegToRad;
  int checked = 0;
  for (int k = 0; k < 20000; ++k) {
    const Eigen::Vector3d p(30.0 * uni(rng), 30.0 * uni(rng), 30.0 * uni(rng));
    const Point point{static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()), 0.0F};
    const Eigen::Vector3d s = params.links.sensor_pose.inverse() * point.xyz().cast<double>();
    const double elevation = std::asin(s.z() / s.norm()) / kDegToRad;
    std::vector<double> distance;
    for (const double e : sorted) distance.push_back(std::abs(e - elevation));
    auto nearest = std::min_element(distance.begin(), distance.end());
    const double t = (std::atan2(s.y(), s.x()) + std::numbers::pi) / step;
    std::vector<double> others = distance;
    others.erase(others.begin() + (nearest - distance.begin()));
    if (*std::min_element(others.begin(), others.end()) - *nearest < 1e-9 || t - std::floor(t) < 1e-9) continue;
    const BeamIndex b = geometry->index(point);
    ASSERT_EQ(b.ring, nearest - distance.begin()) << "elevation " << elevation;
    ASSERT_EQ(b.azimuth_bin, static_cast<int>(std::floor(t)) % 515) << "azimuth " << std::atan2(s.y(), s.x());
    ASSERT_DOUBLE_EQ(b.range_m, s.norm());
    ++checked;
  }
  EXPECT_GT(checked, 19000);
  // Straight behind the sensor (atan2 = pi) is the direction of -pi: bin 0.
  params.links.sensor_pose = Eigen::Isometry3d::Identity();
  params.links.beams.azimuth_step_deg = 0.2;
  const auto plain = BeamGeometry::make(params);
  ASSERT_TRUE(plain.ok());
  EXPECT_EQ(plain->azimuthBins(), 1800);
  EXPECT_EQ(plain->index({-10.0F, 0.0F, 0.0F, 0.0F}).azimuth_bin, 0);
  EXPECT_EQ(plain->index({-10.0F, -0.0F, 0.0F, 0.0F}).azimuth_bin, 0);
  auto at = [](double bins_from_back) {
    const double a = -std::numbers::pi + bins_from_back * 0.2 * kDegToRad;
    return Point{static_cast<float>(10.0 * std::cos(a)), static_cast<float>(10.0 * std::sin(a)), 0.0F, 0.0F};
  };
  EXPECT_EQ(plain->index(at(0.5)).azimuth_bin, 0);
  EXPECT_EQ(plain->index(at(900.5)).azimuth_bin, 900);
  EXPECT_EQ(plain->index(at(1799.5)).azimuth_bin, 1799);
  // Far above the top ring and below the bottom one: the nearest is still a ring.
  EXPECT_EQ(plain->index({0.0F, 0.0F, 10.0F, 0.0F}).ring, 9);
  EXPECT_EQ(plain->index({0.0F, 0.0F, -10.0F, 0.0F}).ring, 0);
}

// Points on and next to the edges of the bins (the sensor frame is the points' frame, so the
// formula below sees the very coordinates the helper sees): the helper's bin is the formula's,
// floor((atan2(y, x) + pi) / step_rad) with the angle pi counted as -pi, however close the edge.
TEST(SensorClustering, AzimuthBinsFollowTheirFormulaAtBinEdges) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  // The last one has too many bins for the table of edge directions.
  for (const double step_deg : {0.2, 0.7, 360.0 / 2048.0, 0.08, 5.0, 0.001}) {
    SensorClusteringParams params;
    params.links.beams = {evenly(-15.0, 2.0, 16), step_deg};
    const auto geometry = BeamGeometry::make(params);
    ASSERT_TRUE(geometry.ok());
    const double step = step_deg * kDegToRad;
    auto formula = [&](const Point& p) {
      const double a = std::atan2(static_cast<double>(p.y), static_cast<double>(p.x));
      const int bin = static_cast<int>(std::floor((a == std::numbers::pi ? 0.0 : a + std::numbers::pi) / step));
      return bin >= geometry->azimuthBins() ? bin - geometry->azimuthBins() : bin;
    };
    int checked = 0;
    const int stride = std::max(1, geometry->azimuthBins() / 3000);
    for (int edge = 0; edge <= geometry->azimuthBins(); edge += stride) {
      for (const double offset : {-1e-6, -1e-9, -1e-13, 0.0, 1e-13, 1e-9, 1e-6}) {
        const double a = -std::numbers::pi + edge * step + offset;
        const double r = 1.0 + 80.0 * uni(rng);
        const Point p{static_cast<float>(r * std::cos(a)), static_cast<float>(r * std::sin(a)), static_cast<float>(r * (uni(rng) - 0.5)), 0.0F};
        ASSERT_EQ(geometry->index(p).azimuth_bin, formula(p)) << "step " << step_deg << ", edge " << edge << ", offset " << offset;
        ++checked;
      }
    }
    // On the axes and diagonals: edges for most steps, and exactly on them (floats rounded the
    // other points' angles by 1e-8 rad or so).
    for (const Point& p : {Point{5.0F, 0.0F, 1.0F, 0.0F}, Point{0.0F, 5.0F, 1.0F, 0.0F}, Point{0.0F, -5.0F, 1.0F, 0.0F},
                           Point{5.0F, 5.0F, 1.0F, 0.0F}, Point{-5.0F, 5.0F, 1.0F, 0.0F}, Point{-5.0F, -5.0F, 1.0F, 0.0F},
                           Point{5.0F, -5.0F, 1.0F, 0.0F}}) {
      EXPECT_EQ(geometry->index(p).azimuth_bin, formula(p)) << "step " << step_deg << " at " << p.x << ", " << p.y;
    }
    // Straight up or down: atan2(0, 0) is 0, the middle of the turn; and exactly behind the sensor.
    // (Zeros of either sign: the transform into the sensor frame turns -0 + 0 into +0.)
    for (const Point& p : {Point{0.0F, 0.0F, 5.0F, 0.0F}, Point{0.0F, 0.0F, -5.0F, 0.0F}, Point{-7.0F, 0.0F, 1.0F, 0.0F}}) {
      EXPECT_EQ(geometry->index(p).azimuth_bin, formula(p)) << "step " << step_deg;
    }
    EXPECT_EQ(geometry->index(Point{-7.0F, -0.0F, 1.0F, 0.0F}).azimuth_bin, 0);
    EXPECT_GT(checked, 7 * 72);  // 5 degrees: 72 bins
  }
}

TEST(SensorClustering, PointsWithoutBeamLinkByDistanceOnly) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const Cloud cloud{{0.0F, 0.0F, 0.0F, 0.0F},  {0.2F, 0.0F, 0.0F, 0.0F}, {nan, 0.1F, 0.0F, 0.0F},
                    {0.0F, 0.0F, inf, 0.0F},    {5.0F, 0.0F, 0.0F, 0.0F}, {0.0F, 0.0F, 0.0F, 0.0F}};
  SensorClusteringParams params;
  params.links.beams = vlp16();
  params.clustering.min_points = 1;
  const auto geometry = BeamGeometry::make(params);
  ASSERT_TRUE(geometry.ok());
  EXPECT_EQ(geometry->index(cloud[0]).ring, BeamIndex::kNoBeam);  // at the sensor's origin
  EXPECT_EQ(geometry->index(cloud[2]).ring, BeamIndex::kNoBeam);
  const Clustering c = sensorAware(cloud, params);
  EXPECT_EQ(c.labels, (std::vector<std::int32_t>{0, 0, -1, -1, 1, 0}));
  EXPECT_EQ(c.labels, bruteForceSensorClusters(cloud, params).labels);
  EXPECT_EQ(sensorAware(Cloud{}, params).cluster_count, 0);
}

// Each refusal names the field to fix.
TEST(SensorClustering, BadParametersAreRefusedNamingTheField) {
  auto refused = [](const SensorClusteringParams& params, const std::string& field) {
    const Status status = validateSensorClusteringParams(params);
    ASSERT_FALSE(status.ok()) << field;
    EXPECT_EQ(status.error().code, ErrorCode::kInvalidArgument) << field;
    EXPECT_NE(status.error().message.find(field), std::string::npos) << status.error().message;
    const auto clustered = sensorAwareClusters(Cloud{{1.0F, 0.0F, 0.0F, 0.0F}}, params);
    ASSERT_FALSE(clustered.ok()) << field;
    EXPECT_EQ(clustered.error().message, status.error().message);
    EXPECT_FALSE(BeamGeometry::make(params).ok()) << field;
  };
  SensorClusteringParams good;
  good.links.beams = vlp16();
  EXPECT_TRUE(validateSensorClusteringParams(good).ok());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();

  auto with = [&](auto change) {
    SensorClusteringParams p = good;
    change(p);
    return p;
  };
  refused(with([](auto& p) { p.links.beams.elevations_deg.clear(); }), "elevations_deg");
  refused(with([](auto& p) { p.links.beams.elevations_deg = {1.0}; }), "elevations_deg");
  refused(with([&](auto& p) { p.links.beams.elevations_deg[3] = nan; }), "elevations_deg[3]");
  refused(with([&](auto& p) { p.links.beams.elevations_deg[0] = -inf; }), "elevations_deg[0]");
  refused(with([](auto& p) { p.links.beams.elevations_deg[5] = 91.0; }), "elevations_deg[5]");
  refused(with([](auto& p) { p.links.beams.elevations_deg[5] = p.links.beams.elevations_deg[9]; }), "elevations_deg");
  refused(with([](auto& p) { p.links.beams.azimuth_step_deg = 0.0; }), "azimuth_step_deg");
  refused(with([](auto& p) { p.links.beams.azimuth_step_deg = -0.2; }), "azimuth_step_deg");
  refused(with([&](auto& p) { p.links.beams.azimuth_step_deg = nan; }), "azimuth_step_deg");
  refused(with([&](auto& p) { p.links.beams.azimuth_step_deg = inf; }), "azimuth_step_deg");
  refused(with([](auto& p) { p.links.beams.azimuth_step_deg = 1e-6; }), "azimuth_step_deg");
  refused(with([](auto& p) { p.links.ring_gap_slack = 0.99; }), "ring_gap_slack");
  refused(with([&](auto& p) { p.links.ring_gap_slack = nan; }), "ring_gap_slack");
  refused(with([&](auto& p) { p.links.ring_gap_slack = inf; }), "ring_gap_slack");
  refused(with([](auto& p) { p.links.azimuth_window = -1; }), "azimuth_window");
  refused(with([](auto& p) { p.clustering.eps_m = 0.0; }), "eps_m");
  refused(with([&](auto& p) { p.clustering.eps_m = nan; }), "eps_m");
  refused(with([](auto& p) { p.links.sensor_pose.linear() *= 2.0; }), "sensor_pose");
  refused(with([&](auto& p) { p.links.sensor_pose.translation().x() = nan; }), "sensor_pose");
  // The edges that are allowed.
  EXPECT_TRUE(validateSensorClusteringParams(with([](auto& p) {
                p.links.ring_gap_slack = 1.0;
                p.links.azimuth_window = 0;
                p.links.beams.elevations_deg = {-90.0, 90.0};
                p.links.beams.azimuth_step_deg = 720.0;
              })).ok());
}

}  // namespace
}  // namespace fogmap
