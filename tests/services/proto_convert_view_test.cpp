// Boxes and classes on the wire: beside compact records (compact_view.hpp) and on exact ellipsoids,
// round trips within the codec's bounds, what a view costs in bytes, malformed views refused by name,
// and out-of-range values refused at admission as bad_box.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "common/config/admission.hpp"
#include "common/geometry/compact_ellipsoid.hpp"
#include "common/geometry/compact_view.hpp"
#include "services/common/proto_convert.hpp"

namespace fogmap {
namespace {

constexpr std::uint64_t kEpoch = 17'000'000'123ULL;

// `count` clusters of one sensor near (x0, y0): 2 m balls, with a box of a car or person each and
// a class, except every fifth (a fragment: neither).
std::vector<Ellipsoid> clustersWithViews(std::mt19937_64& rng, std::uint32_t node, int count, double x0, double y0) {
  std::uniform_real_distribution<double> across(-60.0, 60.0);
  std::uniform_real_distribution<double> yaw(-std::numbers::pi / 2.0, std::numbers::pi / 2.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Ellipsoid> out;
  for (int k = 0; k < count; ++k) {
    Ellipsoid e;
    e.id = {node, kEpoch, static_cast<std::uint32_t>(k)};
    e.center = {x0 + across(rng), y0 + across(rng), 0.9};
    e.shape = Eigen::Vector3d(0.3, 0.6, 0.9).asDiagonal();  // ascending: an exact record
    e.point_count = 10 + static_cast<std::uint64_t>(unit(rng) * 2000.0);
    if (k % 5 != 4) {
      const bool car = k % 2 == 0;
      OrientedBox box;
      box.centre = e.center + Eigen::Vector3d(0.3 * unit(rng), -0.2 * unit(rng), 0.05);
      box.length = car ? 4.4 : 0.6;
      box.width = car ? 1.8 : 0.5;
      box.height = car ? 1.5 : 1.75;
      box.yaw = yaw(rng);
      box.anchor = static_cast<BoxAnchor>(k % 9);
      e.box = box;
      e.label = ObjectLabel{car ? ObjectClass::kCar : ObjectClass::kPerson, unit(rng)};
    }
    out.push_back(e);
  }
  return out;
}

void expectViewsWithinBounds(const Map& got, const Map& sent) {
  ASSERT_EQ(got.objects.size(), sent.objects.size());
  for (std::size_t o = 0; o < sent.objects.size(); ++o) {
    ASSERT_EQ(got.objects[o].ellipsoids.size(), sent.objects[o].ellipsoids.size());
    for (std::size_t k = 0; k < sent.objects[o].ellipsoids.size(); ++k) {
      const Ellipsoid& a = got.objects[o].ellipsoids[k];
      const Ellipsoid& b = sent.objects[o].ellipsoids[k];
      ASSERT_EQ(a.box.has_value(), b.box.has_value()) << toString(b.id);
      ASSERT_EQ(a.label.has_value(), b.label.has_value()) << toString(b.id);
      if (b.box) {
        EXPECT_LE((a.box->centre - b.box->centre).cwiseAbs().maxCoeff(), kCompactViewLengthErrorM + 1e-6);
        EXPECT_NEAR(a.box->length, b.box->length, kCompactViewLengthErrorM + 1e-6);
        EXPECT_NEAR(a.box->width, b.box->width, kCompactViewLengthErrorM + 1e-6);
        EXPECT_NEAR(a.box->height, b.box->height, kCompactViewLengthErrorM + 1e-6);
        EXPECT_LE(axisAngleBetween(a.box->yaw, b.box->yaw), kCompactViewYawErrorRad + 1e-6);
        EXPECT_EQ(a.box->anchor, b.box->anchor);
      }
      if (b.label) {
        EXPECT_EQ(a.label->object_class, b.label->object_class);
        EXPECT_NEAR(a.label->confidence, b.label->confidence, kCompactViewConfidenceError + 1e-6);
      }
    }
  }
}

TEST(ProtoConvertViews, ALocalMapsBoxesAndClassesTravelBesideItsRecordsWithinTheCodecsBounds) {
  std::mt19937_64 rng(31);
  MapMessage m;
  m.header.node = 7;
  m.header.epoch = kEpoch;
  m.header.contributing_nodes = {7};
  m.map = localMap(clustersWithViews(rng, 7, 100, 40.0, -20.0));
  v1::Upload upload;
  *upload.mutable_map() = toProto(m);
  const v1::Map& wire = upload.map();
  ASSERT_EQ(wire.blocks_size(), 1);
  EXPECT_EQ(wire.objects_size(), 0);
  // 80 views of a box and a class (16 bytes), 20 fragments without (1 byte).
  EXPECT_EQ(wire.blocks(0).views().size(), 80U * 16U + 20U * 1U);
  std::printf("[ views    ] local map, 100 ellipsoids (80 with a box and a class): %.2f bytes an ellipsoid as an Upload\n",
              static_cast<double>(upload.ByteSizeLong()) / 100.0);
  EXPECT_LE(static_cast<double>(upload.ByteSizeLong()) / 100.0, 24.0 + 16.0);

  v1::Map parsed;
  ASSERT_TRUE(parsed.ParseFromString(wire.SerializeAsString()));
  const auto back = fromProto(parsed);
  ASSERT_TRUE(back.ok()) << back.error().message;
  expectViewsWithinBounds(back->map, m.map);
  // Decoded and encoded again: the same bytes (a relay forwards views unchanged).
  EXPECT_TRUE(toProto(*back).SerializeAsString() == wire.SerializeAsString());
}

TEST(ProtoConvertViews, AMapWithoutViewsSendsNoViewBytes) {
  std::mt19937_64 rng(32);
  std::vector<Ellipsoid> ellipsoids = clustersWithViews(rng, 3, 10, 0.0, 0.0);
  for (Ellipsoid& e : ellipsoids) {
    e.box.reset();
    e.label.reset();
  }
  MapMessage m;
  m.header.epoch = kEpoch;
  m.map = localMap(ellipsoids);
  const v1::Map wire = toProto(m);
  ASSERT_EQ(wire.blocks_size(), 1);
  EXPECT_TRUE(wire.blocks(0).views().empty());
}

TEST(ProtoConvertViews, GlobalObjectsOfSeveralSensorsKeepEachViewAndExactEllipsoidsCarryTheirsToo) {
  std::mt19937_64 rng(33);
  std::vector<Ellipsoid> ellipsoids;
  std::vector<std::size_t> group;
  for (std::uint32_t node = 1; node <= 3; ++node) {
    for (const Ellipsoid& e : clustersWithViews(rng, node, 20, 0.0, 0.0)) {
      ellipsoids.push_back(e);
      group.push_back(e.id.index);  // cluster k of every sensor is object k
    }
  }
  GlobalMapMessage g;
  g.header.epoch = kEpoch;
  g.map = mapFromGroups(ellipsoids, group);
  for (const EllipsoidWire wire : {EllipsoidWire::kCompact, EllipsoidWire::kExact}) {
    const auto back = fromProto(toProto(g, wire));
    ASSERT_TRUE(back.ok()) << back.error().message;
    expectViewsWithinBounds(back->map, g.map);
  }
  // A view too large for an entry (a 700 m wall) sends its ellipsoid exactly, box included.
  Map wall = localMap({ellipsoids[0]});
  wall.objects[0].ellipsoids[0].box->length = 700.0;
  g.map = wall;
  const v1::GlobalMap wire = toProto(g);
  EXPECT_EQ(wire.blocks_size(), 0);
  ASSERT_EQ(wire.objects_size(), 1);
  EXPECT_FLOAT_EQ(wire.objects(0).ellipsoids(0).box().length(), 700.0F);
  const auto back = fromProto(wire);
  ASSERT_TRUE(back.ok());
  EXPECT_NEAR(back->map.objects[0].ellipsoids[0].box->length, 700.0, 1e-3);
}

void expectRefused(const Expected<MapMessage>& result, const std::vector<std::string>& fragments) {
  ASSERT_FALSE(result.ok());
  for (const auto& f : fragments) {
    EXPECT_NE(result.error().message.find(f), std::string::npos) << result.error().message << " lacks " << f;
  }
}

TEST(ProtoConvertViews, MalformedViewsAreRefusedNamingTheRecordOrTheField) {
  std::mt19937_64 rng(34);
  MapMessage m;
  m.header.epoch = kEpoch;
  m.map = localMap(clustersWithViews(rng, 7, 6, 0.0, 0.0));
  const v1::Map good = toProto(m);
  ASSERT_TRUE(fromProto(good).ok());

  v1::Map extra = good;
  extra.mutable_blocks(0)->mutable_views()->push_back('\0');
  expectRefused(fromProto(extra), {"blocks[0]", "views has 1 bytes beyond its 6 entries"});

  v1::Map short_views = good;
  short_views.mutable_blocks(0)->mutable_views()->resize(20);  // entry 1 is cut
  expectRefused(fromProto(short_views), {"blocks[0] record 1", "needs 16 bytes"});

  v1::Map bad_class = good;
  (*bad_class.mutable_blocks(0)->mutable_views())[0] = static_cast<char>(7U << 5U);
  expectRefused(fromProto(bad_class), {"blocks[0] record 0", "class code 7"});

  const v1::Map exact = toProto(m, EllipsoidWire::kExact);
  v1::Map no_centre = exact;
  no_centre.mutable_objects(0)->mutable_ellipsoids(0)->mutable_box()->clear_centre();
  expectRefused(fromProto(no_centre), {"object 0 ellipsoid 0", "box centre has 0 values"});
  v1::Map bad_anchor = exact;
  bad_anchor.mutable_objects(0)->mutable_ellipsoids(0)->mutable_box()->set_anchor(9);
  expectRefused(fromProto(bad_anchor), {"box anchor 9"});
  v1::Map bad_label = exact;
  bad_label.mutable_objects(1)->mutable_ellipsoids(0)->mutable_label()->set_object_class(6);
  expectRefused(fromProto(bad_label), {"object 1 ellipsoid 0", "object_class 6"});
}

TEST(ProtoConvertViews, BoxesAndClassesOutOfRangeAreRefusedAtAdmissionAsBadBox) {
  std::mt19937_64 rng(35);
  MapMessage m;
  m.header.epoch = kEpoch;
  m.map = localMap(clustersWithViews(rng, 7, 3, 0.0, 0.0));
  const AdmissionLimits limits;
  EXPECT_FALSE(checkMapBounds(m.map, limits, "map").has_value());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  struct Case {
    std::string what;
    void (*spoil)(Ellipsoid&, double);
    double value;
  };
  const std::vector<Case> cases = {
      {"box centre", [](Ellipsoid& e, double v) { e.box->centre.x() = v; }, nan},
      {"box centre", [](Ellipsoid& e, double v) { e.box->centre.y() = v; }, 1e9},
      {"box length", [](Ellipsoid& e, double v) { e.box->length = v; }, inf},
      {"box width", [](Ellipsoid& e, double v) { e.box->width = v; }, -1.0},
      {"box height", [](Ellipsoid& e, double v) { e.box->height = v; }, nan},
      {"exceeds its length", [](Ellipsoid& e, double v) { e.box->width = v; }, 10.0},
      {"box yaw", [](Ellipsoid& e, double v) { e.box->yaw = v; }, nan},
      {"box yaw", [](Ellipsoid& e, double v) { e.box->yaw = v; }, 2.0},
      {"class confidence", [](Ellipsoid& e, double v) { e.label->confidence = v; }, nan},
      {"class confidence", [](Ellipsoid& e, double v) { e.label->confidence = v; }, 1.5},
  };
  for (const Case& c : cases) {
    // Through the exact wire, as a hostile sender would send them.
    MapMessage spoiled = m;
    c.spoil(spoiled.map.objects[1].ellipsoids[0], c.value);
    const auto decoded = fromProto(toProto(spoiled, EllipsoidWire::kExact));
    ASSERT_TRUE(decoded.ok()) << decoded.error().message;
    const auto refused = checkMapBounds(decoded->map, limits, "map");
    ASSERT_TRUE(refused.has_value()) << c.what;
    EXPECT_EQ(refused->reason, Refusal::kBadBox) << c.what;
    EXPECT_STREQ(refusalName(refused->reason), "bad_box");
    EXPECT_NE(refused->message.find(c.what), std::string::npos) << refused->message;
    EXPECT_NE(refused->message.find("7/" + std::to_string(kEpoch) + "/1"), std::string::npos) << refused->message;
  }
}

}  // namespace
}  // namespace fogmap
