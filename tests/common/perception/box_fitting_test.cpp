#include "common/perception/box_fitting.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/base/angles.hpp"

namespace fogmap {
namespace {

// What a LiDAR at `sensor` sees of a box's sides: points every `spacing` m along the footprint's
// edges that face the sensor (an edge faces it when the sensor is on its outer side), at heights
// 0.2 .. height, with Gaussian noise of `noise` m on x and y.
Cloud visibleSides(const OrientedBox& box, const Eigen::Vector3d& sensor, double spacing, double noise, std::mt19937& rng) {
  std::normal_distribution<double> jitter(0.0, noise);
  const double c = std::cos(box.yaw), s = std::sin(box.yaw);
  const Eigen::Vector2d e1(c, s), e2(-s, c);
  const Eigen::Vector2d centre = box.centre.head<2>();
  const Eigen::Vector2d d = sensor.head<2>() - centre;
  Cloud cloud;
  auto side = [&](const Eigen::Vector2d& middle, const Eigen::Vector2d& along, double half) {
    for (double t = -half; t <= half; t += spacing) {
      for (double z = 0.2; z <= box.height; z += 0.3) {
        const Eigen::Vector2d p = middle + t * along;
        cloud.push_back({static_cast<float>(p.x() + jitter(rng)), static_cast<float>(p.y() + jitter(rng)),
                         static_cast<float>(box.centre.z() - 0.5 * box.height + z), 0.0F});
      }
    }
  };
  const double hl = 0.5 * box.length, hw = 0.5 * box.width;
  if (d.dot(e1) > hl) side(centre + hl * e1, e2, hw);
  if (d.dot(e1) < -hl) side(centre - hl * e1, e2, hw);
  if (d.dot(e2) > hw) side(centre + hw * e2, e1, hl);
  if (d.dot(e2) < -hw) side(centre - hw * e2, e1, hl);
  return cloud;
}

// The brute force of the specification: the best score over [0, 90) degrees in steps of `step`.
double bruteForceBestScore(const Cloud& points, double step_deg, double d0) {
  double best = 0.0;
  for (double t = 0.0; t < 90.0; t += step_deg) best = std::max(best, closenessScore(points, t * kDegToRad, d0));
  return best;
}

TEST(BoxFitting, AVehicleSeenOnTwoSidesGivesItsYawSizeCentreAndNearestCorner) {
  std::mt19937 rng(7);
  const Eigen::Vector3d sensor(0.0, 0.0, 1.8);
  int k = 0;
  for (const double yaw_deg : {-89.5, -60.0, -30.0, -1.0, 0.0, 12.0, 45.0, 77.0, 89.0}) {
    SCOPED_TRACE("yaw " + std::to_string(yaw_deg));
    OrientedBox truth;
    truth.length = 4.5;
    truth.width = 1.8;
    truth.height = 1.5;
    truth.yaw = yaw_deg * kDegToRad;
    // The sensor 8 m beyond one end and 5 m beyond one side, a different corner each time.
    const double u = (k % 2 == 0 ? 8.0 : -8.0), v = (k / 2 % 2 == 0 ? 5.0 : -5.0);
    ++k;
    const double c = std::cos(truth.yaw), s = std::sin(truth.yaw);
    truth.centre = Eigen::Vector3d(-(c * u - s * v), -(s * u + c * v), -0.9);
    const Cloud points = visibleSides(truth, sensor, 0.05, 0.01, rng);
    const auto box = fitOrientedBox(points, sensor);
    ASSERT_TRUE(box.ok()) << box.error().message;
    EXPECT_LT(axisAngleBetween(box->yaw, truth.yaw), 1.0 * kDegToRad) << box->yaw / kDegToRad;
    EXPECT_GE(box->yaw, -std::numbers::pi / 2);
    EXPECT_LT(box->yaw, std::numbers::pi / 2);
    EXPECT_NEAR(box->length, truth.length, 0.1);
    EXPECT_NEAR(box->width, truth.width, 0.1);
    EXPECT_NEAR(box->height, truth.height - 0.2, 0.31);  // the sides' points start 0.2 m up, every 0.3 m
    EXPECT_LT((box->centre.head<2>() - truth.centre.head<2>()).norm(), 0.1);
    // The corner the sensor sees, on both boxes (their yaws may differ by 180 degrees).
    EXPECT_LT((box->anchorPoint().head<2>() - [&] {
                OrientedBox t = truth;
                t.anchor = t.anchorFor(sensor);
                return Eigen::Vector2d(t.anchorPoint().head<2>());
              }()).norm(), 0.1);
    EXPECT_NE(box->anchor, BoxAnchor::kNone);
  }
}

TEST(BoxFitting, OnLShapesTheSearchFindsTheBruteForceBestScore) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> yaw(-std::numbers::pi / 2, std::numbers::pi / 2), length(1.0, 12.0), ratio(0.2, 1.0), where(-30.0, 30.0);
  const double d0 = BoxFitParams{}.min_distance_m;
  for (int trial = 0; trial < 40; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    OrientedBox truth;
    truth.centre = Eigen::Vector3d(where(rng), where(rng), 0.0);
    truth.length = length(rng);
    truth.width = truth.length * ratio(rng);
    truth.height = 1.0;
    truth.yaw = yaw(rng);
    const Cloud points = visibleSides(truth, Eigen::Vector3d::Zero(), 0.1, 0.02, rng);
    if (points.size() < 10) continue;
    const auto box = fitOrientedBox(points, std::nullopt);
    ASSERT_TRUE(box.ok()) << box.error().message;
    // The search's grid is the fine step's grid (a coarse step is 12 fine steps): it finds the best
    // yaw of that grid (float against double: within 1 %).
    const double found = closenessScore(points, box->yaw, d0);
    const double best = bruteForceBestScore(points, BoxFitParams{}.fine_step_deg, d0);
    EXPECT_GE(found, 0.99 * best) << "yaw " << box->yaw / kDegToRad << " truth " << truth.yaw / kDegToRad;
    // The footprint's rectangle, whichever of its sides the fit calls the length.
    const double turn = axisAngleBetween(box->yaw, truth.yaw);
    EXPECT_LT(std::min(turn, std::numbers::pi / 2 - turn), 1.0 * kDegToRad) << box->yaw / kDegToRad << " truth " << truth.yaw / kDegToRad;
  }
}

TEST(BoxFitting, AStraightFaceTakesTheMiddleOfTheYawsThatTie) {
  // A 1 m face along 30 degrees, no noise: every yaw within asin(d0 / 1 m) = 0.57 degrees of it
  // keeps all points within d0 of an edge and scores the same; the middle of that run is 30.
  Cloud face;
  const double c = std::cos(30.0 * kDegToRad), s = std::sin(30.0 * kDegToRad);
  for (int k = 0; k <= 20; ++k) face.push_back({static_cast<float>(8.0 + 0.05 * k * c), static_cast<float>(2.0 + 0.05 * k * s), 0.0F, 0.0F});
  const auto box = fitOrientedBox(face, std::nullopt);
  ASSERT_TRUE(box.ok()) << box.error().message;
  EXPECT_LT(axisAngleBetween(box->yaw, 30.0 * kDegToRad), 0.13 * kDegToRad) << box->yaw / kDegToRad;
  EXPECT_NEAR(box->length, 1.0, 1e-5);
}

TEST(BoxFitting, EveryPointLiesInTheBoxWhateverTheCluster) {
  std::mt19937 rng(3);
  std::normal_distribution<double> spread(0.0, 2.0);
  for (int trial = 0; trial < 20; ++trial) {
    Cloud points;
    const int n = 1 + trial * 37;
    for (int i = 0; i < n; ++i) {
      points.push_back({static_cast<float>(50.0 + spread(rng)), static_cast<float>(-20.0 + 0.3 * spread(rng)),
                        static_cast<float>(spread(rng)), 0.0F});
    }
    points.push_back({std::nanf(""), 0.0F, 0.0F, 0.0F});  // ignored
    const auto box = fitOrientedBox(points, Eigen::Vector3d::Zero());
    ASSERT_TRUE(box.ok()) << box.error().message;
    EXPECT_GE(box->length, box->width);
    const double c = std::cos(box->yaw), s = std::sin(box->yaw);
    for (const Point& p : points) {
      if (!isFinitePoint(p)) continue;
      const double dx = p.x - box->centre.x(), dy = p.y - box->centre.y();
      EXPECT_LE(std::abs(c * dx + s * dy), 0.5 * box->length + 1e-4);
      EXPECT_LE(std::abs(-s * dx + c * dy), 0.5 * box->width + 1e-4);
      EXPECT_LE(std::abs(p.z - box->centre.z()), 0.5 * box->height + 1e-4);
    }
  }
}

TEST(BoxFitting, AnchorsFollowWhereTheSensorIs) {
  OrientedBox box;
  box.centre = Eigen::Vector3d(10.0, 0.0, 0.0);
  box.length = 4.0;
  box.width = 2.0;
  box.yaw = 0.0;  // length along +x
  EXPECT_EQ(box.anchorFor({20.0, 0.0, 0.0}), BoxAnchor::kFrontFace);
  EXPECT_EQ(box.anchorFor({0.0, 0.5, 0.0}), BoxAnchor::kRearFace);
  EXPECT_EQ(box.anchorFor({10.0, 9.0, 0.0}), BoxAnchor::kLeftFace);
  EXPECT_EQ(box.anchorFor({11.0, -9.0, 0.0}), BoxAnchor::kRightFace);
  EXPECT_EQ(box.anchorFor({0.0, 5.0, 0.0}), BoxAnchor::kRearLeft);
  EXPECT_EQ(box.anchorFor({0.0, -5.0, 0.0}), BoxAnchor::kRearRight);
  EXPECT_EQ(box.anchorFor({15.0, 5.0, 0.0}), BoxAnchor::kFrontLeft);
  EXPECT_EQ(box.anchorFor({15.0, -5.0, 0.0}), BoxAnchor::kFrontRight);
  EXPECT_EQ(box.anchorFor({10.5, 0.5, 0.0}), BoxAnchor::kNone);
  box.anchor = BoxAnchor::kRearRight;
  EXPECT_TRUE(box.anchorPoint().isApprox(Eigen::Vector3d(8.0, -1.0, 0.0)));
  box.anchor = BoxAnchor::kLeftFace;
  EXPECT_TRUE(box.anchorPoint().isApprox(Eigen::Vector3d(10.0, 1.0, 0.0)));
  box.yaw = std::numbers::pi / 2;  // length along +y: the front face is at +y
  box.anchor = BoxAnchor::kFrontFace;
  EXPECT_LT((box.anchorPoint() - Eigen::Vector3d(10.0, 2.0, 0.0)).norm(), 1e-12);
  EXPECT_EQ(boxAnchorName(BoxAnchor::kFrontLeft), "front_left");
}

TEST(BoxFitting, APriorGrowsTheUnseenSideAwayFromTheSensor) {
  const Eigen::Vector3d sensor(0.0, 0.0, 0.0);
  // A car 20 m ahead seen from behind: its rear, 1.8 m wide across y, 0.2 m deep.
  OrientedBox rear;
  rear.centre = Eigen::Vector3d(20.1, 0.0, -1.0);
  rear.length = 1.8;
  rear.width = 0.2;
  rear.yaw = std::numbers::pi / 2;  // the fit's long edge runs along y
  const OrientedBox car = grownToPrior(rear, sensor, BoxPrior{});
  EXPECT_NEAR(car.length, 4.4, 1e-12);
  EXPECT_NEAR(car.width, 1.8, 1e-12);
  EXPECT_LT(axisAngleBetween(car.yaw, 0.0), 1e-12);  // the length runs away from the sensor
  EXPECT_NEAR(car.centre.x(), 20.0 + 2.2, 1e-9);     // the rear face stays at x = 20
  EXPECT_NEAR(car.centre.y(), 0.0, 1e-9);
  EXPECT_EQ(car.anchor, BoxAnchor::kRearFace);
  // Seen on a corner, 3 m of its 4.4 m side and all of its width: only the length grows, away.
  OrientedBox corner;
  corner.centre = Eigen::Vector3d(10.0 + 1.5, 5.0 + 0.9, 0.0);
  corner.length = 3.0;
  corner.width = 1.8;
  corner.yaw = 0.0;
  const OrientedBox grown = grownToPrior(corner, sensor, BoxPrior{});
  EXPECT_NEAR(grown.length, 4.4, 1e-12);
  EXPECT_NEAR(grown.centre.x(), 10.0 + 2.2, 1e-9);
  EXPECT_NEAR(grown.centre.y(), 5.0 + 0.9, 1e-9);
  EXPECT_EQ(grown.anchor, BoxAnchor::kRearRight);
  // A box larger than the prior stays as it is.
  OrientedBox bus = corner;
  bus.length = 11.0;
  bus.width = 2.5;
  const OrientedBox same = grownToPrior(bus, sensor, BoxPrior{});
  EXPECT_EQ(same.length, 11.0);
  EXPECT_EQ(same.width, 2.5);
  EXPECT_TRUE(same.centre.isApprox(bus.centre));
}

TEST(BoxFitting, GrownFromItsAnchorAViewKeepsTheFaceItsSensorSaw) {
  // The rear 1.2 m of a car along x, its rear face (x = 20) seen: the car runs on to x = 24.4.
  OrientedBox rear;
  rear.centre = Eigen::Vector3d(20.6, 3.0, 0.7);
  rear.length = 1.8;  // across: the car's width
  rear.width = 1.2;
  rear.yaw = foldedYaw(std::numbers::pi / 2);  // the fit's long edge runs along y
  rear.anchor = rear.anchorFor(Eigen::Vector3d(0.0, 3.0, 1.7));
  ASSERT_NE(rear.anchor, BoxAnchor::kNone);
  const OrientedBox car = grownFromAnchor(rear, *vehiclePrior(ObjectClass::kCar));
  EXPECT_NEAR(car.length, 4.4, 1e-9);
  EXPECT_NEAR(car.width, 1.8, 1e-9);
  EXPECT_LT(axisAngleBetween(car.yaw, 0.0), 1e-9);
  EXPECT_NEAR(car.centre.x(), 20.0 + 2.2, 1e-6);  // the seen face stays at x = 20
  EXPECT_NEAR(car.centre.y(), 3.0, 1e-6);
  // The same as knowing the sensor.
  const OrientedBox known = grownToPrior(rear, Eigen::Vector3d(0.0, 3.0, 1.7), *vehiclePrior(ObjectClass::kCar));
  EXPECT_LT((known.centre - car.centre).norm(), 1e-6);
  // Without an anchor (several sensors' views) a short axis grows on both sides alike.
  OrientedBox middle = rear;
  middle.anchor = BoxAnchor::kNone;
  const OrientedBox both = grownFromAnchor(middle, *vehiclePrior(ObjectClass::kCar));
  EXPECT_NEAR(both.centre.x(), 20.6, 1e-9);
  EXPECT_NEAR(both.length, 4.4, 1e-9);
  // Trucks and buses have their own size; people and poles none.
  EXPECT_NEAR(vehiclePrior(ObjectClass::kTruckOrBus)->length_m, 8.0, 1e-12);
  EXPECT_FALSE(vehiclePrior(ObjectClass::kPerson).has_value());
  EXPECT_FALSE(vehiclePrior(ObjectClass::kPole).has_value());
}

TEST(BoxFitting, YawsFoldOntoHalfATurn) {
  EXPECT_DOUBLE_EQ(foldedYaw(0.25), 0.25);
  EXPECT_NEAR(foldedYaw(std::numbers::pi + 0.25), 0.25, 1e-12);
  EXPECT_NEAR(foldedYaw(-std::numbers::pi + 0.25), 0.25, 1e-12);
  EXPECT_NEAR(foldedYaw(std::numbers::pi / 2), -std::numbers::pi / 2, 1e-12);
  EXPECT_NEAR(foldedYaw(-std::numbers::pi / 2), -std::numbers::pi / 2, 1e-12);
  EXPECT_NEAR(axisAngleBetween(80 * kDegToRad, -85 * kDegToRad), 15 * kDegToRad, 1e-12);
  EXPECT_NEAR(axisAngleBetween(10 * kDegToRad, 190 * kDegToRad), 0.0, 1e-12);
  EXPECT_NEAR(axisAngleBetween(0.0, std::numbers::pi / 2), std::numbers::pi / 2, 1e-12);
}

TEST(BoxFitting, RefusesNoFinitePointAndBadParametersNamingTheField) {
  const Cloud none = {{std::nanf(""), 1.0F, 1.0F, 0.0F}};
  const auto empty = fitOrientedBox(none, std::nullopt);
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.error().message.find("finite point"), std::string::npos) << empty.error().message;
  const Cloud one = {{1.0F, 2.0F, 3.0F, 0.0F}};
  const auto point = fitOrientedBox(one, std::nullopt);
  ASSERT_TRUE(point.ok());
  EXPECT_EQ(point->length, 0.0);
  EXPECT_TRUE(point->centre.isApprox(Eigen::Vector3d(1.0, 2.0, 3.0)));
  for (const auto& [params, field] : std::vector<std::pair<BoxFitParams, std::string>>{
           {{0.0, 0.25, 0.01}, "coarse_step_deg"},
           {{91.0, 0.25, 0.01}, "coarse_step_deg"},
           {{3.0, 4.0, 0.01}, "fine_step_deg"},
           {{3.0, std::nan(""), 0.01}, "fine_step_deg"},
           {{3.0, 0.25, 0.0}, "min_distance_m"}}) {
    const auto refused = fitOrientedBox(one, std::nullopt, params);
    ASSERT_FALSE(refused.ok()) << field;
    EXPECT_NE(refused.error().message.find(field), std::string::npos) << refused.error().message;
  }
}

}  // namespace
}  // namespace fogmap
