// Merging one instant's displacement centroids: against a hand-computed pooled covariance, and
// against connected components found by breadth-first search on random centroids (fixed seeds).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <queue>
#include <random>
#include <span>
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
    // Odd seeds around the origin: cells of negative coordinates too.
    std::uniform_real_distribution<double> coordinate(seed % 2 == 1 ? -6.0 : 0.0, seed % 2 == 1 ? 6.0 : 12.0);
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

TEST(MergeCentroids, LocatedCentroidsPlaceTheObservationsOfTheGroupsFoundAsSeen) {
  // Seen: two people 1.2 m apart (two groups) and a third seen twice, 0.5 m apart (one group).
  const std::vector<DisplacementCentroid> seen{centroidAt({0.0, 0.0, 1.0}, 0.01, 10), centroidAt({1.2, 0.0, 1.0}, 0.01, 10),
                                               centroidAt({5.0, 0.0, 1.0}, 0.01, 10), centroidAt({5.5, 0.0, 1.0}, 0.03, 30)};
  // Located: the first two moved within 0.2 m of each other, the third's views onto 5.3 and 5.2.
  const std::vector<DisplacementCentroid> located{centroidAt({0.5, 0.0, 1.0}, 0.01, 10), centroidAt({0.7, 0.0, 1.0}, 0.01, 10),
                                                  centroidAt({5.3, 0.0, 1.0}, 0.01, 10), centroidAt({5.2, 0.0, 1.0}, 0.03, 30)};
  const auto merged = mergeCentroids(seen, 1.0, located);
  ASSERT_EQ(merged.size(), 3U) << "grouped as seen";
  EXPECT_LT((merged[0].position - Eigen::Vector3d(0.5, 0.0, 1.0)).norm(), 1e-12);
  EXPECT_LT((merged[1].position - Eigen::Vector3d(0.7, 0.0, 1.0)).norm(), 1e-12);
  EXPECT_LT((merged[2].position - Eigen::Vector3d(5.25, 0.0, 1.0)).norm(), 1e-12) << "placed as located";
  // Pooled over the located views: (10 (0.01 I + d d^T) + 30 (0.03 I + d d^T)) / 40, d = 0.05 m in x.
  Eigen::Matrix3d expected = Eigen::Matrix3d::Identity() * ((10 * 0.01 + 30 * 0.03) / 40.0);
  expected(0, 0) += 0.05 * 0.05;
  EXPECT_LT((merged[2].covariance - expected).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(mergeCentroids(seen, 1.0, std::span<const DisplacementCentroid>(located).first(2)).size(), 3U)
      << "located of another length is ignored";
}

// The points a LiDAR at `sensor` sees of an upright cylinder of radius r at `axis`: its near half,
// evenly spread across the line of sight (a far object: equal azimuth steps are equal lateral
// steps), at heights 0.2 to 1.6 m. Summarised as the displacement detector does.
DisplacementCentroid seenCylinder(const Eigen::Vector2d& sensor, const Eigen::Vector2d& axis, double r) {
  const Eigen::Vector2d along = (axis - sensor).normalized();
  const Eigen::Vector2d across(-along.y(), along.x());
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 201; ++i) {
    const double lateral = -r + 2.0 * r * i / 200.0;
    const Eigen::Vector2d p = axis + lateral * across - std::sqrt(std::max(0.0, r * r - lateral * lateral)) * along;
    for (int k = 0; k < 8; ++k) points.emplace_back(p.x(), p.y(), 0.2 + 0.2 * k);
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const auto& p : points) covariance += (p - mean) * (p - mean).transpose();
  covariance /= static_cast<double>(points.size() - 1);
  return {mean, covariance, points.size()};
}

TEST(VisibleSideCorrected, APersonsCentroidMovesFromItsVisibleSideToItsAxis) {
  const Eigen::Vector2d axis(7.0, -3.0);
  for (const Eigen::Vector2d& sensor : {Eigen::Vector2d(0, 0), Eigen::Vector2d(20, 20), Eigen::Vector2d(7, -25)}) {
    const DisplacementCentroid seen = seenCylinder(sensor, axis, 0.25);
    // Analytic: the mean of the visible half lies pi r / 4 = 0.196 m nearer the sensor.
    EXPECT_NEAR((seen.position.head<2>() - axis).norm(), M_PI / 4.0 * 0.25, 0.005);
    const DisplacementCentroid corrected = visibleSideCorrected(seen, Eigen::Vector3d(sensor.x(), sensor.y(), 1.8), 0.4);
    EXPECT_LT((corrected.position.head<2>() - axis).norm(), 0.01) << "sensor at " << sensor.transpose();
    EXPECT_EQ(corrected.position.z(), seen.position.z());
    EXPECT_EQ(corrected.covariance, seen.covariance);
    EXPECT_EQ(corrected.point_count, seen.point_count);
  }
}

TEST(VisibleSideCorrected, WideClustersZeroRadiusAndACentroidAtTheSensorAreLeftAsTheyAre) {
  const Eigen::Vector3d sensor(0, 0, 1.8);
  // A car's face, 1.8 m wide, 10 m ahead: too wide to be taken for a cylinder.
  const DisplacementCentroid face = seenCylinder({0, 0}, {10, 0}, 0.9);
  EXPECT_EQ(visibleSideCorrected(face, sensor, 0.4).position, face.position);
  const DisplacementCentroid person = seenCylinder({0, 0}, {10, 0}, 0.25);
  EXPECT_EQ(visibleSideCorrected(person, sensor, 0.0).position, person.position) << "0: off";
  EXPECT_EQ(visibleSideCorrected(person, person.position, 0.4).position, person.position) << "no line of sight";
}

}  // namespace
}  // namespace fogmap::tracking
