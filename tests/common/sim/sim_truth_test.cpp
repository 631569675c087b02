// The truth of processed points: nearest simulated return, brute force as the oracle.
#include <gtest/gtest.h>

#include <limits>
#include <random>

#include "common/perception/preprocess.hpp"
#include "common/sim/scene.hpp"
#include "common/sim/truth.hpp"

namespace fogmap::sim {
namespace {

std::vector<std::int64_t> bruteForce(const Cloud& points, const Cloud& returns, const std::vector<std::uint32_t>& truth,
                                     double reach) {
  std::vector<std::int64_t> out;
  for (const Point& p : points) {
    double best = std::numeric_limits<double>::infinity();
    std::size_t nearest = returns.size();
    for (std::size_t r = 0; r < returns.size(); ++r) {
      const double dx = static_cast<double>(returns[r].x) - p.x;
      const double dy = static_cast<double>(returns[r].y) - p.y;
      const double dz = static_cast<double>(returns[r].z) - p.z;
      const double d2 = dx * dx + dy * dy + dz * dz;
      if (d2 < best) {
        best = d2;
        nearest = r;
      }
    }
    out.push_back(nearest < returns.size() && best <= reach * reach && truth[nearest] != kGroundId
                      ? static_cast<std::int64_t>(truth[nearest])
                      : -1);
  }
  return out;
}

TEST(SimTruth, EveryPointTakesTheTruthOfTheNearestReturnWithinReach) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> coordinate(-3.0F, 3.0F);
  std::uniform_int_distribution<std::uint32_t> object(0, 5);  // 0: ground
  Cloud returns;
  std::vector<std::uint32_t> truth;
  for (int i = 0; i < 2000; ++i) {
    returns.push_back({coordinate(rng), coordinate(rng), coordinate(rng), 0.0F});
    truth.push_back(object(rng));
  }
  Cloud points;
  for (int i = 0; i < 500; ++i) points.push_back({coordinate(rng), coordinate(rng), coordinate(rng), 0.0F});
  for (const double reach : {0.05, 0.2, 1.0}) {
    EXPECT_EQ(truthOfPoints(points, returns, truth, reach), bruteForce(points, returns, truth, reach)) << reach;
  }
}

TEST(SimTruth, VoxelCentroidsKeepTheirObjectsTruth) {
  // Two objects 2 m apart, sampled densely: the centroids of a 0.2 m voxel grid land among their
  // own object's returns.
  Cloud returns;
  std::vector<std::uint32_t> truth;
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) {
      returns.push_back({0.05F * static_cast<float>(i), 0.05F * static_cast<float>(j), 0.0F, 0.0F});
      truth.push_back(1);
      returns.push_back({3.0F + 0.05F * static_cast<float>(i), 0.05F * static_cast<float>(j), 0.0F, 0.0F});
      truth.push_back(2);
    }
  }
  PreprocessConfig config;
  config.voxel_leaf_m = 0.2;
  const auto centroids = preprocess(returns, config);
  ASSERT_TRUE(centroids.ok());
  const auto labels = truthOfPoints(*centroids, returns, truth, 0.2);
  ASSERT_EQ(labels.size(), centroids->size());
  for (std::size_t i = 0; i < labels.size(); ++i) EXPECT_EQ(labels[i], (*centroids)[i].x < 1.5F ? 1 : 2) << i;
}

TEST(SimTruth, GroundAndFarPointsHaveNoObject) {
  const Cloud returns = {{0, 0, 0, 0}, {1, 0, 0, 0}};
  const std::vector<std::uint32_t> truth = {kGroundId, 4};
  const Cloud points = {{0.01F, 0, 0, 0}, {1.01F, 0, 0, 0}, {5, 5, 5, 0}};
  EXPECT_EQ(truthOfPoints(points, returns, truth, 0.1), (std::vector<std::int64_t>{-1, 4, -1}));
  EXPECT_EQ(truthOfPoints(points, returns, std::vector<std::uint32_t>{1}, 0.1), (std::vector<std::int64_t>{-1, -1, -1}))
      << "a truth vector of the wrong length labels nothing";
}

}  // namespace
}  // namespace fogmap::sim
