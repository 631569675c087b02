// The constant-velocity filter against closed forms and a target it must lock onto.
#include <gtest/gtest.h>

#include <random>

#include "common/tracking/kalman.hpp"

namespace fogmap::tracking {
namespace {

TEST(ConstantVelocityFilter, PredictMovesTheStateAndGrowsTheCovarianceAsTheClosedFormSays) {
  ConstantVelocityFilter f({1.0, 2.0}, Eigen::Matrix2d::Identity() * 0.04, 1.0, ConstantVelocityModel{0.5});
  const Eigen::Matrix4d p0 = f.covariance();
  f.predict(0.2);
  EXPECT_TRUE(f.position().isApprox(Eigen::Vector2d(1.0, 2.0))) << "at rest it stays";
  // Per axis: P = [[p + dt^2 v + dt^4/4 q, dt v + dt^3/2 q], [., v + dt^2 q]] with p = 0.04, v = 1, q = 0.25.
  const double dt = 0.2, q = 0.25;
  EXPECT_NEAR(f.covariance()(0, 0), p0(0, 0) + dt * dt * 1.0 + dt * dt * dt * dt / 4 * q, 1e-12);
  EXPECT_NEAR(f.covariance()(0, 2), dt * 1.0 + dt * dt * dt / 2 * q, 1e-12);
  EXPECT_NEAR(f.covariance()(2, 2), 1.0 + dt * dt * q, 1e-12);
  EXPECT_NEAR(f.covariance()(0, 1), 0.0, 1e-15) << "the axes stay independent";
  f.predict(-1.0);
  EXPECT_TRUE(f.position().isApprox(Eigen::Vector2d(1.0, 2.0))) << "a negative step is no step";
}

TEST(ConstantVelocityFilter, AnUpdateWeighsPredictionAndMeasurementByTheirCovariances) {
  // Position variance 1 against a measurement of variance 1: the estimate lands halfway, its
  // variance halves; the Mahalanobis distance is the innovation over sqrt(S) = sqrt(2).
  ConstantVelocityFilter f({0.0, 0.0}, Eigen::Matrix2d::Identity(), 1.0);
  const Eigen::Matrix2d r = Eigen::Matrix2d::Identity();
  EXPECT_NEAR(f.mahalanobis2({2.0, 0.0}, r), 4.0 / 2.0, 1e-12);
  f.update({2.0, 0.0}, r);
  EXPECT_NEAR(f.position().x(), 1.0, 1e-12);
  EXPECT_NEAR(f.position().y(), 0.0, 1e-12);
  EXPECT_NEAR(f.covariance()(0, 0), 0.5, 1e-12);
  EXPECT_TRUE(f.covariance().isApprox(f.covariance().transpose()));
  // A far more precise measurement wins nearly outright.
  ConstantVelocityFilter g({0.0, 0.0}, Eigen::Matrix2d::Identity(), 1.0);
  g.update({2.0, 0.0}, Eigen::Matrix2d::Identity() * 1e-6);
  EXPECT_NEAR(g.position().x(), 2.0, 1e-5);
}

TEST(ConstantVelocityFilter, LocksOntoAConstantVelocityTargetThroughNoisyMeasurements) {
  std::mt19937 rng(9);
  std::normal_distribution<double> noise(0.0, 0.05);
  const Eigen::Vector2d velocity(1.4, -0.6);  // a walking person, m/s
  const double dt = 0.1;
  const Eigen::Matrix2d r = Eigen::Matrix2d::Identity() * 0.05 * 0.05;
  ConstantVelocityFilter f({3.0, 4.0}, r, 2.0, ConstantVelocityModel{0.3});
  Eigen::Vector2d truth(3.0, 4.0);
  for (int k = 1; k <= 100; ++k) {
    truth += velocity * dt;
    f.predict(dt);
    f.update(truth + Eigen::Vector2d(noise(rng), noise(rng)), r);
  }
  EXPECT_LT((f.velocity() - velocity).norm(), 0.15);
  EXPECT_LT((f.position() - truth).norm(), 0.05) << "better than one raw measurement's noise";
  // Its own uncertainty agrees: the truth sits within the 99.7 % gate of the next prediction
  // (chi-square with 2 degrees of freedom).
  constexpr double kGate = 11.8;
  f.predict(dt);
  truth += velocity * dt;
  EXPECT_LT(f.mahalanobis2(truth, r), kGate);
}

}  // namespace
}  // namespace fogmap::tracking
