// The CTRV model against the geometry of its arcs (straight lines and circles worked out by hand),
// its Jacobian against central differences, and the filter on a car driving a circle.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include <Eigen/Cholesky>

#include "common/base/angles.hpp"
#include "common/tracking/ctrv.hpp"

namespace fogmap::tracking {
namespace {

CtrvState stateOf(double x, double y, double heading, double speed, double yaw_rate) {
  CtrvState s;
  s << x, y, heading, speed, yaw_rate;
  return s;
}

TEST(Ctrv, WithoutTurningAVehicleMovesAlongItsHeading) {
  const CtrvState s = stateOf(1.0, -2.0, 0.3, 10.0, 0.0);
  const CtrvState p = ctrvPredict(s, 0.5);
  EXPECT_NEAR(p(0), 1.0 + 5.0 * std::cos(0.3), 1e-12);
  EXPECT_NEAR(p(1), -2.0 + 5.0 * std::sin(0.3), 1e-12);
  EXPECT_DOUBLE_EQ(p(2), 0.3);
  EXPECT_DOUBLE_EQ(p(3), 10.0);
}

TEST(Ctrv, ATurningVehicleStaysOnItsCircleAndStepsComposeIntoOneArc) {
  // 5 m/s at 0.5 rad/s: a circle of radius 10 m. Heading 0 at (0, 0): the centre is (0, 10).
  const CtrvState start = stateOf(0.0, 0.0, 0.0, 5.0, 0.5);
  const Eigen::Vector2d centre(0.0, 10.0);
  CtrvState stepped = start;
  for (int k = 0; k < 40; ++k) {
    stepped = ctrvPredict(stepped, 0.1);
    EXPECT_NEAR((stepped.head<2>() - centre).norm(), 10.0, 1e-9) << "step " << k;
  }
  const CtrvState once = ctrvPredict(start, 4.0);
  EXPECT_NEAR((once.head<2>() - stepped.head<2>()).norm(), 0.0, 1e-9);
  // After 4 s it has turned 2 rad: at the centre plus 10 (sin 2, -cos 2), heading 2.
  EXPECT_NEAR(once(0), 10.0 * std::sin(2.0), 1e-9);
  EXPECT_NEAR(once(1), 10.0 - 10.0 * std::cos(2.0), 1e-9);
  EXPECT_NEAR(once(2), 2.0, 1e-12);
}

TEST(Ctrv, TheStraightExpansionMeetsTheArcAtItsThreshold) {
  for (const double w : {kStraightYawRate * (1.0 - 1e-9), kStraightYawRate, -kStraightYawRate}) {
    const CtrvState s = stateOf(3.0, 4.0, 1.1, 40.0, w);
    // The arc's formula written out, whatever side of the threshold w is on.
    const double x = 3.0 + 40.0 / w * (std::sin(1.1 + w) - std::sin(1.1));
    const double y = 4.0 + 40.0 / w * (std::cos(1.1) - std::cos(1.1 + w));
    const CtrvState p = ctrvPredict(s, 1.0);
    EXPECT_NEAR(p(0), x, 1e-5) << "w " << w;
    EXPECT_NEAR(p(1), y, 1e-5) << "w " << w;
  }
}

TEST(Ctrv, TheJacobianIsTheDerivativeOfThePrediction) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> heading(-3.0, 3.0), speed(0.0, 30.0), dt(0.01, 1.0);
  for (const double w : {0.0, 2e-4, -5e-4, 0.05, -0.8, 1.5}) {
    for (int trial = 0; trial < 20; ++trial) {
      const CtrvState s = stateOf(1.0, 2.0, heading(rng), speed(rng), w);
      const double step = dt(rng);
      const auto f = ctrvJacobian(s, step);
      for (int j = 0; j < 5; ++j) {
        constexpr double h = 1e-6;
        CtrvState up = s, down = s;
        up(j) += h;
        down(j) -= h;
        CtrvState diff = ctrvPredict(up, step) - ctrvPredict(down, step);
        diff(2) = wrapToPi(diff(2));
        const CtrvState numeric = diff / (2.0 * h);
        for (int i = 0; i < 5; ++i) {
          // Where the prediction switches formula inside the difference, the two agree to 1e-5 m.
          EXPECT_NEAR(f(i, j), numeric(i), 2e-4 + 1e-6 * std::abs(numeric(i)))
              << "d state " << i << " / d state " << j << ", w " << w << ", dt " << step;
        }
      }
    }
  }
}

TEST(Ctrv, ANegativeSpeedIsTheSameMotionWithTheHeadingTurnedRound) {
  CtrvFilter backwards(Eigen::Vector2d(0.0, 0.0), Eigen::Matrix2d::Identity() * 0.01, 0.2, 0.1, -3.0, 1.0, 0.1);
  EXPECT_NEAR(backwards.speed(), 3.0, 1e-12);
  EXPECT_NEAR(backwards.heading(), wrapToPi(0.2 + std::numbers::pi), 1e-12);
  backwards.predict(2.0);
  EXPECT_NEAR(backwards.position().x(), -6.0 * std::cos(0.2), 1e-9);
  EXPECT_NEAR(backwards.position().y(), -6.0 * std::sin(0.2), 1e-9);
  const Eigen::Vector2d v = backwards.velocity();
  EXPECT_NEAR(v.x(), -3.0 * std::cos(0.2), 1e-9);
  EXPECT_NEAR(v.y(), -3.0 * std::sin(0.2), 1e-9);
}

TEST(Ctrv, AHeadingMeasuredAcrossTheSeamMovesTheHeadingTheShortWay) {
  CtrvFilter f(Eigen::Vector2d::Zero(), Eigen::Matrix2d::Identity(), std::numbers::pi - 0.01, 0.2, 5.0, 1.0, 0.1);
  f.updateHeading(-std::numbers::pi + 0.03, 0.2);  // 0.04 rad further on, across +-pi
  const double moved = wrapToPi(f.heading() - (std::numbers::pi - 0.01));
  EXPECT_GT(moved, 0.0);
  EXPECT_LT(moved, 0.04);
  // Equal sigmas: halfway.
  EXPECT_NEAR(moved, 0.02, 1e-9);
}

TEST(Ctrv, AnAxisIsReadAsTheDirectionNearerTheHeading) {
  CtrvFilter f(Eigen::Vector2d::Zero(), Eigen::Matrix2d::Identity(), 0.1, 0.2, 5.0, 1.0, 0.1);
  f.updateAxis(0.3 + std::numbers::pi, 0.2);  // the box's yaw pointing backwards: the axis at 0.3
  EXPECT_NEAR(f.heading(), 0.2, 1e-9);
  EXPECT_NEAR(f.speed(), 5.0, 1e-9) << "a heading alone does not change the speed";
}

TEST(Ctrv, OnACarDrivingACircleTheFilterFindsItsSpeedAndYawRate) {
  // 8 m/s on a circle of radius 20 m (0.4 rad/s), measured at 10 Hz with 10 cm of noise; the
  // filter starts knowing only the first position and a heading 20 degrees off, at rest.
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.1);
  const CtrvState truth0 = stateOf(0.0, 0.0, 0.0, 8.0, 0.4);
  const Eigen::Matrix2d r = Eigen::Matrix2d::Identity() * 0.01;
  // Tuned for a car that holds its speed and its turn (the truth has no acceleration).
  CtrvFilter f(truth0.head<2>(), r, 20.0 * kDegToRad, 0.5, 0.0, 10.0, 0.5,
               CtrvModel{.acceleration_sigma = 0.3, .yaw_acceleration_sigma = 0.1});
  CtrvState truth = truth0;
  for (int k = 1; k <= 100; ++k) {
    truth = ctrvPredict(truth, 0.1);
    f.predict(0.1);
    f.updatePosition(truth.head<2>() + Eigen::Vector2d(noise(rng), noise(rng)), r);
  }
  EXPECT_NEAR(f.speed(), 8.0, 0.3);
  EXPECT_NEAR(f.yawRate(), 0.4, 0.05);
  EXPECT_LT(std::abs(wrapToPi(f.heading() - truth(2))), 3.0 * kDegToRad);
  EXPECT_LT((f.position() - truth.head<2>()).norm(), 0.15);
  // The covariance stays symmetric and positive definite.
  EXPECT_LT((f.covariance() - f.covariance().transpose()).norm(), 1e-12);
  EXPECT_GT(f.covariance().ldlt().vectorD().minCoeff(), 0.0);
}

TEST(Ctrv, NoMeasurementNoCertainty) {
  CtrvFilter f(Eigen::Vector2d::Zero(), Eigen::Matrix2d::Identity() * 0.01, 0.0, 0.1, 10.0, 0.5, 0.1);
  const double before = f.positionCovariance().trace();
  f.predict(1.0);
  EXPECT_GT(f.positionCovariance().trace(), before);
  f.predict(-1.0);  // as 0
  const CtrvState still = f.state();
  f.predict(0.0);
  EXPECT_EQ(f.state(), still);
}

}  // namespace
}  // namespace fogmap::tracking
