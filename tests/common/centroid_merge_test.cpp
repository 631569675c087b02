// Merging one instant's displacement centroids: against a hand-computed pooled covariance, and
// against connected components found by breadth-first search on random centroids (fixed seeds).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <queue>
#include <random>
#include <vector>

#include "common/tracking/centroid_merge.hpp"

namespace fogmap::tracking {
namespace {

DisplacementCentroid centroidAt(const Eigen::Vector3d& p, double variance, std::size_t points) {
  return {p, Eigen::Matrix3d::Identity() * variance, points};
}

TEST(MergeCentroids, TwoViewsOfOneObjectAreTheirMeanWithThePooledCovariance) {
  // One person seen from two sides, 0.4 m apart on the ground, 10 and 30 points; a pole 5 m away.
  const std::vector<DisplacementCentroid> centroids{centroidAt({1.0, 0.0, 0.9}, 0.02, 10),
                                                    centroidAt({5.0, 5.0, 1.0}, 0.01, 8),
                                                    centroidAt({1.4, 0.0, 1.1}, 0.04, 30)};
  const auto merged = mergeCentroids(centroids, 1.0);
  ASSERT_EQ(merged.size(), 2U);
  // Each view counts once in the position, whatever its points.
  EXPECT_LT((merged[0].position - Eigen::Vector3d(1.2, 0.0, 1.0)).norm(), 1e-12);
  // Pooled: (10 (0.02 I + d1 d1^T) + 30 (0.04 I + d2 d2^T)) / 40 with d = (-+0.2, 0, -+0.1).
  Eigen::Matrix3d expected = Eigen::Matrix3d::Identity() * ((10 * 0.02 + 30 * 0.04) / 40.0);
  const Eigen::Vector3d d(0.2, 0.0, 0.1);
  expected += d * d.transpose();
  EXPECT_LT((merged[0].covariance - expected).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((merged[1].position - Eigen::Vector3d(5.0, 5.0, 1.0)).norm(), 1e-12);
  EXPECT_LT((merged[1].covariance - Eigen::Matrix3d::Identity() * 0.01).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(MergeCentroids, HeightDoesNotSeparateAndZeroRadiusKeepsEveryCentroid) {
  const std::vector<DisplacementCentroid> centroids{centroidAt({0, 0, 0.2}, 0.01, 5), centroidAt({0.1, 0, 1.8}, 0.01, 5)};
  EXPECT_EQ(mergeCentroids(centroids, 0.5).size(), 1U) << "the gap is measured on the ground";
  const auto kept = mergeCentroids(centroids, 0.0);
  ASSERT_EQ(kept.size(), 2U);
  EXPECT_EQ(kept[0].position, centroids[0].position);
  EXPECT_EQ(kept[1].position, centroids[1].position);
  EXPECT_TRUE(mergeCentroids({}, 1.0).empty());
}

TEST(MergeCentroids, GroupsAreTheConnectedComponentsOfGapsBelowTheRadius) {
  for (const unsigned seed : {1U, 2U, 3U, 4U, 5U}) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> coordinate(0.0, 12.0);
    std::vector<DisplacementCentroid> centroids;
    for (int i = 0; i < 60; ++i) centroids.push_back(centroidAt({coordinate(rng), coordinate(rng), 1.0}, 0.01, 1 + i % 7));
    const double radius = 1.0;
    // Oracle: breadth-first search over the "closer than radius on the ground" graph.
    const std::size_t n = centroids.size();
    std::vector<int> component(n, -1);
    std::vector<Eigen::Vector3d> means;
    for (std::size_t start = 0; start < n; ++start) {
      if (component[start] >= 0) continue;
      const int id = static_cast<int>(means.size());
      std::queue<std::size_t> open;
      open.push(start);
      component[start] = id;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      int members = 0;
      while (!open.empty()) {
        const std::size_t i = open.front();
        open.pop();
        sum += centroids[i].position;
        ++members;
        for (std::size_t j = 0; j < n; ++j) {
          if (component[j] < 0 && (centroids[i].position.head<2>() - centroids[j].position.head<2>()).norm() < radius) {
            component[j] = id;
            open.push(j);
          }
        }
      }
      means.push_back(sum / members);
    }
    const auto merged = mergeCentroids(centroids, radius);
    ASSERT_EQ(merged.size(), means.size()) << "seed " << seed;
    // Components are numbered by their first member, as the observations come.
    for (std::size_t k = 0; k < means.size(); ++k) {
      EXPECT_LT((merged[k].position - means[k]).norm(), 1e-9) << "seed " << seed << ", group " << k;
    }
  }
}

}  // namespace
}  // namespace fogmap::tracking
