#include "common/perception/madc.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "common/geometry/ellipsoid.hpp"
#include "common/perception/clustering.hpp"

namespace fogmap {
namespace {

// Boxes of points 3 m apart (each one cluster at eps 0.35 m), a few lone points between them
// (noise below min_points), shuffled so that clusters interleave in the cloud.
Cloud boxesAndNoise(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> unit(0.0F, 1.0F);
  Cloud cloud;
  for (int b = 0; b < 6; ++b) {
    const float x0 = 3.0F * static_cast<float>(b);
    const float length = 0.5F + 2.0F * unit(rng);
    for (int i = 0; i < 400; ++i) {
      cloud.push_back({x0 + length * unit(rng), 0.8F * unit(rng), 1.5F * unit(rng), 0.0F});
    }
    cloud.push_back({x0 + 2.9F, 5.0F, 0.0F, 0.0F});
  }
  std::shuffle(cloud.begin(), cloud.end(), rng);
  return cloud;
}

TEST(ClusterEllipsoids, EachClusterFromItsOwnPointsAndNoiseLeftOut) {
  const Cloud cloud = boxesAndNoise(3);
  const Clustering clustering = euclideanClusters(cloud, ClusteringParams{0.35, 10});
  ASSERT_EQ(clustering.cluster_count, 6);
  for (const EllipsoidParams params : {EllipsoidParams{1.5, 0.175, 2.5}, EllipsoidParams{1.5, 0.175}}) {
    const std::vector<Ellipsoid> ellipsoids = clusterEllipsoids(cloud, clustering, 7, 99, params);
    ASSERT_EQ(ellipsoids.size(), 6U);
    for (std::int32_t k = 0; k < clustering.cluster_count; ++k) {
      // The oracle: the cluster's points alone, gathered by label.
      ClusterSummary summary;
      for (std::size_t i = 0; i < cloud.size(); ++i) {
        if (clustering.labels[i] == k) summary.add(cloud[i]);
      }
      ClusterReach reach(summary);
      for (std::size_t i = 0; i < cloud.size(); ++i) {
        if (clustering.labels[i] == k) reach.add(cloud[i]);
      }
      const Ellipsoid expected = params.reaches() ? reach.ellipsoid({7, 99, static_cast<std::uint32_t>(k)}, params)
                                                  : ellipsoidFromSummary(summary, {7, 99, static_cast<std::uint32_t>(k)}, params);
      const Ellipsoid& e = ellipsoids[static_cast<std::size_t>(k)];
      EXPECT_EQ(e.id, expected.id);
      EXPECT_EQ(e.point_count, 400U);
      EXPECT_LT((e.center - expected.center).norm(), 1e-9);
      EXPECT_LT((e.shape - expected.shape).norm(), 1e-9 * expected.shape.norm());
    }
  }
}

TEST(ClusterEllipsoids, TheLocalMapTakesTheTopologysAlphaMax) {
  const Cloud cloud = boxesAndNoise(5);
  MadcParams params;
  params.alpha_max = 2.5;
  const auto reaching = genLocalMap(cloud, 3, 4, params);
  params.alpha_max = 0.0;
  const auto paper = genLocalMap(cloud, 3, 4, params);
  ASSERT_TRUE(reaching && paper);
  ASSERT_EQ(reaching->map.objects.size(), 6U);
  ASSERT_EQ(paper->map.objects.size(), 6U);
  EXPECT_EQ(reaching->clustering.labels, paper->clustering.labels);
  const auto reference = clusterEllipsoids(cloud, reaching->clustering, 3, 4, EllipsoidParams{1.5, 0.175, 2.5});
  for (std::size_t k = 0; k < 6; ++k) {
    EXPECT_EQ(reaching->map.objects[k].ellipsoids.front(), reference[k]);
    // A uniform box's ends lie beyond 1.5 sigma: the reaching ellipsoid is the larger one.
    EXPECT_GT(reaching->map.objects[k].ellipsoids.front().shape.trace(), paper->map.objects[k].ellipsoids.front().shape.trace());
  }
}

}  // namespace
}  // namespace fogmap
