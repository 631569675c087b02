// Displacement centroids against scenes whose answer is known: lattices of points whose centroid and
// covariance have closed forms, and a brute-force voxel set as the oracle of change detection.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "common/io/cloud_io.hpp"
#include "common/tracking/displacement.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap::tracking {
namespace {

// m^3 points on a regular lattice filling a cube of edge `edge_m` centred on `centre`, half a step
// in from each face: their mean is the centre, their population variance per axis s^2 (m^2 - 1) / 12.
Cloud cube(const Eigen::Vector3d& centre, double edge_m, int m) {
  Cloud points;
  const double step = edge_m / m;
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < m; ++j) {
      for (int k = 0; k < m; ++k) {
        const Eigen::Vector3d p = centre + step * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5) -
                                  Eigen::Vector3d::Constant(edge_m / 2.0);
        points.push_back({static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()), 1.0F});
      }
    }
  }
  return points;
}

struct Rect {
  double x0, x1, y0, y1;
  bool contains(double x, double y) const { return x >= x0 && x < x1 && y >= y0 && y < y1; }
};

// Ground around z = 0.05 (inside one 0.1 m voxel layer) on a 2 cm grid over x in [0, 4), y in [-2, 2),
// with a 4 mm checkerboard ripple so that its z variance is small but not zero; `hidden` areas have
// no ground (under and behind an object, as a LiDAR sees it).
Cloud ground(std::initializer_list<Rect> hidden) {
  Cloud points;
  for (int i = 0; i < 200; ++i) {
    for (int j = 0; j < 200; ++j) {
      const double x = 0.02 * (i + 0.5);
      const double y = -2.0 + 0.02 * (j + 0.5);
      bool visible = true;
      for (const Rect& r : hidden) visible = visible && !r.contains(x, y);
      if (!visible) continue;
      const double z = 0.05 + ((i + j) % 2 == 0 ? 0.004 : -0.004);
      points.push_back({static_cast<float>(x), static_cast<float>(y), static_cast<float>(z), 1.0F});
    }
  }
  return points;
}

Cloud concat(Cloud a, const Cloud& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

DisplacementDetector detector(const DisplacementParams& params = DisplacementParams::indoor()) {
  auto d = DisplacementDetector::create(params);
  EXPECT_TRUE(d.ok()) << d.error().message;
  return std::move(d).value();
}

// The sample variance per axis of an m^3 lattice of step s.
double latticeSampleVariance(double step, int m) {
  const double n = std::pow(m, 3);
  return step * step * (m * m - 1) / 12.0 * n / (n - 1.0);
}

TEST(DisplacementDetector, StaticSceneGivesNoCentroidsOnTheSecondFrame) {
  const Cloud scene = concat(ground({{1.8, 3.0, -0.2, 0.2}}), cube({2.0, 0.0, 0.4}, 0.4, 20));
  auto d = detector();
  const auto first = d.push(scene);
  EXPECT_EQ(first.centroids.size(), 1U) << "the box, seen for the first time";
  const auto second = d.push(scene);
  EXPECT_EQ(second.displacement_points, 0U);
  EXPECT_EQ(second.clusters, 0U);
  EXPECT_TRUE(second.centroids.empty());
}

TEST(DisplacementDetector, ABoxMovedFartherThanItsSizeGivesOneCentroidAtItsNewCentre) {
  const Cloud floor = ground({{0.0, 4.0, -0.2, 0.2}});  // a corridor with no ground, so only the box moves
  auto d = detector();
  (void)d.push(concat(floor, cube({1.5, 0.0, 0.4}, 0.4, 20)));
  const auto r = d.push(concat(floor, cube({2.0, 0.0, 0.4}, 0.4, 20)));
  ASSERT_EQ(r.centroids.size(), 1U);
  const DisplacementCentroid& c = r.centroids[0];
  EXPECT_EQ(c.point_count, 8000U);
  EXPECT_EQ(r.displacement_points, 8000U);
  EXPECT_NEAR(c.position.x(), 2.0, 1e-5);
  EXPECT_NEAR(c.position.y(), 0.0, 1e-5);
  EXPECT_NEAR(c.position.z(), 0.4, 1e-5);
  const double variance = latticeSampleVariance(0.02, 20);
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(c.covariance(a, a), variance, 1e-6) << "axis " << a;
    for (int b = 0; b < 3; ++b) {
      if (a != b) {
        EXPECT_NEAR(c.covariance(a, b), 0.0, 1e-6) << a << ", " << b;
      }
    }
  }
}

TEST(DisplacementDetector, ABoxMovedByLessThanItsSizeGivesTheCentroidOfItsLeadingSlab) {
  // Voxels are aligned to the sensor origin. The box spans x in [1.0, 1.4), then [1.26, 1.66): the
  // voxels x in [1.4, 1.7) are new, so the moved points are the 13 lattice layers x = 1.41 ... 1.65,
  // a 13 x 20 x 20 slab centred at x = 1.53 with the box's y and z.
  const Cloud floor = ground({{0.0, 4.0, -0.2, 0.2}});
  auto d = detector();
  (void)d.push(concat(floor, cube({1.2, 0.0, 0.4}, 0.4, 20)));
  const auto r = d.push(concat(floor, cube({1.46, 0.0, 0.4}, 0.4, 20)));
  ASSERT_EQ(r.centroids.size(), 1U);
  EXPECT_EQ(r.centroids[0].point_count, 13U * 20U * 20U);
  EXPECT_NEAR(r.centroids[0].position.x(), 1.53, 1e-5);
  EXPECT_NEAR(r.centroids[0].position.y(), 0.0, 1e-5);
  EXPECT_NEAR(r.centroids[0].position.z(), 0.4, 1e-5);
}

TEST(DisplacementDetector, FlatGroundRevealedByAMovingObjectIsDroppedByTheZFilter) {
  // The box floats 0.2 m up (like a car's body), so the ground's voxel layer below it stays empty.
  // It moves 1.5 m sideways: its footprint and shadow behind it (x in [1.8, 3.0)) are revealed.
  const Cloud before = concat(ground({{1.8, 3.0, -0.2, 0.2}}), cube({2.0, 0.0, 0.4}, 0.4, 20));
  const Cloud after = concat(ground({{1.8, 3.0, 1.3, 1.7}}), cube({2.0, 1.5, 0.4}, 0.4, 20));

  auto d = detector();
  (void)d.push(before);
  const auto r = d.push(after);
  EXPECT_EQ(r.clusters, 2U) << "the box and the revealed ground";
  EXPECT_EQ(r.dropped_flat, 1U);
  ASSERT_EQ(r.centroids.size(), 1U);
  EXPECT_TRUE(r.centroids[0].position.isApprox(Eigen::Vector3d(2.0, 1.5, 0.4), 1e-5));

  // Without the filter the ground patch comes back, flat at z = 0.05: the filter is what dropped it.
  DisplacementParams unfiltered = DisplacementParams::indoor();
  unfiltered.min_z_variance_m2 = 0.0;
  auto u = detector(unfiltered);
  (void)u.push(before);
  const auto all = u.push(after);
  ASSERT_EQ(all.centroids.size(), 2U);
  EXPECT_EQ(all.dropped_flat, 0U);
  const auto& patch = all.centroids[0].position.y() < 1.0 ? all.centroids[0] : all.centroids[1];
  EXPECT_NEAR(patch.position.z(), 0.05, 1e-3);
  EXPECT_NEAR(patch.position.x(), 2.4, 1e-3);
  EXPECT_LT(patch.covariance(2, 2), DisplacementParams::indoor().min_z_variance_m2);
}

TEST(DisplacementDetector, TheFirstFrameIsAllDisplacement) {
  const Cloud box = cube({2.0, 0.0, 0.4}, 0.4, 20);
  const Cloud scene = concat(ground({{1.8, 3.0, -0.2, 0.2}}), box);
  auto d = detector();
  const auto r = d.push(scene);
  EXPECT_EQ(r.displacement_points, scene.size());
  EXPECT_EQ(r.clusters, 2U) << "the ground and the box";
  EXPECT_EQ(r.dropped_flat, 1U) << "the ground is flat";
  ASSERT_EQ(r.centroids.size(), 1U);
  EXPECT_EQ(r.centroids[0].point_count, box.size());
  EXPECT_TRUE(r.centroids[0].position.isApprox(Eigen::Vector3d(2.0, 0.0, 0.4), 1e-5));
}

TEST(DisplacementDetector, DisplacementPointsAreThoseInVoxelsEmptyInThePreviousFrame) {
  // Oracle: the set of voxels floor(p / l) of the previous frame, and a linear scan. Four frames
  // check that only the previous frame counts, not the ones before; the third reaches far beyond
  // the first two, so the octree grows, and the fourth is compared against that grown tree.
  using Key = std::array<std::int64_t, 3>;
  const double voxel = 0.1;
  auto key = [&](const Point& p) {
    return Key{static_cast<std::int64_t>(std::floor(p.x / voxel)), static_cast<std::int64_t>(std::floor(p.y / voxel)),
               static_cast<std::int64_t>(std::floor(p.z / voxel))};
  };
  std::mt19937 rng(11);
  auto random_cloud = [&](float extent, std::size_t n) {
    std::uniform_real_distribution<float> u(-extent, extent);
    Cloud c(n);
    for (auto& p : c) p = {u(rng), u(rng), u(rng), 0.0F};
    return c;
  };
  Cloud wide = concat(random_cloud(1.0F, 3000), random_cloud(40.0F, 500));
  std::shuffle(wide.begin(), wide.end(), rng);  // the tree grows between points of one frame
  const std::array<Cloud, 4> frames{random_cloud(1.0F, 3000), random_cloud(1.0F, 3000), wide, random_cloud(1.0F, 3000)};

  auto d = detector();
  (void)d.push(frames[0]);
  for (std::size_t f = 1; f < frames.size(); ++f) {
    std::set<Key> before;
    for (const Point& p : frames[f - 1]) before.insert(key(p));
    std::size_t expected = 0;
    for (const Point& p : frames[f]) expected += before.count(key(p)) == 0 ? 1 : 0;
    ASSERT_GT(expected, 0U);
    ASSERT_LT(expected, frames[f].size());
    EXPECT_EQ(d.push(frames[f]).displacement_points, expected) << "frame " << f;
  }
}

TEST(DisplacementDetector, NonFinitePointsAreSkippedAndCounted) {
  constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const Cloud floor = ground({{0.0, 4.0, -0.2, 0.2}});
  const Cloud before = concat(floor, cube({1.5, 0.0, 0.4}, 0.4, 20));
  Cloud after = concat(floor, cube({2.0, 0.0, 0.4}, 0.4, 20));
  auto clean = detector();
  (void)clean.push(before);
  const auto expected = clean.push(after);
  ASSERT_EQ(expected.centroids.size(), 1U);

  const Cloud bad{{kNan, 0, 0, 0}, {0, kInf, 0, 0}, {0, 0, -kInf, 0}, {kNan, kNan, kNan, 0}};
  after.insert(after.begin() + 100, bad.begin(), bad.end());
  after.insert(after.end(), bad.begin(), bad.end());
  after.push_back({1e30F, 0.0F, 0.0F, 0.0F});  // finite, but beyond any octree
  auto d = detector();
  const auto first = d.push(concat(before, bad));
  EXPECT_EQ(first.non_finite, bad.size());
  EXPECT_EQ(first.displacement_points, before.size());
  const auto r = d.push(after);
  EXPECT_EQ(r.non_finite, 2 * bad.size());
  EXPECT_EQ(r.beyond_reach, 1U);
  EXPECT_EQ(r.displacement_points, expected.displacement_points);
  ASSERT_EQ(r.centroids.size(), 1U);
  EXPECT_EQ(r.centroids[0].position, expected.centroids[0].position);
  EXPECT_EQ(r.centroids[0].covariance, expected.centroids[0].covariance);

  const auto only_bad = d.push(bad);
  EXPECT_EQ(only_bad.non_finite, bad.size());
  EXPECT_EQ(only_bad.displacement_points, 0U);
  EXPECT_TRUE(only_bad.centroids.empty());
  EXPECT_EQ(d.push(before).displacement_points, before.size()) << "after an empty frame, everything is new";
}

TEST(DisplacementParams, InvalidParamsAreRefusedNamingTheField) {
  EXPECT_TRUE(validateDisplacementParams(DisplacementParams::indoor()).ok());
  EXPECT_TRUE(validateDisplacementParams(DisplacementParams::outdoor()).ok());
  const std::vector<std::tuple<const char*, void (*)(DisplacementParams&)>> cases{
      {"voxel_m", [](DisplacementParams& p) { p.voxel_m = 0.0; }},
      {"voxel_m", [](DisplacementParams& p) { p.voxel_m = -1.0; }},
      {"voxel_m", [](DisplacementParams& p) { p.voxel_m = std::numeric_limits<double>::infinity(); }},
      {"voxel_m", [](DisplacementParams& p) { p.voxel_m = 1e3; }},
      {"neighbour_m", [](DisplacementParams& p) { p.neighbour_m = 0.0; }},
      {"neighbour_m", [](DisplacementParams& p) { p.neighbour_m = std::numeric_limits<double>::quiet_NaN(); }},
      {"min_neighbours", [](DisplacementParams& p) { p.min_neighbours = 0; }},
      {"min_points", [](DisplacementParams& p) { p.min_points = 1; }},
      {"min_z_variance_m2", [](DisplacementParams& p) { p.min_z_variance_m2 = -0.01; }},
      {"min_z_variance_m2", [](DisplacementParams& p) { p.min_z_variance_m2 = std::numeric_limits<double>::infinity(); }},
  };
  for (const auto& [field, spoil] : cases) {
    DisplacementParams p;
    spoil(p);
    const Status s = validateDisplacementParams(p);
    ASSERT_FALSE(s.ok()) << field;
    EXPECT_EQ(s.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(s.error().message.find(field), std::string::npos) << s.error().message;
    const auto d = DisplacementDetector::create(p);
    ASSERT_FALSE(d.ok()) << field;
    EXPECT_EQ(d.error().message, s.error().message);
  }
}

TEST(DisplacementDetector, RealKittiFramesGiveCentroids) {
  const auto dir = test_support::kittiSequenceDir();
  const auto f0 = readKittiBin(dir / "0000000000.bin");
  const auto f1 = readKittiBin(dir / "0000000001.bin");
  ASSERT_TRUE(f0.ok()) << f0.error().message;
  ASSERT_TRUE(f1.ok()) << f1.error().message;
  const DisplacementParams params = DisplacementParams::outdoor();
  auto d = detector(params);
  const auto first = d.push(f0->points);
  EXPECT_EQ(first.displacement_points, f0->points.size());
  const auto r = d.push(f1->points);
  EXPECT_EQ(r.non_finite, 0U);
  EXPECT_GT(r.displacement_points, 0U);
  EXPECT_LT(r.displacement_points, f1->points.size() / 2) << "most of a street stays where it was";
  EXPECT_FALSE(r.centroids.empty());
  EXPECT_EQ(r.clusters, r.centroids.size() + r.dropped_flat);
  for (const auto& c : r.centroids) {
    EXPECT_GE(c.point_count, params.min_points);
    EXPECT_GT(c.covariance(2, 2), params.min_z_variance_m2);
    EXPECT_LT(c.position.head<2>().norm(), 130.0) << "within an HDL-64E's range";
  }
}

}  // namespace
}  // namespace fogmap::tracking
