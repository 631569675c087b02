// Object outlines on the ground (common/sim/footprint) against analytic answers: a turned box, a
// cylinder's circle, a composite's hull, a moving object where it is at a time.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/sim/footprint.hpp"
#include "common/sim/generators.hpp"

namespace fogmap::sim {
namespace {

SceneObject objectWith(std::vector<Part> parts, Eigen::Vector2d xy = Eigen::Vector2d::Zero(), double yaw_deg = 0.0) {
  SceneObject o;
  o.id = 1;
  o.parts = std::move(parts);
  o.xy = xy;
  o.yaw_deg = yaw_deg;
  return o;
}

Part box(Eigen::Vector3d size, Eigen::Vector3d at = Eigen::Vector3d::Zero(), double yaw_deg = 0.0) {
  return {Shape::kBox, at, size, yaw_deg};
}

Part cylinder(double radius, Eigen::Vector3d at = Eigen::Vector3d::Zero()) {
  return {Shape::kCylinder, at, {2 * radius, 2 * radius, 1.0}, 0.0};
}

// True when `polygon` holds exactly the points of `expected` (any order), each within 1e-9.
::testing::AssertionResult sameVertices(const std::vector<Eigen::Vector2d>& polygon, const std::vector<Eigen::Vector2d>& expected) {
  if (polygon.size() != expected.size()) {
    return ::testing::AssertionFailure() << polygon.size() << " vertices, expected " << expected.size();
  }
  for (const auto& e : expected) {
    const bool found = std::any_of(polygon.begin(), polygon.end(), [&](const Eigen::Vector2d& p) { return (p - e).norm() < 1e-9; });
    if (!found) return ::testing::AssertionFailure() << "no vertex at (" << e.x() << ", " << e.y() << ")";
  }
  return ::testing::AssertionSuccess();
}

double signedArea(const std::vector<Eigen::Vector2d>& polygon) {
  double twice = 0.0;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const auto& a = polygon[i];
    const auto& b = polygon[(i + 1) % polygon.size()];
    twice += a.x() * b.y() - b.x() * a.y();
  }
  return twice / 2.0;
}

TEST(SimFootprint, ABoxTurnedNinetyDegreesSwapsItsSides) {
  // 2 m along the object's x, 1 m across, at (3, 4), turned 90 degrees: 1 m along x, 2 m along y.
  const auto outline = footprint(objectWith({box({2, 1, 1})}, {3, 4}, 90.0), 0.0);
  EXPECT_TRUE(sameVertices(outline, {{2.5, 3}, {3.5, 3}, {3.5, 5}, {2.5, 5}}));
  EXPECT_NEAR(signedArea(outline), 2.0, 1e-9) << "counter-clockwise, 2 square metres";
  // The part's own yaw adds to the object's: 45 + 45 is the same rectangle.
  const auto halves = footprint(objectWith({box({2, 1, 1}, Eigen::Vector3d::Zero(), 45.0)}, {3, 4}, 45.0), 0.0);
  EXPECT_TRUE(sameVertices(halves, {{2.5, 3}, {3.5, 3}, {3.5, 5}, {2.5, 5}}));
  // Turned 30 degrees counter-clockwise (from +x towards +y): each corner rotates about the centre.
  const Eigen::Rotation2Dd turn(M_PI / 6.0);
  const Eigen::Vector2d c(3, 4);
  EXPECT_TRUE(sameVertices(footprint(objectWith({box({2, 1, 1})}, c, 30.0), 0.0),
                           {c + turn * Eigen::Vector2d(1, 0.5), c + turn * Eigen::Vector2d(-1, 0.5),
                            c + turn * Eigen::Vector2d(-1, -0.5), c + turn * Eigen::Vector2d(1, -0.5)}));
}

TEST(SimFootprint, ACylinderIsASixteenGonOnItsCircle) {
  const auto outline = footprint(objectWith({cylinder(0.4)}, {-2, 1}), 0.0);
  ASSERT_EQ(outline.size(), static_cast<std::size_t>(kFootprintCylinderSides));
  for (const auto& p : outline) EXPECT_NEAR((p - Eigen::Vector2d(-2, 1)).norm(), 0.4, 1e-12);
  // A regular 16-gon inscribed in a circle of radius r: area 8 r^2 sin(2 pi / 16).
  EXPECT_NEAR(signedArea(outline), 8 * 0.16 * std::sin(2 * M_PI / 16), 1e-12);
}

TEST(SimFootprint, PartsOffsetInTheObjectFrameTurnWithItAndMergeIntoOneHull) {
  // Two 1 x 1 boxes 2 m apart along the object's x, the object turned 90 degrees at (10, 0): one
  // 1 x 3 hull along y; the gap between the boxes is inside the hull.
  const SceneObject pair = objectWith({box({1, 1, 1}, {-1, 0, 0}), box({1, 1, 1}, {1, 0, 0})}, {10, 0}, 90.0);
  EXPECT_TRUE(sameVertices(footprint(pair, 0.0), {{9.5, -1.5}, {10.5, -1.5}, {10.5, 1.5}, {9.5, 1.5}}));
  // A part 2 m ahead of an object heading +y (turned 90 degrees) is 2 m along +y, not -y.
  EXPECT_TRUE(sameVertices(footprint(objectWith({box({1, 1, 1}, {2, 0, 0})}, {0, 0}, 90.0), 0.0),
                           {{-0.5, 1.5}, {0.5, 1.5}, {0.5, 2.5}, {-0.5, 2.5}}));
  // A box with a cylinder sticking out of its front (x = 1 + 0.5): the hull reaches the circle.
  const auto mast = footprint(objectWith({box({2, 2, 1}), cylinder(0.5, {1.5, 0, 0})}), 0.0);
  double max_x = -1e9;
  for (const auto& p : mast) max_x = std::max(max_x, p.x());
  EXPECT_NEAR(max_x, 2.0, 1e-12);
  EXPECT_TRUE(std::any_of(mast.begin(), mast.end(), [](const Eigen::Vector2d& p) { return (p - Eigen::Vector2d(-1, -1)).norm() < 1e-12; }));
  // A generated forklift (factory scene) is a composite: one convex hull, counter-clockwise.
  const Scene factory = factoryScene(1);
  const auto forklift = std::find_if(factory.objects.begin(), factory.objects.end(), [](const SceneObject& o) { return o.label == "forklift"; });
  ASSERT_NE(forklift, factory.objects.end());
  ASSERT_EQ(forklift->parts.size(), 2U) << "a body and a mast";
  const auto hull = footprint(*forklift, 0.0);
  ASSERT_GT(hull.size(), 4U) << "the mast sticks out of the body: more than a rectangle";
  EXPECT_GT(signedArea(hull), 0.0);
  for (std::size_t i = 0; i < hull.size(); ++i) {
    const auto& a = hull[i];
    const auto& b = hull[(i + 1) % hull.size()];
    const auto& c = hull[(i + 2) % hull.size()];
    EXPECT_GT((b - a).x() * (c - b).y() - (b - a).y() * (c - b).x(), 0.0) << "a left turn at every vertex";
  }
}

TEST(SimFootprint, AMovingObjectsOutlineIsWhereItIsAtTheTime) {
  // 2 m/s along +y from (1, 0): at t = 2 s at (1, 4), heading along +y, so the 2 x 1 box lies along y.
  SceneObject moving = objectWith({box({2, 1, 1})}, {1, 0});
  moving.motion.velocity_mps = {0, 2};
  EXPECT_TRUE(sameVertices(footprint(moving, 2.0), {{0.5, 3}, {1.5, 3}, {1.5, 5}, {0.5, 5}}));
  // Along waypoints at 1 m/s: (0,0) -> (4,0) -> (4,4); at t = 6 s it is at (4, 2) heading +y.
  SceneObject walker = objectWith({cylinder(0.25)});
  walker.motion.waypoints = {{0, 0}, {4, 0}, {4, 4}};
  walker.motion.speed_mps = 1.0;
  for (const auto& p : footprint(walker, 6.0)) EXPECT_NEAR((p - Eigen::Vector2d(4, 2)).norm(), 0.25, 1e-12);
}

TEST(SimFootprint, HullsDropInnerAndCollinearPointsAndKeepDegenerateInput) {
  EXPECT_TRUE(footprint(objectWith({}), 0.0).empty());
  const auto square = convexHull({{0, 0}, {1, 0}, {2, 0}, {2, 2}, {0, 2}, {1, 1}, {0, 1}, {2, 2}});
  ASSERT_EQ(square.size(), 4U);
  EXPECT_EQ(square[0], Eigen::Vector2d(0, 0)) << "starts at the lowest x, then lowest y";
  EXPECT_EQ(square[1], Eigen::Vector2d(2, 0)) << "counter-clockwise";
  EXPECT_EQ(convexHull({{1, 1}, {1, 1}, {0, 0}}).size(), 2U);
}

// footprintGap against analytic gaps: squares side by side, a diamond's vertex facing a side, two
// outlines overlapping, and a point.
TEST(SimFootprint, GapIsTheDistanceBetweenFacingSidesAndNegativeWhenOverlapping) {
  const std::vector<Eigen::Vector2d> unit = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  const auto moved = [](std::vector<Eigen::Vector2d> v, const Eigen::Vector2d& by) {
    for (auto& p : v) p += by;
    return v;
  };
  EXPECT_NEAR(footprintGap(unit, moved(unit, {1.5, 0.0})), 0.5, 1e-12);
  EXPECT_NEAR(footprintGap(moved(unit, {0.0, -3.0}), unit), 2.0, 1e-12);
  EXPECT_NEAR(footprintGap(unit, moved(unit, {0.5, 0.25})), -0.5, 1e-12);
  const std::vector<Eigen::Vector2d> diamond = {{2.0, 0.5}, {2.5, 0.0}, {3.0, 0.5}, {2.5, 1.0}};
  EXPECT_NEAR(footprintGap(unit, diamond), 1.0, 1e-12);  // its left vertex 1 m from the right side
  const std::vector<Eigen::Vector2d> point = {{0.5, 4.0}};
  EXPECT_NEAR(footprintGap(unit, point), 3.0, 1e-12);
  EXPECT_EQ(footprintGap(unit, {}), std::numeric_limits<double>::infinity());
}

}  // namespace
}  // namespace fogmap::sim
