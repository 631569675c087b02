#include "common/perception/clustering.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <random>
#include <string>

#include "common/geometry/map.hpp"
#include "common/io/cloud_io.hpp"
#include "common/perception/preprocess.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap {
namespace {

// Oracle: all pairs, "closer than eps" decided exactly as PCL's EuclideanClusterExtraction decides
// it (the tolerance cast to float, squared in float; distances as FLANN's L2_Simple).
Clustering bruteForceClusters(std::span<const Point> points, const ClusteringParams& params) {
  const auto eps = static_cast<float>(params.eps_m);
  const float eps2 = eps * eps;
  DisjointSets sets(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    for (std::size_t j = i + 1; j < points.size(); ++j) {
      float d2 = 0.0F;
      float d = points[i].x - points[j].x;
      d2 += d * d;
      d = points[i].y - points[j].y;
      d2 += d * d;
      d = points[i].z - points[j].z;
      d2 += d * d;
      if (d2 < eps2) sets.unite(i, j);
    }
  }
  std::vector<std::size_t> size(points.size(), 0);
  for (std::size_t i = 0; i < points.size(); ++i) ++size[sets.find(i)];
  std::vector<std::int32_t> labels(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto s = size[sets.find(i)];
    labels[i] = (s >= params.min_points && s <= params.max_points) ? static_cast<std::int32_t>(sets.find(i)) : -1;
  }
  return canonicalize(labels);
}

// Blobs of points around random centres plus uniform clutter, optionally far from the origin.
Cloud randomScene(std::mt19937_64& rng, std::size_t n, double extent, double offset) {
  std::uniform_real_distribution<double> uni(-extent, extent);
  std::normal_distribution<double> blob(0.0, 0.3);
  std::uniform_int_distribution<int> blobs(1, 12);
  std::vector<Eigen::Vector3d> centres(static_cast<std::size_t>(blobs(rng)));
  for (auto& c : centres) c = {uni(rng), uni(rng), uni(rng) * 0.2};
  Cloud cloud;
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Vector3d p;
    if (i % 4 == 0) {
      p = {uni(rng), uni(rng), uni(rng) * 0.2};
    } else {
      p = centres[i % centres.size()] + Eigen::Vector3d(blob(rng), blob(rng), blob(rng));
    }
    p.array() += offset;
    cloud.push_back({static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()), 0.0F});
  }
  return cloud;
}

TEST(Clustering, EqualsBruteForceOnRandomClouds) {
  std::mt19937_64 rng(20240611);
  std::uniform_real_distribution<double> eps_dist(0.05, 0.8);
  std::uniform_int_distribution<std::size_t> min_dist(1, 15);
  for (int trial = 0; trial < 200; ++trial) {
    const double offset = trial % 5 == 0 ? 1000.0 : 0.0;
    const Cloud cloud = randomScene(rng, 300 + static_cast<std::size_t>(trial) * 5, 3.0 + trial % 7, offset);
    ClusteringParams params;
    params.eps_m = eps_dist(rng);
    params.min_points = min_dist(rng);
    params.max_points = trial % 3 == 0 ? 200 : params.max_points;
    const Clustering expected = bruteForceClusters(cloud, params);
    const Clustering actual = euclideanClusters(cloud, params);
    ASSERT_EQ(actual.cluster_count, expected.cluster_count) << "trial " << trial;
    ASSERT_EQ(actual.labels, expected.labels) << "trial " << trial;
  }
}

// Clouds with enough occupied cells that every thread gets a share of the columns; clusters
// cross the boundaries between the threads' ranges.
TEST(Clustering, ThreadedSearchEqualsBruteForce) {
  std::mt19937_64 rng(99);
  for (int trial = 0; trial < 4; ++trial) {
    const Cloud cloud = randomScene(rng, 14000, 12.0, trial % 2 == 0 ? 0.0 : 300.0);
    ClusteringParams params;
    params.eps_m = 0.12 + 0.04 * trial;
    params.min_points = 3;
    const Clustering expected = bruteForceClusters(cloud, params);
    for (const std::size_t threads : {1, 2, 3}) {
      params.threads = threads;
      const Clustering actual = euclideanClusters(cloud, params);
      ASSERT_EQ(actual.labels, expected.labels) << "trial " << trial << ", " << threads << " threads";
    }
  }
}

TEST(Clustering, NonFinitePointsAreNoiseAndConnectNothing) {
  std::mt19937_64 rng(5);
  const Cloud finite = randomScene(rng, 2000, 5.0, 0.0);
  Cloud cloud;
  std::vector<bool> bad;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  for (std::size_t i = 0; i < finite.size(); ++i) {
    if (i % 97 == 0) {
      cloud.push_back({i % 2 == 0 ? nan : finite[i].x, finite[i].y, i % 2 == 0 ? finite[i].z : -inf, 0.0F});
      bad.push_back(true);
    }
    cloud.push_back(finite[i]);
    bad.push_back(false);
  }
  ClusteringParams params;
  params.min_points = 3;
  const Clustering expected = bruteForceClusters(finite, params);
  for (const Clustering& actual : {euclideanClusters(cloud, params), pclEuclideanClusters(cloud, params, false)}) {
    ASSERT_EQ(actual.labels.size(), cloud.size());
    EXPECT_EQ(actual.cluster_count, expected.cluster_count);
    std::vector<std::int32_t> finite_labels;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      if (bad[i]) {
        EXPECT_EQ(actual.labels[i], -1) << "point " << i;
      } else {
        finite_labels.push_back(actual.labels[i]);
      }
    }
    EXPECT_EQ(finite_labels, expected.labels);
  }
  const Clustering db = dbscan(cloud, DbscanParams{});
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (bad[i]) {
      EXPECT_EQ(db.labels[i], -1) << "point " << i;
    }
  }
}

TEST(Clustering, PointsExactlyEpsApartAreNotConnected) {
  // 0.5 is exact in float, so the squared distance equals eps^2 exactly: strict "<" separates.
  Cloud cloud;
  for (int i = 0; i < 10; ++i) cloud.push_back({0.5F * static_cast<float>(i), 0.0F, 0.0F, 0.0F});
  ClusteringParams params;
  params.eps_m = 0.5;
  params.min_points = 1;
  const Clustering c = euclideanClusters(cloud, params);
  EXPECT_EQ(c.cluster_count, 10);
  EXPECT_EQ(c.labels, bruteForceClusters(cloud, params).labels);
  params.eps_m = 0.5001;
  EXPECT_EQ(euclideanClusters(cloud, params).cluster_count, 1);
}

// PCL casts eps to float and squares it in float; eps^2 rounded from double is the next float up
// for eps = 0.35. Points exactly 0.35F apart lie between the two: not connected, whether they are
// consecutive in the input (the shortcut for scan order) or not (the grid search).
TEST(Clustering, PointsFloatEpsApartAreNotConnectedLikePcl) {
  const Cloud consecutive{{0.0F, 0.0F, 0.0F, 0.0F}, {0.35F, 0.0F, 0.0F, 0.0F}, {50.0F, 0.0F, 0.0F, 0.0F}};
  const Cloud apart{{0.0F, 0.0F, 0.0F, 0.0F}, {50.0F, 0.0F, 0.0F, 0.0F}, {0.35F, 0.0F, 0.0F, 0.0F}};
  ClusteringParams params;
  params.eps_m = 0.35;
  params.min_points = 1;
  for (const Cloud& cloud : {consecutive, apart}) {
    const Clustering pcl = pclEuclideanClusters(cloud, params, false);
    EXPECT_EQ(pcl.cluster_count, 3);
    EXPECT_EQ(euclideanClusters(cloud, params).labels, pcl.labels);
    EXPECT_EQ(bruteForceClusters(cloud, params).labels, pcl.labels);
  }
}

// Inputs at the edges of float and of the integer grid: fogmap must still give PCL's partition,
// which here is also the brute-force one.
void expectPclPartition(const Cloud& cloud, const ClusteringParams& params, const std::string& what) {
  const Clustering pcl = pclEuclideanClusters(cloud, params, false);
  EXPECT_EQ(pcl.labels, bruteForceClusters(cloud, params).labels) << what;
  EXPECT_EQ(euclideanClusters(cloud, params).labels, pcl.labels) << what;
  EXPECT_EQ(euclideanClusters(cloud, params).cluster_count, pcl.cluster_count) << what;
}

TEST(Clustering, FarOutlierGivesPclPartition) {
  std::mt19937_64 rng(30);
  Cloud cloud = randomScene(rng, 2000, 10.0, 0.0);
  const std::size_t outlier = 1000;
  cloud.insert(cloud.begin() + outlier, Point{1e30F, 0.0F, 0.0F, 0.0F});
  for (const std::size_t min_points : {std::size_t{1}, std::size_t{5}}) {
    ClusteringParams params;
    params.min_points = min_points;
    expectPclPartition(cloud, params, "min points " + std::to_string(min_points));
    // The outlier connects to nothing: a cluster of its own with min 1, noise otherwise.
    const Clustering ours = euclideanClusters(cloud, params);
    const auto label = ours.labels[outlier];
    if (min_points == 1) {
      EXPECT_EQ(std::count(ours.labels.begin(), ours.labels.end(), label), 1);
    } else {
      EXPECT_EQ(label, -1);
    }
  }
}

TEST(Clustering, TinyEpsGivesPclPartition) {
  std::mt19937_64 rng(31);
  Cloud cloud = randomScene(rng, 2000, 10.0, 0.0);
  // Duplicates and points 1e-30 m apart: eps^2 = 1e-50 is 0 in float, so even these stay apart.
  cloud.push_back({1e-30F, 0.0F, 0.0F, 0.0F});
  cloud.push_back({2e-30F, 0.0F, 0.0F, 0.0F});
  cloud.push_back(cloud.front());
  const Cloud tiny{{1e-30F, 0.0F, 0.0F, 0.0F}, {1e-30F, 0.0F, 0.0F, 0.0F}, {2e-30F, 0.0F, 0.0F, 0.0F}};
  ClusteringParams params;
  params.eps_m = 1e-25;
  params.min_points = 1;
  for (const Cloud& c : {cloud, tiny}) {
    expectPclPartition(c, params, std::to_string(c.size()) + " points");
    EXPECT_EQ(euclideanClusters(c, params).cluster_count, static_cast<std::int32_t>(c.size()));
  }
}

// Every coordinate near 1e30, where floats are 7.6e22 apart: only duplicates are closer than
// eps (other differences square to infinity); and a scene shifted by 1e30 along x only.
TEST(Clustering, HugeCoordinatesGivePclPartition) {
  std::mt19937_64 rng(32);
  const Cloud scene = randomScene(rng, 2000, 10.0, 0.0);
  Cloud huge;
  Cloud shifted;
  for (const auto& p : scene) {
    auto far = [](float c) { return static_cast<float>(1e30 + 1e23 * static_cast<double>(c)); };
    huge.push_back({far(p.x), far(p.y), far(p.z), 0.0F});
    shifted.push_back({1e30F, p.y, p.z, 0.0F});
  }
  for (const double eps : {1e-3, 0.35, 100.0}) {  // the admitted range of eps is [1e-3, 100] m
    ClusteringParams params;
    params.eps_m = eps;
    params.min_points = 2;
    expectPclPartition(huge, params, "all huge, eps " + std::to_string(eps));
    expectPclPartition(shifted, params, "x huge, eps " + std::to_string(eps));
  }
}

TEST(Clustering, DuplicatesAndSinglePointsAndEmpty) {
  ClusteringParams params;
  params.min_points = 2;
  EXPECT_EQ(euclideanClusters(Cloud{}, params).cluster_count, 0);
  const Cloud single{{1.0F, 2.0F, 3.0F, 0.0F}};
  EXPECT_EQ(euclideanClusters(single, params).labels, std::vector<std::int32_t>{-1});
  const Cloud dup{{1.0F, 2.0F, 3.0F, 0.0F}, {1.0F, 2.0F, 3.0F, 0.0F}, {9.0F, 2.0F, 3.0F, 0.0F}};
  EXPECT_EQ(euclideanClusters(dup, params).labels, (std::vector<std::int32_t>{0, 0, -1}));
}

TEST(Clustering, ClustersLargerThanMaxAreNoiseLikePcl) {
  Cloud cloud;
  for (int i = 0; i < 30; ++i) cloud.push_back({0.1F * static_cast<float>(i), 0.0F, 0.0F, 0.0F});
  for (int i = 0; i < 5; ++i) cloud.push_back({100.0F + 0.1F * static_cast<float>(i), 0.0F, 0.0F, 0.0F});
  ClusteringParams params;
  params.min_points = 3;
  params.max_points = 20;
  const Clustering ours = euclideanClusters(cloud, params);
  EXPECT_EQ(ours.cluster_count, 1);
  EXPECT_EQ(ours.labels[0], -1);
  EXPECT_EQ(ours.labels[30], 0);
  EXPECT_EQ(ours.labels, pclEuclideanClusters(cloud, params, false).labels);
}

TEST(Clustering, EqualsPclOnRandomClouds) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const Cloud cloud = randomScene(rng, 3000, 8.0, trial % 2 == 0 ? 0.0 : -500.0);
    ClusteringParams params;
    params.eps_m = 0.2 + 0.05 * trial;
    params.min_points = 1 + static_cast<std::size_t>(trial % 10);
    const Clustering pcl = pclEuclideanClusters(cloud, params, false);
    EXPECT_EQ(euclideanClusters(cloud, params).labels, pcl.labels) << "trial " << trial;
    EXPECT_EQ(pclEuclideanClusters(cloud, params, true).labels, pcl.labels) << "trial " << trial;
  }
}

TEST(Clustering, EqualsPclOnEveryBundledKittiScan) {
  for (const auto& path : test_support::bundledKittiScans()) {
    const auto scan = readCloud(path);
    ASSERT_TRUE(scan.ok()) << scan.error().message;
    ClusteringParams params;  // eps 0.35 m, 10 points: the paper's setting
    const Clustering pcl = pclEuclideanClusters(scan->points, params, false);
    const Clustering ours = euclideanClusters(scan->points, params);
    EXPECT_GT(ours.cluster_count, 50) << path;
    EXPECT_EQ(ours.cluster_count, pcl.cluster_count) << path;
    EXPECT_EQ(ours.labels, pcl.labels) << path;
    params.threads = 4;
    EXPECT_EQ(euclideanClusters(scan->points, params).labels, pcl.labels) << path << ", 4 threads";
  }
}

TEST(Clustering, EqualsPclOnGroundRemovedScanWithOtherEps) {
  const auto scan = readCloud(test_support::bundledKittiScans().front());
  ASSERT_TRUE(scan.ok());
  const auto ground = removeGround(scan->points, GroundParams{});
  ASSERT_TRUE(ground.ok()) << ground.error().message;
  for (const double eps : {0.2, 0.5, 0.8}) {
    ClusteringParams params;
    params.eps_m = eps;
    params.min_points = 5;
    EXPECT_EQ(euclideanClusters(ground->non_ground, params).labels,
              pclEuclideanClusters(ground->non_ground, params, false).labels)
        << "eps " << eps;
  }
}

TEST(Clustering, CanonicalLabelsFollowFirstPoint) {
  const std::vector<std::int32_t> raw{7, -3, 2, 7, 2, 9};
  const Clustering c = canonicalize(raw);
  EXPECT_EQ(c.labels, (std::vector<std::int32_t>{0, -1, 1, 0, 1, 2}));
  EXPECT_EQ(c.cluster_count, 3);
}

// Oracle DBSCAN: O(n^2) neighbourhoods, same expansion order.
Clustering bruteForceDbscan(std::span<const Point> points, const DbscanParams& params) {
  const auto eps2 = static_cast<float>(params.eps_m * params.eps_m);
  const std::size_t n = points.size();
  std::vector<std::vector<std::size_t>> nb(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j) {
      const float dx = points[i].x - points[j].x;
      const float dy = points[i].y - points[j].y;
      const float dz = points[i].z - points[j].z;
      if (dx * dx + dy * dy + dz * dz < eps2) nb[i].push_back(j);
    }
  }
  std::vector<std::int32_t> labels(n, -2);
  std::int32_t next = 0;
  for (std::size_t s = 0; s < n; ++s) {
    if (nb[s].size() < params.min_neighbours || labels[s] != -2) continue;
    const auto id = next++;
    labels[s] = id;
    std::vector<std::size_t> queue{s};
    for (std::size_t q = 0; q < queue.size(); ++q) {
      // Border assignment depends on expansion order; the oracle checks core points only.
      for (const auto j : nb[queue[q]]) {
        if (labels[j] != -2) continue;
        labels[j] = id;
        if (nb[j].size() >= params.min_neighbours) queue.push_back(j);
      }
    }
  }
  for (auto& l : labels) l = l == -2 ? -1 : l;
  return canonicalize(labels);
}

TEST(Dbscan, CorePointsMatchBruteForceOracle) {
  std::mt19937_64 rng(99);
  for (int trial = 0; trial < 30; ++trial) {
    const Cloud cloud = randomScene(rng, 400, 4.0, 0.0);
    DbscanParams params;
    params.eps_m = 0.15 + 0.02 * trial;
    params.min_neighbours = 3 + static_cast<std::size_t>(trial % 5);
    const Clustering expected = bruteForceDbscan(cloud, params);
    const Clustering actual = dbscan(cloud, params);
    ASSERT_EQ(actual.cluster_count, expected.cluster_count) << "trial " << trial;
    // Core points (and noise) are order-independent; compare the partition restricted to them.
    std::vector<std::int32_t> a;
    std::vector<std::int32_t> e;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      std::size_t count = 0;
      for (const auto& q : cloud) {
        const float dx = cloud[i].x - q.x;
        const float dy = cloud[i].y - q.y;
        const float dz = cloud[i].z - q.z;
        count += dx * dx + dy * dy + dz * dz < static_cast<float>(params.eps_m * params.eps_m);
      }
      if (count >= params.min_neighbours || expected.labels[i] < 0) {
        a.push_back(actual.labels[i]);
        e.push_back(expected.labels[i]);
      }
    }
    ASSERT_EQ(canonicalize(a).labels, canonicalize(e).labels) << "trial " << trial;
  }
}

TEST(Dbscan, SmallClustersBecomeNoise) {
  Cloud cloud;
  for (int i = 0; i < 6; ++i) cloud.push_back({0.01F * static_cast<float>(i), 0.0F, 0.0F, 0.0F});
  for (int i = 0; i < 20; ++i) cloud.push_back({5.0F + 0.01F * static_cast<float>(i), 0.0F, 0.0F, 0.0F});
  DbscanParams params{0.05, 3, 10};
  const Clustering c = dbscan(cloud, params);
  EXPECT_EQ(c.cluster_count, 1);
  EXPECT_EQ(c.labels[0], -1);
  EXPECT_EQ(c.labels[6], 0);
}

TEST(ClusterSummaries, MatchDirectSumsPerCluster) {
  std::mt19937_64 rng(3);
  const Cloud cloud = randomScene(rng, 2000, 6.0, 250.0);
  const Clustering c = euclideanClusters(cloud, ClusteringParams{});
  const auto summaries = summarizeClusters(cloud, c);
  ASSERT_EQ(summaries.size(), static_cast<std::size_t>(c.cluster_count));
  for (std::int32_t k = 0; k < c.cluster_count; ++k) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    std::size_t n = 0;
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      if (c.labels[i] != k) continue;
      mean += Eigen::Vector3d(cloud[i].x, cloud[i].y, cloud[i].z);
      ++n;
    }
    mean /= static_cast<double>(n);
    EXPECT_EQ(summaries[static_cast<std::size_t>(k)].count(), n);
    EXPECT_LT((summaries[static_cast<std::size_t>(k)].mean() - mean).norm(), 1e-9);
  }
}

}  // namespace
}  // namespace fogmap
