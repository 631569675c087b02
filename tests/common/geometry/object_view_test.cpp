// Oriented boxes and classes on ellipsoids: a global object's box and class from its views (against
// analytic answers, and the same whatever order maps are merged in), and the compact view codec
// (round trips within its stated bounds, sizes, refusals).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "common/geometry/compact_ellipsoid.hpp"
#include "common/geometry/compact_view.hpp"
#include "common/geometry/map.hpp"
#include "common/geometry/object_shape.hpp"

namespace fogmap {
namespace {

OrientedBox boxAt(double x, double y, double length, double width, double yaw, double z = 0.8, double height = 1.6) {
  OrientedBox b;
  b.centre = {x, y, z};
  b.length = length;
  b.width = width;
  b.height = height;
  b.yaw = yaw;
  return b;
}

Ellipsoid view(std::uint32_t node, std::uint32_t index, std::uint64_t points, std::optional<OrientedBox> box,
               std::optional<ObjectLabel> label = std::nullopt) {
  Ellipsoid e;
  e.id = {node, 1, index};
  e.center = box ? box->centre : Eigen::Vector3d(0.0, 0.0, 1.0);
  e.shape = Eigen::Matrix3d::Identity();
  e.point_count = points;
  e.box = box;
  e.label = label;
  return e;
}

// The one object mapFromGroups makes of `ellipsoids`, all in one group.
MapObject mappedObjectOf(std::vector<Ellipsoid> ellipsoids) {
  std::vector<std::size_t> group(ellipsoids.size(), 0);
  return mapFromGroups(ellipsoids, group).objects.at(0);
}

// ---- a global object's box ----------------------------------------------------------------------

TEST(ObjectBox, OneViewIsItsOwnBoxAnchorIncluded) {
  OrientedBox b = boxAt(10, 5, 4.4, 1.8, 0.5);
  b.anchor = BoxAnchor::kRearLeft;
  const auto box = objectBox(mappedObjectOf({view(1, 0, 50, b), view(2, 0, 80, std::nullopt)}));
  ASSERT_TRUE(box);
  EXPECT_EQ(*box, b);
  EXPECT_FALSE(objectBox(mappedObjectOf({view(1, 0, 50, std::nullopt)})).has_value());
}

TEST(ObjectBox, TheRearAndFrontHalvesOfACarSeenByTwoSensorsGiveTheWholeCar) {
  // A car 4.4 x 1.8 m at (10, 5) turned 30 degrees; one sensor sees its rear half, the other its front.
  const double yaw = std::numbers::pi / 6.0;
  const Eigen::Vector2d along(std::cos(yaw), std::sin(yaw));
  const Eigen::Vector2d rear = Eigen::Vector2d(10, 5) - 1.1 * along;
  const Eigen::Vector2d front = Eigen::Vector2d(10, 5) + 1.1 * along;
  OrientedBox rear_box = boxAt(rear.x(), rear.y(), 2.2, 1.8, yaw, 0.7, 1.4);
  rear_box.anchor = BoxAnchor::kRearFace;
  OrientedBox front_box = boxAt(front.x(), front.y(), 2.2, 1.8, yaw + 0.01, 0.8, 1.6);  // the better-seen view
  front_box.anchor = BoxAnchor::kFrontFace;
  const auto box = objectBox(mappedObjectOf({view(1, 3, 40, rear_box), view(2, 7, 90, front_box)}));
  ASSERT_TRUE(box);
  EXPECT_DOUBLE_EQ(box->yaw, yaw + 0.01);  // from the view with the most points
  EXPECT_NEAR(box->centre.x(), 10.0, 0.03);
  EXPECT_NEAR(box->centre.y(), 5.0, 0.03);
  EXPECT_NEAR(box->centre.z(), 0.8, 1e-12);  // from 0 to 1.6
  EXPECT_NEAR(box->height, 1.6, 1e-12);
  EXPECT_NEAR(box->length, 4.4, 0.03);
  EXPECT_NEAR(box->width, 1.8, 0.05);
  EXPECT_EQ(box->anchor, BoxAnchor::kNone);  // two sensors, two faces
}

TEST(ObjectBox, ViewsSideBySideTurnTheAxisWhereTheExtentAcrossIsTheLarger) {
  // Two 2 x 1.5 m boxes along x, side by side in y: together 2 m along x and 3 m across.
  const auto box = objectBox(mappedObjectOf({view(1, 0, 60, boxAt(0, 0.75, 2.0, 1.5, 0.0)), view(2, 0, 50, boxAt(0, -0.75, 2.0, 1.5, 0.0))}));
  ASSERT_TRUE(box);
  EXPECT_NEAR(box->length, 3.0, 1e-12);
  EXPECT_NEAR(box->width, 2.0, 1e-12);
  EXPECT_NEAR(box->yaw, -std::numbers::pi / 2.0, 1e-12);  // folded into [-pi/2, pi/2)
  EXPECT_NEAR(box->centre.head<2>().norm(), 0.0, 1e-12);
}

TEST(ObjectBox, EqualPointCountsTakeTheAxisOfTheSmallestId) {
  const auto box = objectBox(mappedObjectOf({view(2, 0, 50, boxAt(0, 0, 2.0, 1.0, 0.3)), view(1, 4, 50, boxAt(0, 0, 2.0, 1.0, -0.2))}));
  ASSERT_TRUE(box);
  EXPECT_DOUBLE_EQ(box->yaw, -0.2);  // node 1 sorts first
}

TEST(ObjectBox, FootprintsOverlapByTheirSeparatingAxes) {
  const OrientedBox a = boxAt(0, 0, 4.0, 2.0, 0.0);
  EXPECT_TRUE(footprintsOverlap(a, boxAt(3.9, 0, 4.0, 2.0, 0.0)));
  EXPECT_FALSE(footprintsOverlap(a, boxAt(4.1, 0, 4.0, 2.0, 0.0)));
  // A 1 m square turned 45 degrees off a's corner (2, 1): its axis-aligned bounds overlap a's, but
  // its own diagonal axis separates them at (2.4, 1.4); at (2.3, 1.3) they overlap.
  EXPECT_FALSE(footprintsOverlap(a, boxAt(2.4, 1.4, 1.0, 1.0, std::numbers::pi / 4)));
  EXPECT_TRUE(footprintsOverlap(a, boxAt(2.3, 1.3, 1.0, 1.0, std::numbers::pi / 4)));
  EXPECT_TRUE(footprintsOverlap(a, boxAt(0, 0, 0.5, 0.5, 0.3)));  // inside
}

// ---- a global object's class --------------------------------------------------------------------

TEST(ObjectLabel, ViewsVoteWithConfidenceTimesPoints) {
  const auto label = objectLabel(mappedObjectOf({view(1, 0, 100, std::nullopt, ObjectLabel{ObjectClass::kCar, 0.9}),
                                           view(2, 0, 50, std::nullopt, ObjectLabel{ObjectClass::kPerson, 0.8}),
                                           view(3, 0, 500, std::nullopt)}));  // unlabelled: no say
  ASSERT_TRUE(label);
  EXPECT_EQ(label->object_class, ObjectClass::kCar);  // 90 against 40
  EXPECT_NEAR(label->confidence, 90.0 / 150.0, 1e-12);
  EXPECT_FALSE(objectLabel(mappedObjectOf({view(1, 0, 100, std::nullopt)})).has_value());
  // A tie goes to the smaller class number.
  const auto tie = objectLabel(mappedObjectOf({view(1, 0, 10, std::nullopt, ObjectLabel{ObjectClass::kCyclist, 0.5}),
                                         view(2, 0, 10, std::nullopt, ObjectLabel{ObjectClass::kPerson, 0.5})}));
  ASSERT_TRUE(tie);
  EXPECT_EQ(tie->object_class, ObjectClass::kPerson);
}

// ---- order-insensitive like MERGE -----------------------------------------------------------------

// Local maps of `nodes` sensors, each seeing every one of `objects` cars (a view each, overlapping
// ellipsoids), with boxes and labels that differ from view to view.
std::vector<Map> viewsOfCars(std::mt19937_64& rng, int nodes, int objects) {
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Map> maps;
  for (int n = 0; n < nodes; ++n) {
    std::vector<Ellipsoid> ellipsoids;
    for (int o = 0; o < objects; ++o) {
      const double yaw = foldedYaw(0.7 * o + 0.1 * jitter(rng));
      OrientedBox b = boxAt(20.0 * o + jitter(rng), jitter(rng), 3.0 + jitter(rng), 1.5 + jitter(rng), yaw);
      b.anchor = static_cast<BoxAnchor>(1 + (n + o) % 8);
      const auto cls = static_cast<ObjectClass>((n * 7 + o) % static_cast<int>(kObjectClassCount));
      Ellipsoid e = view(static_cast<std::uint32_t>(n + 1), static_cast<std::uint32_t>(o),
                         20 + static_cast<std::uint64_t>(unit(rng) * 100.0), b, ObjectLabel{cls, unit(rng)});
      e.shape = Eigen::Matrix3d::Identity() * 4.0;  // 2 m semi-axes: the views of a car overlap
      if ((n + o) % 3 == 2) e.label.reset();
      ellipsoids.push_back(e);
    }
    maps.push_back(localMap(std::move(ellipsoids)));
  }
  return maps;
}

TEST(ObjectView, BoxesAndClassesDoNotDependOnTheOrderOfMerging) {
  std::mt19937_64 rng(19);
  const std::vector<Map> maps = viewsOfCars(rng, 5, 6);
  const Map reference = mergeAll(maps).map;
  ASSERT_EQ(reference.objects.size(), 6U);
  std::vector<std::size_t> order(maps.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  for (int trial = 0; trial < 20; ++trial) {
    std::shuffle(order.begin(), order.end(), rng);
    Map folded = maps[order[0]];
    for (std::size_t k = 1; k < order.size(); ++k) folded = merge(maps[order[k]], folded).map;
    folded = merge(folded, maps[order[1]]).map;  // a map seen twice changes nothing
    ASSERT_EQ(folded, reference);
    for (std::size_t o = 0; o < reference.objects.size(); ++o) {
      EXPECT_EQ(objectBox(folded.objects[o]), objectBox(reference.objects[o]));
      EXPECT_EQ(objectLabel(folded.objects[o]), objectLabel(reference.objects[o]));
    }
  }
  for (const MapObject& object : reference.objects) {
    EXPECT_TRUE(objectBox(object).has_value());
    EXPECT_EQ(object.ellipsoids.size(), 5U);
  }
}

// ---- the compact view codec -------------------------------------------------------------------

TEST(CompactView, EntriesTakeOneTwoFifteenOrSixteenBytes) {
  const OrientedBox b = boxAt(3.2, -1.4, 4.1, 1.7, 0.25);
  const ObjectLabel l{ObjectClass::kCar, 0.75};
  for (const auto& [e, bytes] : {std::pair{view(1, 0, 10, std::nullopt), 1U}, std::pair{view(1, 0, 10, std::nullopt, l), 2U},
                                 std::pair{view(1, 0, 10, b), 15U}, std::pair{view(1, 0, 10, b, l), 16U}}) {
    std::string out;
    ASSERT_TRUE(appendCompactView(e, out));
    EXPECT_EQ(out.size(), bytes);
    Ellipsoid back = e;
    back.box.reset();
    back.label.reset();
    std::size_t at = 0;
    ASSERT_TRUE(readCompactView(out, at, back));
    EXPECT_EQ(at, out.size());
    EXPECT_EQ(back.box.has_value(), e.box.has_value());
    EXPECT_EQ(back.label.has_value(), e.label.has_value());
  }
}

TEST(CompactView, RandomViewsComeBackWithinTheStatedBounds) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> position(-300.0, 300.0);
  std::uniform_real_distribution<double> offset(-40.0, 40.0);
  std::uniform_real_distribution<double> side(0.0, 30.0);
  std::uniform_real_distribution<double> yaw(-std::numbers::pi / 2.0, std::numbers::pi / 2.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const CompactOrigin origin{0, 0, 0};
  for (int trial = 0; trial < 2000; ++trial) {
    Ellipsoid e = view(3, static_cast<std::uint32_t>(trial), 100, std::nullopt);
    e.center = {position(rng), position(rng), 0.1 * position(rng)};
    double length = side(rng), width = side(rng);
    if (width > length) std::swap(length, width);
    OrientedBox b = boxAt(e.center.x() + offset(rng), e.center.y() + offset(rng), length, width,
                          trial == 0 ? -std::numbers::pi / 2.0 : yaw(rng), e.center.z() + 0.1 * offset(rng), side(rng));
    b.anchor = static_cast<BoxAnchor>(trial % 9);
    e.box = b;
    e.label = ObjectLabel{static_cast<ObjectClass>(trial % 6), trial == 1 ? 1.0 : unit(rng)};
    // Through the ellipsoid's record first: the view's centre is measured from the decoded centre.
    std::string record, entry;
    ASSERT_TRUE(appendCompact(e, origin, record));
    ASSERT_TRUE(appendCompactView(e, entry));
    auto decoded = decodeCompact(record, origin, 3, 1);
    ASSERT_TRUE(decoded) << decoded.error().message;
    std::size_t at = 0;
    ASSERT_TRUE(readCompactView(entry, at, *decoded));
    ASSERT_TRUE(decoded->box && decoded->label);
    const OrientedBox& d = *decoded->box;
    EXPECT_LE((d.centre - b.centre).cwiseAbs().maxCoeff(), kCompactViewLengthErrorM + 1e-9);
    EXPECT_NEAR(d.length, b.length, kCompactViewLengthErrorM + 1e-9);
    EXPECT_NEAR(d.width, b.width, kCompactViewLengthErrorM + 1e-9);
    EXPECT_NEAR(d.height, b.height, kCompactViewLengthErrorM + 1e-9);
    EXPECT_LE(axisAngleBetween(d.yaw, b.yaw), kCompactViewYawErrorRad);
    EXPECT_GE(d.yaw, -std::numbers::pi / 2.0);
    EXPECT_LT(d.yaw, std::numbers::pi / 2.0);
    EXPECT_EQ(d.anchor, b.anchor);
    EXPECT_EQ(decoded->label->object_class, e.label->object_class);
    EXPECT_NEAR(decoded->label->confidence, e.label->confidence, kCompactViewConfidenceError);
    // Packed again, the decoded view gives the same bytes.
    std::string again;
    ASSERT_TRUE(appendCompactView(*decoded, again));
    EXPECT_EQ(again, entry);
  }
}

TEST(CompactView, ViewsThatDoNotFitAreNotWritten) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<Ellipsoid> misfits;
  misfits.push_back(view(1, 0, 10, boxAt(nan, 0, 2, 1, 0)));
  misfits.push_back(view(1, 0, 10, boxAt(0, 0, 700, 1, 0)));
  misfits.push_back(view(1, 0, 10, boxAt(0, 0, 2, -0.5, 0)));
  misfits.push_back(view(1, 0, 10, boxAt(0, 0, 2, 1, std::numbers::pi / 2.0)));
  misfits.push_back(view(1, 0, 10, boxAt(0, 0, 2, 1, std::numeric_limits<double>::infinity())));
  misfits.push_back(view(1, 0, 10, std::nullopt, ObjectLabel{ObjectClass::kCar, 1.5}));
  misfits.push_back(view(1, 0, 10, std::nullopt, ObjectLabel{ObjectClass::kCar, nan}));
  Ellipsoid far = view(1, 0, 10, boxAt(400, 0, 2, 1, 0));
  far.center = {0, 0, 0};  // the box 400 m from its ellipsoid
  misfits.push_back(far);
  for (const Ellipsoid& e : misfits) {
    std::string out;
    EXPECT_FALSE(viewFitsCompact(e));
    EXPECT_FALSE(appendCompactView(e, out));
    EXPECT_TRUE(out.empty());
  }
}

TEST(CompactView, MalformedEntriesAreRefusedByName) {
  auto refused = [](const std::string& entries) {
    Ellipsoid e = view(4, 2, 10, std::nullopt);
    std::size_t at = 0;
    const Status s = readCompactView(entries, at, e);
    EXPECT_FALSE(s);
    return s ? std::string() : s.error().message;
  };
  EXPECT_NE(refused(std::string()).find("end before"), std::string::npos);
  EXPECT_NE(refused(std::string(1, static_cast<char>(7U << 5U))).find("class code 7"), std::string::npos);
  EXPECT_NE(refused(std::string(1, static_cast<char>(1U | (9U << 1U)))).find("anchor 9"), std::string::npos);
  EXPECT_NE(refused(std::string(1, static_cast<char>(2U << 1U))).find("without a box"), std::string::npos);
  EXPECT_NE(refused(std::string(5, static_cast<char>(1U))).find("needs 15 bytes, 5 are left"), std::string::npos);
  EXPECT_NE(refused(std::string(1, static_cast<char>(3U << 5U))).find("needs 2 bytes"), std::string::npos);
  EXPECT_NE(refused(std::string()).find("ellipsoid 4/1/2"), std::string::npos);
}

}  // namespace
}  // namespace fogmap
