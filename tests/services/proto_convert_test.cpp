#include "services/common/proto_convert.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <google/protobuf/descriptor.h>
#include <google/protobuf/unknown_field_set.h>

#include "common/base/little_endian.hpp"
#include "common/geometry/compact_ellipsoid.hpp"
#include "common/geometry/map.hpp"
#include "tests/support/geometry_builders.hpp"

namespace fogmap {
namespace {

// Symmetric positive definite, and exactly symmetric as withAura produces them (the wire carries
// the upper triangle only). In double precision: see roundedToFloat.
Eigen::Matrix3d randomShape(std::mt19937_64& rng, double min_axis = 0.1, double max_axis = 3.0) {
  std::uniform_real_distribution<double> axis(min_axis, max_axis);
  const Eigen::Matrix3d r = fogmap::test_support::randomRotation(rng);
  const Eigen::Vector3d semi{axis(rng), axis(rng), axis(rng)};  // braces: drawn in order
  const Eigen::Matrix3d m = r * semi.cwiseAbs2().asDiagonal() * r.transpose();
  return 0.5 * (m + m.transpose());
}

// An ellipsoid that travels exactly carries its centre and shape as float32: a round trip is exact
// for geometry whose values are floats, and rounds every other value to the nearest float once.
enum class Geometry { kFloat, kDouble };

// The ellipsoid with every centre and shape value rounded to the nearest float (element by
// element, so an exactly symmetric shape stays exactly symmetric).
Ellipsoid roundedToFloat(Ellipsoid e) {
  e.center = e.center.cast<float>().cast<double>();
  e.shape = e.shape.cast<float>().cast<double>();
  return e;
}

// How the ellipsoids of a test map travel: each in a compact record, each exactly (a record counts
// at most 65,535 points), or every third exactly.
enum class Wire { kPacked, kExact, kMixed };
constexpr std::uint64_t kMorePointsThanARecordHolds = 100'000;

constexpr std::uint64_t kSampleEpoch = 123456789012ULL;

// Union of the ellipsoids' delimiting boxes: what an object's box must be.
Box unionOfDelimitingBoxes(const std::vector<Ellipsoid>& ellipsoids) {
  Box box;
  for (const auto& e : ellipsoids) box.extend(delimitingBox(e));
  return box;
}

// A map of `objects` objects with 1..3 ellipsoids each, from several nodes, in canonical form.
// Each object's first ellipsoid has frame `epoch` (the frame the wire leaves out in a message of
// that epoch), the others a frame of their own.
Map randomMap(std::mt19937_64& rng, int objects, Geometry geometry = Geometry::kFloat,
              std::uint64_t epoch = kSampleEpoch, Wire wire = Wire::kPacked) {
  std::uniform_real_distribution<double> pos(-50.0, 50.0);
  std::vector<Ellipsoid> ellipsoids;
  std::vector<std::size_t> object_of;
  for (int o = 0; o < objects; ++o) {
    const int n = 1 + o % 3;
    for (int k = 0; k < n; ++k) {
      Ellipsoid e;
      e.id = {static_cast<std::uint32_t>(1 + k), k == 0 ? epoch : 1000 + static_cast<std::uint64_t>(o),
              static_cast<std::uint32_t>(o)};
      // Values with no short decimal form, so a text round trip would show (and, in double
      // geometry, values no float holds: the 1e-9 / 3 is far below a float's resolution).
      e.center = {pos(rng) + 1e-9 / 3.0, pos(rng), pos(rng) / 7.0};
      e.shape = randomShape(rng);
      e.point_count = 5 + static_cast<std::uint64_t>(o * 3 + k);
      if (wire == Wire::kExact || (wire == Wire::kMixed && (o + k) % 3 == 1)) {
        e.point_count += kMorePointsThanARecordHolds;
      }
      ellipsoids.push_back(geometry == Geometry::kFloat ? roundedToFloat(e) : e);
      object_of.push_back(static_cast<std::size_t>(o));
    }
  }
  return mapFromGroups(ellipsoids, object_of);
}

MapHeader sampleHeader() {
  MapHeader h;
  h.node = 7;
  h.epoch = kSampleEpoch;
  h.sensor_time_ns = 1700000000123456789LL;
  h.contributing_nodes = {1, 2, 5};
  h.missing_nodes = {3};
  return h;
}

MapMessage sampleMapMessage(Wire wire) {
  std::mt19937_64 rng(11);
  return {sampleHeader(), randomMap(rng, 9, Geometry::kFloat, kSampleEpoch, wire)};
}

// Nine objects (object o has 1 + o % 3 ellipsoids), every ellipsoid exact on the wire.
v1::Map exactSampleProtoMap() { return toProto(sampleMapMessage(Wire::kExact)); }
// The same objects, every ellipsoid a record: block 0 is node 1's with 9 records (the first
// ellipsoid of every object, object o's has index o), the others one record each (node 2 or 3, a
// frame of their own); every object is listed, with no exact ellipsoid.
// The size of a block's records: 20 bytes where the block numbers them (first_index), else 22.
std::size_t recordBytes(const v1::EllipsoidBlock& block) {
  return compactRecordBytes(block.has_first_index() ? CompactIndex::kImplicit : CompactIndex::kInRecord);
}

// The block with every record holding its index (22 bytes), as a block without first_index has
// them: the same ellipsoids on the wire.
void putIndicesInRecords(v1::EllipsoidBlock& block) {
  if (!block.has_first_index()) return;
  std::string records;
  const std::string& bare = block.records();
  for (std::size_t r = 0; r * kCompactRecordBytesWithoutIndex < bare.size(); ++r) {
    records.append(bare, r * kCompactRecordBytesWithoutIndex, kCompactRecordBytesWithoutIndex);
    putU16(records, static_cast<std::uint16_t>(block.first_index() + r));
  }
  block.set_records(records);
  block.clear_first_index();
}
template <class Message>
Message withIndicesInRecords(Message message) {
  for (auto& block : *message.mutable_blocks()) putIndicesInRecords(block);
  return message;
}

// The sample with every record's index in the record (22 bytes each), so that the tests below can
// forge faults at a record's offsets.
v1::Map packedSampleProtoMap() { return withIndicesInRecords(toProto(sampleMapMessage(Wire::kPacked))); }

// A block's origin as the codec takes it.
CompactOrigin originOf(const v1::EllipsoidBlock& block) {
  return {block.origin_x_cm(), block.origin_y_cm(), block.origin_z_cm()};
}

// The object of each record of a block: its object_step summed.
std::vector<std::int64_t> recordObjects(const v1::EllipsoidBlock& block) {
  std::vector<std::int64_t> objects;
  std::int64_t sum = 0;
  for (const std::int32_t step : block.object_step()) objects.push_back(sum += step);
  return objects;
}

// Names the object of each record, as steps.
void setRecordObjects(v1::EllipsoidBlock& block, const std::vector<std::int64_t>& objects) {
  block.clear_object_step();
  std::int64_t previous = 0;
  for (const std::int64_t o : objects) {
    block.add_object_step(static_cast<std::int32_t>(o - previous));
    previous = o;
  }
}

// Asserts that `result` is an invalid-argument error whose message contains every fragment.
template <class T>
void expectRejected(const Expected<T>& result, std::initializer_list<std::string> fragments) {
  ASSERT_FALSE(result.ok());
  EXPECT_EQ(result.error().code, ErrorCode::kInvalidArgument);
  for (const auto& f : fragments) {
    EXPECT_NE(result.error().message.find(f), std::string::npos)
        << "message '" << result.error().message << "' does not mention '" << f << "'";
  }
}

bool samePoints(const Cloud& a, const Cloud& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    // Bitwise: the wire carries float32 exactly.
    if (std::memcmp(&a[i].x, &b[i].x, sizeof(float)) != 0 || std::memcmp(&a[i].y, &b[i].y, sizeof(float)) != 0 ||
        std::memcmp(&a[i].z, &b[i].z, sizeof(float)) != 0) {
      return false;
    }
  }
  return true;
}

// ---- geometry within the compact codec's bound -----------------------------------------------

// Semi-axes (ascending) and their directions, from the test's own eigen-decomposition.
struct Axes {
  Eigen::Matrix3d rotation;
  Eigen::Vector3d semi;
};

Axes axesOf(const Ellipsoid& e) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(e.shape);
  return {solver.eigenvectors(), solver.eigenvalues().cwiseMax(0.0).cwiseSqrt()};
}

// Sampled points of from's surface pushed outward along its normal by `distance` that lie inside
// `to`. None when to's surface lies within `distance` of from's (to is then inside from's outer
// parallel body, whose boundary the pushed points are). Random directions and the axes' ends.
int pushedPointsInside(const Ellipsoid& from, const Ellipsoid& to, double distance, std::mt19937_64& rng) {
  const Axes axes = axesOf(from);
  const Eigen::LDLT<Eigen::Matrix3d> to_shape(to.shape);
  int inside = 0;
  for (int i = 0; i < 64 + 6; ++i) {
    const Eigen::Vector3d u = i < 6 ? Eigen::Vector3d(Eigen::Vector3d::Unit(i / 2) * (i % 2 == 0 ? 1.0 : -1.0))
                                    : fogmap::test_support::randomUnitVector(rng);
    const Eigen::Vector3d p = from.center + axes.rotation * axes.semi.cwiseProduct(u);
    const Eigen::Vector3d normal = (axes.rotation * u.cwiseQuotient(axes.semi)).normalized();
    const Eigen::Vector3d d = p + distance * normal - to.center;
    // A relative 1e-9 on the Mahalanobis value is well under a micrometre here.
    if (d.dot(to_shape.solve(d)) < 1.0 - 1e-9) ++inside;
  }
  return inside;
}

// Expects `got` to be `sent` as the wire carries it: ids, point counts and grouping into objects
// exactly; an exact ellipsoid rounded to float once; a packed one with its centre within 0.5 cm per
// axis, its semi-axes within 0.5 mm, and each surface within compactSurfaceErrorBound(largest
// semi-axis) of the other; boxes recomputed from the ellipsoids that came back.
void expectWithinCompactBound(const Map& got, const Map& sent) {
  std::mt19937_64 rng(99);
  ASSERT_EQ(got.objects.size(), sent.objects.size());
  for (std::size_t o = 0; o < sent.objects.size(); ++o) {
    const auto& a = sent.objects[o].ellipsoids;
    const auto& b = got.objects[o].ellipsoids;
    ASSERT_EQ(b.size(), a.size()) << "object " << o;
    for (std::size_t k = 0; k < a.size(); ++k) {
      ASSERT_EQ(b[k].id, a[k].id) << "object " << o << " ellipsoid " << k;
      EXPECT_EQ(b[k].point_count, a[k].point_count) << toString(a[k].id);
      if (b[k] == roundedToFloat(a[k])) continue;  // travelled exactly
      EXPECT_LE((b[k].center - a[k].center).cwiseAbs().maxCoeff(), kCompactCentreErrorM + 1e-9) << toString(a[k].id);
      const Axes sent_axes = axesOf(a[k]);
      const Axes got_axes = axesOf(b[k]);
      EXPECT_LE((got_axes.semi - sent_axes.semi).cwiseAbs().maxCoeff(), kCompactSemiAxisErrorM + 1e-9)
          << toString(a[k].id);
      const double bound = compactSurfaceErrorBound(sent_axes.semi.maxCoeff());
      EXPECT_EQ(pushedPointsInside(a[k], b[k], bound, rng), 0) << toString(a[k].id) << " beyond " << bound << " m";
      EXPECT_EQ(pushedPointsInside(b[k], a[k], bound, rng), 0) << toString(a[k].id) << " beyond " << bound << " m";
    }
    EXPECT_EQ(got.objects[o].box, unionOfDelimitingBoxes(b)) << "object " << o;
  }
}

// True when every ellipsoid's semi-axes differ in whole mm (the codec's rotation is then unique).
bool semiAxesDistinctInMm(const Map& map) {
  for (const auto& o : map.objects) {
    for (const auto& e : o.ellipsoids) {
      const Eigen::Vector3d mm = (axesOf(e).semi * 1000.0).array().round();
      if (mm[0] == mm[1] || mm[1] == mm[2]) return false;
    }
  }
  return true;
}

// ---- round trips -----------------------------------------------------------------------------

TEST(ProtoConvert, MapRoundTripKeepsIdsAndObjectsExactlyAndGeometryWithinTheCompactBound) {
  std::mt19937_64 rng(1);
  for (int trial = 0; trial < 50; ++trial) {
    const Wire wire = trial % 3 == 0 ? Wire::kPacked : (trial % 3 == 1 ? Wire::kMixed : Wire::kExact);
    const MapMessage m{sampleHeader(), randomMap(rng, trial, Geometry::kDouble, kSampleEpoch, wire)};
    const auto back = fromProto(toProto(m));
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(back->header, m.header);
    SCOPED_TRACE("trial " + std::to_string(trial));
    expectWithinCompactBound(back->map, m.map);
  }
}

TEST(ProtoConvert, MapRoundTripSurvivesSerialisation) {
  const MapMessage m = sampleMapMessage(Wire::kMixed);
  const v1::Map wire = toProto(m);
  EXPECT_GT(wire.blocks_size(), 0);
  const std::string bytes = wire.SerializeAsString();
  v1::Map parsed;
  ASSERT_TRUE(parsed.ParseFromString(bytes));
  const auto back = fromProto(parsed);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->header, m.header);
  expectWithinCompactBound(back->map, m.map);
  const auto direct = fromProto(wire);
  ASSERT_TRUE(direct.ok()) << direct.error().message;
  EXPECT_EQ(*back, *direct) << "the bytes carry everything the message does";
}

TEST(ProtoConvert, ExactEllipsoidsAreRoundedToFloatOnceThenRoundTripExactly) {
  std::mt19937_64 rng(6);
  const MapMessage m{sampleHeader(), randomMap(rng, 20, Geometry::kDouble, kSampleEpoch, Wire::kExact)};
  EXPECT_EQ(toProto(m).blocks_size(), 0) << "no ellipsoid of this map fits a record";
  const auto once = fromProto(toProto(m));
  ASSERT_TRUE(once.ok()) << once.error().message;
  EXPECT_EQ(once->header, m.header);
  ASSERT_EQ(once->map.objects.size(), m.map.objects.size());
  int rounded = 0;
  for (std::size_t o = 0; o < m.map.objects.size(); ++o) {
    const auto& sent = m.map.objects[o].ellipsoids;
    const auto& got = once->map.objects[o].ellipsoids;
    ASSERT_EQ(got.size(), sent.size()) << "object " << o;
    for (std::size_t k = 0; k < sent.size(); ++k) {
      const Ellipsoid& a = sent[k];
      const Ellipsoid& b = got[k];
      EXPECT_EQ(b.id, a.id);
      EXPECT_EQ(b.point_count, a.point_count);
      // Each value is the nearest float to the original, so within float rounding of it.
      for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(b.center[i], static_cast<double>(static_cast<float>(a.center[i])));
        EXPECT_LE(std::abs(b.center[i] - a.center[i]), 1e-7 * std::abs(a.center[i])) << "centre " << i;
        rounded += b.center[i] != a.center[i] ? 1 : 0;
      }
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
          EXPECT_EQ(b.shape(i, j), static_cast<double>(static_cast<float>(a.shape(i, j))));
          EXPECT_LE(std::abs(b.shape(i, j) - a.shape(i, j)), 1e-7 * std::abs(a.shape(i, j))) << "shape " << i << j;
          rounded += b.shape(i, j) != a.shape(i, j) ? 1 : 0;
        }
      }
      EXPECT_EQ(b.shape, b.shape.transpose()) << "still exactly symmetric";
    }
    EXPECT_EQ(once->map.objects[o].box, unionOfDelimitingBoxes(got)) << "the box of the rounded ellipsoids";
  }
  EXPECT_GT(rounded, 0) << "double geometry should not all be floats, or this test shows nothing";

  // Rounded once, the map is float geometry: the second round trip is exact (also as bytes).
  const auto twice = fromProto(toProto(*once));
  ASSERT_TRUE(twice.ok()) << twice.error().message;
  EXPECT_EQ(*twice, *once);
  v1::Map parsed;
  ASSERT_TRUE(parsed.ParseFromString(toProto(*once).SerializeAsString()));
  const auto parsed_back = fromProto(parsed);
  ASSERT_TRUE(parsed_back.ok()) << parsed_back.error().message;
  EXPECT_EQ(*parsed_back, *once);

  // The same for a global map.
  GlobalMapMessage g;
  g.header = sampleHeader();
  g.map = randomMap(rng, 15, Geometry::kDouble, kSampleEpoch, Wire::kExact);
  const auto g_once = fromProto(toProto(g));
  ASSERT_TRUE(g_once.ok()) << g_once.error().message;
  EXPECT_NE(g_once->map, g.map);
  const auto g_twice = fromProto(toProto(*g_once));
  ASSERT_TRUE(g_twice.ok()) << g_twice.error().message;
  EXPECT_EQ(*g_twice, *g_once);
}

// A decoded map encodes to the bytes it came in when its semi-axes are distinct in mm and its
// rotations are away from ties between quaternion components (random ones are, but for about 2 in
// 100,000): a relay that decodes and re-encodes forwards the same records, and a map decoded twice
// is the map decoded once.
TEST(ProtoConvert, DecodedMapsEncodeToTheBytesTheyCameIn) {
  std::mt19937_64 rng(12);
  int checked = 0;
  for (int trial = 0; trial < 30; ++trial) {
    SCOPED_TRACE("trial " + std::to_string(trial));
    const Wire wire = trial % 3 == 0 ? Wire::kPacked : (trial % 3 == 1 ? Wire::kMixed : Wire::kExact);
    const MapMessage m{sampleHeader(), randomMap(rng, 1 + trial, Geometry::kDouble, kSampleEpoch, wire)};
    if (!semiAxesDistinctInMm(m.map)) continue;  // two semi-axes equal in mm: the rotation is free
    ++checked;
    const std::string bytes = toProto(m).SerializeAsString();
    v1::Map parsed;
    ASSERT_TRUE(parsed.ParseFromString(bytes));
    const auto once = fromProto(parsed);
    ASSERT_TRUE(once.ok()) << once.error().message;
    EXPECT_EQ(toProto(*once).SerializeAsString(), bytes);
    const auto twice = fromProto(toProto(*once));
    ASSERT_TRUE(twice.ok()) << twice.error().message;
    EXPECT_EQ(*twice, *once);

    GlobalMapMessage g;
    g.header = m.header;
    g.map = m.map;
    const std::string global_bytes = toProto(g).SerializeAsString();
    v1::GlobalMap global_parsed;
    ASSERT_TRUE(global_parsed.ParseFromString(global_bytes));
    const auto global_once = fromProto(global_parsed);
    ASSERT_TRUE(global_once.ok()) << global_once.error().message;
    EXPECT_EQ(toProto(*global_once).SerializeAsString(), global_bytes);
  }
  EXPECT_GE(checked, 20) << "most random maps have distinct semi-axes";
}

// Where two semi-axes are equal (spheres, discs) the rotation about the third is free: a decoded
// one re-encodes to other bytes, but a sphere keeps its shape and a disc stays within the bound.
TEST(ProtoConvert, SpheresAndDiscsKeepTheirGeometryWhenEncodedAgain) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> pos(-50.0, 50.0);
  std::vector<Ellipsoid> ellipsoids;
  for (std::uint32_t k = 0; k < 20; ++k) {
    const Eigen::Matrix3d r = fogmap::test_support::randomRotation(rng);
    const double a = 0.2 + 0.1 * k;
    const Eigen::Vector3d semi = k % 2 == 0 ? Eigen::Vector3d(a, a, a) : Eigen::Vector3d(0.05, a, a);
    Ellipsoid e;
    e.id = {4, kSampleEpoch, k};
    e.center = {pos(rng), pos(rng), pos(rng)};
    const Eigen::Matrix3d m = r * semi.cwiseAbs2().asDiagonal() * r.transpose();
    e.shape = 0.5 * (m + m.transpose());
    e.point_count = 40;
    ellipsoids.push_back(e);
  }
  const MapMessage m{sampleHeader(), localMap(ellipsoids)};
  const auto once = fromProto(toProto(m));
  ASSERT_TRUE(once.ok()) << once.error().message;
  expectWithinCompactBound(once->map, m.map);
  const auto twice = fromProto(toProto(*once));
  ASSERT_TRUE(twice.ok()) << twice.error().message;
  expectWithinCompactBound(twice->map, once->map);
  for (std::size_t o = 0; o < m.map.objects.size(); ++o) {
    const Ellipsoid& e = twice->map.objects[o].ellipsoids[0];
    if (e.id.index % 2 == 0) {
      EXPECT_LE((e.shape - once->map.objects[o].ellipsoids[0].shape).cwiseAbs().maxCoeff(), 1e-12)
          << "a sphere is a sphere whatever its rotation";
    }
  }
}

// Where the ellipsoid (node, index) is on the wire: its frame when one is sent, nullopt when it is
// left out; fails the test when there is no such ellipsoid.
template <class Message>
std::optional<std::uint64_t> wireFrame(const Message& message, std::uint32_t node, std::uint32_t index) {
  for (const auto& o : message.objects()) {
    for (const auto& e : o.ellipsoids()) {
      if (e.id().node() == node && e.id().index() == index) {
        return e.id().has_frame() ? std::optional<std::uint64_t>(e.id().frame()) : std::nullopt;
      }
    }
  }
  for (const auto& b : message.blocks()) {
    if (b.node() != node) continue;
    v1::EllipsoidBlock numbered = b;
    putIndicesInRecords(numbered);
    const std::string& records = numbered.records();
    for (std::size_t r = 0; r + kCompactEllipsoidBytes <= records.size(); r += kCompactEllipsoidBytes) {
      if (getU16(records, r + 20) == index) return b.has_frame() ? std::optional<std::uint64_t>(b.frame()) : std::nullopt;
    }
  }
  ADD_FAILURE() << "no ellipsoid " << node << "/" << index << " on the wire";
  return std::nullopt;
}

// Every frame sent explicitly, also where it is the epoch (an encoder that always sends it).
template <class Message>
void sendEveryFrame(Message& message) {
  const std::uint64_t epoch = message.header().epoch();
  for (auto& o : *message.mutable_objects()) {
    for (auto& e : *o.mutable_ellipsoids()) {
      if (!e.id().has_frame()) e.mutable_id()->set_frame(epoch);
    }
  }
  for (auto& b : *message.mutable_blocks()) {
    if (!b.has_frame()) b.set_frame(epoch);
  }
}

Ellipsoid ballAt(const EllipsoidId& id, double x, std::uint64_t point_count) {
  Ellipsoid e;
  e.id = id;
  e.center = {x, 0.5, -1.25};
  e.shape = Eigen::Matrix3d::Identity() * 0.25;
  e.point_count = point_count;
  return e;
}

TEST(ProtoConvert, FrameIsLeftOutWhenItIsTheEpoch) {
  const std::uint64_t epoch = 42;
  // As records (one block per node and frame) and as exact ellipsoids (more points than a record holds).
  for (const std::uint64_t points : {std::uint64_t{3}, kMorePointsThanARecordHolds}) {
    const bool packed = points == 3;
    SCOPED_TRACE(packed ? "records" : "exact ellipsoids");
    MapMessage m;
    m.header.node = 9;
    m.header.epoch = epoch;
    m.map = localMap({ballAt({3, epoch, 0}, 0.0, points), ballAt({3, epoch - 1, 1}, 4.0, points),
                      ballAt({4, 0, 2}, 8.0, points), ballAt({5, epoch + 1, 0}, 12.0, points)});
    const v1::Map wire = toProto(m);
    EXPECT_EQ(wire.blocks_size(), packed ? 4 : 0);
    EXPECT_EQ(wire.objects_size(), packed ? 0 : 4) << "objects of their own are not listed";
    EXPECT_EQ(wireFrame(wire, 3, 0), std::nullopt) << "frame == epoch is left out";
    EXPECT_EQ(wireFrame(wire, 3, 1), epoch - 1);
    EXPECT_EQ(wireFrame(wire, 4, 2), 0U) << "frame 0 is a value, not absence";
    EXPECT_EQ(wireFrame(wire, 5, 0), epoch + 1);

    // Decoded: an absent frame is the epoch, a present one is kept (also through bytes).
    v1::Map parsed;
    ASSERT_TRUE(parsed.ParseFromString(wire.SerializeAsString()));
    EXPECT_EQ(wireFrame(parsed, 3, 0), std::nullopt);
    EXPECT_EQ(wireFrame(parsed, 4, 2), 0U);
    const auto back = fromProto(parsed);
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(back->header, m.header);
    expectWithinCompactBound(back->map, m.map);

    // An absent frame means the epoch of the message it arrives in.
    v1::Map moved = wire;
    moved.mutable_header()->set_epoch(77);
    const auto in_77 = fromProto(moved);
    ASSERT_TRUE(in_77.ok()) << in_77.error().message;
    std::vector<EllipsoidId> ids;
    for (const auto& o : in_77->map.objects) {
      for (const auto& e : o.ellipsoids) ids.push_back(e.id);
    }
    std::sort(ids.begin(), ids.end());
    EXPECT_EQ(ids, (std::vector<EllipsoidId>{{3, 41, 1}, {3, 77, 0}, {4, 0, 2}, {5, 43, 0}}));

    // An explicit frame equal to the epoch decodes the same.
    v1::Map explicit_frame = wire;
    sendEveryFrame(explicit_frame);
    EXPECT_EQ(wireFrame(explicit_frame, 3, 0), epoch);
    const auto explicit_back = fromProto(explicit_frame);
    ASSERT_TRUE(explicit_back.ok()) << explicit_back.error().message;
    EXPECT_EQ(*explicit_back, *back);

    // Global maps follow the same rule.
    GlobalMapMessage g;
    g.header = m.header;
    g.map = m.map;
    v1::GlobalMap global_wire = toProto(g);
    EXPECT_EQ(wireFrame(global_wire, 3, 0), std::nullopt);
    EXPECT_EQ(wireFrame(global_wire, 3, 1), epoch - 1);
    const auto global_back = fromProto(global_wire);
    ASSERT_TRUE(global_back.ok()) << global_back.error().message;
    EXPECT_EQ(global_back->map, back->map);
    sendEveryFrame(global_wire);
    const auto global_explicit = fromProto(global_wire);
    ASSERT_TRUE(global_explicit.ok()) << global_explicit.error().message;
    EXPECT_EQ(global_explicit->map, back->map);
  }
}

TEST(ProtoConvert, WireObjectsCarryNoBoxAndBoxesAreRecomputed) {
  // The box is gone from the schema; its field number is reserved.
  const google::protobuf::Descriptor* object_type = v1::MapObject::descriptor();
  EXPECT_EQ(object_type->field_count(), 1);
  EXPECT_EQ(object_type->FindFieldByName("box"), nullptr);
  EXPECT_EQ(object_type->FindFieldByNumber(2), nullptr);
  EXPECT_TRUE(object_type->IsReservedNumber(2));

  const MapMessage m = sampleMapMessage(Wire::kMixed);
  v1::Map wire = toProto(m);
  const auto expected = fromProto(wire);
  ASSERT_TRUE(expected.ok()) << expected.error().message;
  for (const auto& o : wire.objects()) {
    EXPECT_TRUE(o.GetReflection()->GetUnknownFields(o).empty()) << "nothing but ellipsoids is sent";
  }
  // A box from an old sender (field 2) is skipped as an unknown field, never trusted.
  v1::Box bogus;
  bogus.mutable_min()->set_x(-1e9);
  bogus.mutable_max()->set_x(-1e9 + 1);
  ASSERT_GT(wire.objects_size(), 0);
  v1::MapObject* first = wire.mutable_objects(0);
  first->GetReflection()->MutableUnknownFields(first)->AddLengthDelimited(2, bogus.SerializeAsString());
  v1::Map parsed;
  ASSERT_TRUE(parsed.ParseFromString(wire.SerializeAsString()));

  const auto back = fromProto(parsed);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(*back, *expected);
  ASSERT_FALSE(back->map.objects.empty());
  for (std::size_t o = 0; o < back->map.objects.size(); ++o) {
    const MapObject& object = back->map.objects[o];
    EXPECT_FALSE(object.box.empty());
    EXPECT_EQ(object.box, unionOfDelimitingBoxes(object.ellipsoids)) << "object " << o;
  }
}

TEST(ProtoConvert, MapIsRebuiltInCanonicalForm) {
  const v1::Map wire = toProto(sampleMapMessage(Wire::kMixed));
  const auto expected = fromProto(wire);
  ASSERT_TRUE(expected.ok()) << expected.error().message;
  ASSERT_GT(wire.blocks_size(), 1);
  // Reverse the objects (renumbering the records' objects), the ellipsoids within each object, the
  // blocks and the records within each block.
  v1::Map shuffled = wire;
  // Listed objects and packed ones are reversed among themselves.
  const std::int64_t listed = shuffled.objects_size();
  const std::int64_t packed = shuffled.packed_objects();
  ASSERT_GT(listed, 0);
  ASSERT_GT(packed, 0);
  std::reverse(shuffled.mutable_objects()->begin(), shuffled.mutable_objects()->end());
  for (auto& o : *shuffled.mutable_objects()) {
    std::reverse(o.mutable_ellipsoids()->begin(), o.mutable_ellipsoids()->end());
  }
  std::reverse(shuffled.mutable_blocks()->begin(), shuffled.mutable_blocks()->end());
  for (auto& b : *shuffled.mutable_blocks()) {
    std::vector<std::int64_t> objects = recordObjects(b);
    for (auto& o : objects) o = o < listed ? listed - 1 - o : listed + (packed - 1 - (o - listed));
    std::reverse(objects.begin(), objects.end());
    setRecordObjects(b, objects);
    putIndicesInRecords(b);  // reordered, the records must carry their indices
    std::string records;
    for (std::size_t r = b.records().size(); r >= kCompactEllipsoidBytes; r -= kCompactEllipsoidBytes) {
      records += b.records().substr(r - kCompactEllipsoidBytes, kCompactEllipsoidBytes);
    }
    b.set_records(records);
  }
  // Unsorted node lists come back sorted.
  shuffled.mutable_header()->clear_contributing_nodes();
  for (const std::uint32_t n : {5U, 1U, 2U}) shuffled.mutable_header()->add_contributing_nodes(n);
  const auto back = fromProto(shuffled);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(*back, *expected);
}

TEST(ProtoConvert, PointChunkRoundTripIsExact) {
  PointChunk c;
  c.header = sampleHeader();
  c.chunk = 2;
  c.chunk_count = 4;
  c.first_point = 1000;
  c.total_points = 5000;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<float> pos(-80.0F, 80.0F);
  for (int i = 0; i < 777; ++i) c.points.push_back({pos(rng), pos(rng), pos(rng) / 3.0F, 0.0F});
  c.points.push_back({-0.0F, std::numeric_limits<float>::denorm_min(), std::numeric_limits<float>::max(), 0.0F});

  v1::PointChunk wire = toProto(c);
  EXPECT_EQ(wire.xyz().size(), c.points.size() * 12);
  EXPECT_TRUE(wire.labels().empty());
  auto back = fromProto(wire);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->header, c.header);
  EXPECT_EQ(back->chunk, c.chunk);
  EXPECT_EQ(back->chunk_count, c.chunk_count);
  EXPECT_EQ(back->first_point, c.first_point);
  EXPECT_EQ(back->total_points, c.total_points);
  EXPECT_TRUE(samePoints(back->points, c.points));
  EXPECT_TRUE(back->labels.empty());

  for (std::size_t i = 0; i < c.points.size(); ++i) c.labels.push_back(static_cast<std::int32_t>(i % 5) - 1);
  c.labels.back() = std::numeric_limits<std::int32_t>::min();
  wire = toProto(c);
  EXPECT_EQ(wire.labels().size(), c.points.size() * 4);
  back = fromProto(wire);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->labels, c.labels);
  EXPECT_TRUE(samePoints(back->points, c.points));
}

// The oracle: the uploads themselves, cut by hand into chunks and serialised.
std::size_t serialisedBaselineBytes(const MapHeader& header, std::size_t points, std::size_t per_chunk,
                                    std::uint64_t first_sequence) {
  const std::size_t count = std::max<std::size_t>(1, (points + per_chunk - 1) / per_chunk);
  std::size_t total = 0;
  for (std::size_t c = 0; c < count; ++c) {
    PointChunk chunk;
    chunk.header = header;
    chunk.chunk = static_cast<std::uint32_t>(c);
    chunk.chunk_count = static_cast<std::uint32_t>(count);
    chunk.first_point = static_cast<std::uint32_t>(c * per_chunk);
    chunk.total_points = static_cast<std::uint32_t>(points);
    for (std::size_t i = c * per_chunk; i < std::min(points, (c + 1) * per_chunk); ++i) {
      chunk.points.push_back({0.5F * static_cast<float>(i), -1.0F, 2.0F, 0.0F});
    }
    v1::Upload upload;
    upload.set_sequence(first_sequence + c);
    *upload.mutable_points() = toProto(chunk);
    total += upload.ByteSizeLong();
  }
  return total;
}

TEST(ProtoConvert, BaselineUploadBytesEqualTheSerialisedUploads) {
  MapHeader header;
  header.node = 7;
  header.epoch = 17'000'000'123ULL;
  header.sensor_time_ns = 1'700'000'000'123'456'789LL;
  header.contributing_nodes = {7};
  for (const std::size_t points : {0UL, 1UL, 10UL, 127UL, 1000UL, 65'535UL, 65'536UL, 65'537UL, 150'000UL}) {
    for (const std::size_t per_chunk : {1000UL, 65'536UL}) {
      for (const std::uint64_t sequence : {0ULL, 1ULL, 127ULL, 128ULL, 1ULL << 35}) {
        if (points / per_chunk > 100) continue;  // keep the oracle quick
        EXPECT_EQ(baselineUploadBytes(header, points, per_chunk, sequence),
                  serialisedBaselineBytes(header, points, per_chunk, sequence))
            << points << " points, " << per_chunk << " a chunk, from sequence " << sequence;
      }
    }
  }
}

TEST(ProtoConvert, PointsArePackedLittleEndianFloat32) {
  PointChunk c;
  c.total_points = 1;
  c.points.push_back({1.0F, -2.0F, 0.5F, 9.0F});
  c.labels = {-1};
  const v1::PointChunk wire = toProto(c);
  const std::string expected_xyz("\x00\x00\x80\x3f\x00\x00\x00\xc0\x00\x00\x00\x3f", 12);
  EXPECT_EQ(wire.xyz(), expected_xyz);
  EXPECT_EQ(wire.labels(), std::string("\xff\xff\xff\xff", 4));
}

TEST(ProtoConvert, GlobalMapRoundTripKeepsAllButGeometryExactly) {
  std::mt19937_64 rng(4);
  for (const Mode mode : {Mode::kMadc, Mode::kBaseline, Mode::kExt}) {
    GlobalMapMessage g;
    g.header = sampleHeader();
    g.map = randomMap(rng, 12, Geometry::kDouble, kSampleEpoch, Wire::kMixed);
    g.mode = mode;
    g.published_time_ns = 1700000000999999999LL;
    g.merge_seconds = 0.000123456789;
    g.pairs_all = 1234;
    g.pairs_tested = 56;
    g.point_labels = {{1, {0, 0, -1, 2}}, {4, {}}, {9, {std::numeric_limits<std::int32_t>::max()}}};
    g.revision = 3;
    g.late = true;
    const auto back = fromProto(toProto(g));
    ASSERT_TRUE(back.ok()) << back.error().message;
    GlobalMapMessage but_the_map = *back;
    but_the_map.map = g.map;
    EXPECT_EQ(but_the_map, g) << modeName(mode);
    expectWithinCompactBound(back->map, g.map);
  }
}

TEST(ProtoConvert, GeofenceRoundTripIsExact) {
  const Geofence fence = boxGeofence("loading bay", {-1.5, 2.0 / 3.0, 0.0}, {4.0, 5.25, 3.0});
  const auto back = fromProto(toProto(fence));
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->name, fence.name);
  ASSERT_EQ(back->half_spaces.size(), fence.half_spaces.size());
  for (std::size_t i = 0; i < fence.half_spaces.size(); ++i) {
    EXPECT_EQ(back->half_spaces[i].normal, fence.half_spaces[i].normal);
    EXPECT_EQ(back->half_spaces[i].offset, fence.half_spaces[i].offset);
  }
}

// ---- compact records on the wire -------------------------------------------------------------

// `count` clusters of one sensor's frame, within 80 m of the sensor (x, y) and 3 m in z.
std::vector<Ellipsoid> sensorClusters(std::mt19937_64& rng, std::uint32_t node, std::uint64_t frame, int count,
                                      const Eigen::Vector3d& sensor) {
  std::uniform_real_distribution<double> across(-80.0, 80.0);
  std::uniform_real_distribution<double> up(0.0, 3.0);
  std::uniform_int_distribution<std::uint64_t> points(10, 5000);
  std::vector<Ellipsoid> out;
  for (int k = 0; k < count; ++k) {
    Ellipsoid e;
    e.id = {node, frame, static_cast<std::uint32_t>(k)};
    e.center = sensor + Eigen::Vector3d{across(rng), across(rng), up(rng)};
    e.shape = randomShape(rng, 0.2, 4.0);
    e.point_count = points(rng);
    out.push_back(e);
  }
  return out;
}

// A block whose ellipsoids all fit records around the common frame's origin takes that origin,
// which the wire leaves out; one beyond 327.67 m of it takes the first centre's instead.
TEST(ProtoConvert, BlocksNearTheCommonOriginLeaveTheirOriginOut) {
  std::mt19937_64 rng(23);
  MapMessage m;
  m.header.node = 7;
  m.header.epoch = 17'000'000'123ULL;
  m.map = localMap(sensorClusters(rng, 7, m.header.epoch, 10, {25.0, -40.0, 1.0}));
  const v1::Map near = toProto(m);
  ASSERT_EQ(near.blocks_size(), 1);
  EXPECT_EQ(originOf(near.blocks(0)),
            (CompactOrigin{0, 0, 0}));
  const auto back = fromProto(near);
  ASSERT_TRUE(back.ok()) << back.error().message;
  expectWithinCompactBound(back->map, m.map);
  EXPECT_EQ(toProto(*back).SerializeAsString(), near.SerializeAsString()) << "a decoded map encodes to the same bytes";

  // Moved 200 m out, and one ellipsoid 300 m beyond the first: beyond 327.67 m of the common origin,
  // so the block's origin is its first centre, and every record still fits around it.
  std::vector<Ellipsoid> ellipsoids;
  for (const auto& o : m.map.objects) ellipsoids.push_back(o.ellipsoids[0]);
  for (auto& e : ellipsoids) e.center += Eigen::Vector3d(200.0, 0.0, 0.0);
  ellipsoids.back().center = ellipsoids.front().center + Eigen::Vector3d(300.0, 0.0, 0.0);
  m.map = localMap(ellipsoids);
  const v1::Map far = toProto(m);
  ASSERT_EQ(far.blocks_size(), 1);
  EXPECT_EQ(far.blocks(0).records().size(), 10 * recordBytes(far.blocks(0)));
  EXPECT_EQ(originOf(far.blocks(0)),
            compactOriginNear(m.map.objects[0].ellipsoids[0].center));
}

TEST(ProtoConvert, LocalMapTravelsAsOneBlockOfNumberedRecordsOfAtMost21BytesAnEllipsoid) {
  std::mt19937_64 rng(21);
  MapMessage m;
  m.header.node = 7;
  m.header.epoch = 17'000'000'123ULL;
  m.header.sensor_time_ns = 1'700'000'012'300'000'000LL;
  m.header.contributing_nodes = {7};
  m.map = localMap(sensorClusters(rng, 7, m.header.epoch, 100, {1234.5, -678.9, 2.0}));
  v1::Upload upload;
  upload.set_sequence(4242);
  *upload.mutable_map() = toProto(m);
  const v1::Map& wire = upload.map();
  EXPECT_EQ(wire.objects_size(), 0) << "every record is an object of its own";
  ASSERT_EQ(wire.blocks_size(), 1);
  const v1::EllipsoidBlock& block = wire.blocks(0);
  EXPECT_EQ(block.node(), 7U);
  EXPECT_FALSE(block.has_frame());
  EXPECT_EQ(block.object_step_size(), 0);
  EXPECT_EQ(wire.packed_objects(), 0U);
  // The edge's clusters are numbered 0 .. 99 in record order: the block numbers them, 20 bytes a record.
  ASSERT_TRUE(block.has_first_index());
  EXPECT_EQ(block.first_index(), 0U);
  EXPECT_EQ(block.records().size(), 100 * kCompactRecordBytesWithoutIndex);
  EXPECT_EQ(originOf(block),
            compactOriginNear(m.map.objects[0].ellipsoids[0].center))
      << "the origin is the first centre";

  const double per_ellipsoid = static_cast<double>(upload.ByteSizeLong()) / 100.0;
  std::printf("[ compact  ] local map, 100 ellipsoids: %zu bytes as a Map, %zu as an Upload: %.2f bytes an ellipsoid\n",
              wire.ByteSizeLong(), upload.ByteSizeLong(), per_ellipsoid);
  EXPECT_LE(per_ellipsoid, 21.0);

  v1::Map parsed;
  ASSERT_TRUE(parsed.ParseFromString(wire.SerializeAsString()));
  const auto back = fromProto(parsed);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->header, m.header);
  expectWithinCompactBound(back->map, m.map);
}

// 100 objects of 2 or 3 ellipsoids, each from another of 6 sensors around a site.
GlobalMapMessage multiNodeGlobalMap(std::mt19937_64& rng) {
  GlobalMapMessage g;
  g.header.node = 100;
  g.header.epoch = 17'000'000'123ULL;
  g.header.sensor_time_ns = 1'700'000'012'300'000'000LL;
  g.header.contributing_nodes = {1, 2, 3, 4, 5, 6};
  g.mode = Mode::kMadc;
  g.published_time_ns = 1'700'000'012'400'000'000LL;
  g.merge_seconds = 0.0021;
  g.pairs_all = 31000;
  g.pairs_tested = 640;
  std::uniform_real_distribution<double> across(-100.0, 100.0);
  std::normal_distribution<double> jitter(0.0, 0.2);
  std::uniform_int_distribution<std::uint64_t> points(10, 3000);
  std::vector<std::uint32_t> next_index(7, 0);
  std::vector<Ellipsoid> ellipsoids;
  std::vector<std::size_t> object_of;
  for (std::size_t o = 0; o < 100; ++o) {
    const Eigen::Vector3d at{5000.0 + across(rng), -2000.0 + across(rng), 1.0};
    std::vector<std::uint32_t> nodes = {1, 2, 3, 4, 5, 6};
    std::shuffle(nodes.begin(), nodes.end(), rng);
    nodes.resize(o % 2 == 0 ? 2 : 3);
    for (const std::uint32_t node : nodes) {
      Ellipsoid e;
      e.id = {node, g.header.epoch, next_index[node]++};
      e.center = at + Eigen::Vector3d{jitter(rng), jitter(rng), jitter(rng)};
      e.shape = randomShape(rng, 0.2, 3.0);
      e.point_count = points(rng);
      ellipsoids.push_back(e);
      object_of.push_back(o);
    }
  }
  g.map = mapFromGroups(ellipsoids, object_of);
  return g;
}

TEST(ProtoConvert, GlobalMapOfMultiNodeObjectsListsTheObjectOfEachRecord) {
  std::mt19937_64 rng(22);
  const GlobalMapMessage g = multiNodeGlobalMap(rng);
  const v1::GlobalMap wire = toProto(g);
  EXPECT_EQ(wire.objects_size(), 0) << "every ellipsoid is a record: no object is listed";
  EXPECT_EQ(wire.packed_objects(), 100U);
  EXPECT_EQ(wire.blocks_size(), 6) << "one block per sensor";
  for (const auto& b : wire.blocks()) {
    EXPECT_EQ(static_cast<std::size_t>(b.object_step_size()) * recordBytes(b), b.records().size());
    for (const std::int32_t step : b.object_step()) EXPECT_GE(step, 0) << "records follow their objects' order";
  }
  const std::size_t count = g.map.ellipsoidCount();
  const double per_ellipsoid = static_cast<double>(wire.ByteSizeLong()) / static_cast<double>(count);
  std::printf("[ compact  ] global map, 100 objects of %zu ellipsoids from 6 sensors: %zu bytes, %.2f bytes an "
              "ellipsoid\n", count, wire.ByteSizeLong(), per_ellipsoid);
  // 22 bytes a record, 1 for its object's step, and the block headers.
  EXPECT_LE(per_ellipsoid, 24.0);

  v1::GlobalMap parsed;
  ASSERT_TRUE(parsed.ParseFromString(wire.SerializeAsString()));
  const auto back = fromProto(parsed);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->header, g.header);
  EXPECT_EQ(back->pairs_all, g.pairs_all);
  expectWithinCompactBound(back->map, g.map);
}

Ellipsoid ellipsoidWithAxes(const EllipsoidId& id, const Eigen::Vector3d& center, const Eigen::Vector3d& semi_axes) {
  std::mt19937_64 rng(id.index + 31 * id.node);
  const Eigen::Matrix3d r = fogmap::test_support::randomRotation(rng);
  const Eigen::Matrix3d m = r * semi_axes.cwiseAbs2().asDiagonal() * r.transpose();
  Ellipsoid e;
  e.id = id;
  e.center = center;
  e.shape = 0.5 * (m + m.transpose());
  e.point_count = 25 + id.index;
  return e;
}

TEST(ProtoConvert, EllipsoidsThatDoNotFitARecordTravelExactlyInTheirObjects) {
  const std::uint64_t epoch = kSampleEpoch;
  const Eigen::Vector3d site(100.0, 200.0, 1.0);
  const Ellipsoid near1 = ellipsoidWithAxes({1, epoch, 0}, site, {0.3, 0.6, 1.1});
  const Ellipsoid long2 = ellipsoidWithAxes({2, epoch, 0}, site + Eigen::Vector3d(1.0, 0.0, 0.0), {0.3, 0.5, 80.0});
  const Ellipsoid far1 = ellipsoidWithAxes({1, epoch, 1}, site + Eigen::Vector3d(400.0, 0.0, 0.0), {0.4, 0.7, 1.3});
  const Ellipsoid near2 = ellipsoidWithAxes({2, epoch, 1}, site + Eigen::Vector3d(400.5, 0.0, 0.0), {0.2, 0.9, 1.4});
  const Ellipsoid lone3 = ellipsoidWithAxes({3, epoch, 0}, site + Eigen::Vector3d(20.0, 10.0, 0.0), {0.5, 2.0, 70.0});
  const Ellipsoid more1 =
      ellipsoidWithAxes({1, epoch, 2}, site + Eigen::Vector3d(10.0, -10.0, 0.0), {0.25, 0.35, 0.45});
  EXPECT_FALSE(fitsCompact(long2, compactOriginNear(long2.center))) << "an 80 m semi-axis";
  EXPECT_FALSE(fitsCompact(far1, compactOriginNear(near1.center))) << "400 m from node 1's origin";
  const std::vector<Ellipsoid> ellipsoids = {near1, long2, far1, near2, lone3, more1};
  const MapMessage m{sampleHeader(), mapFromGroups(ellipsoids, std::vector<std::size_t>{0, 0, 1, 1, 2, 3})};

  const v1::Map wire = toProto(m);
  // Exact ellipsoids in their objects, as (object, node, index); records per node.
  std::vector<std::array<std::uint32_t, 3>> exact;
  for (int o = 0; o < wire.objects_size(); ++o) {
    for (const auto& e : wire.objects(o).ellipsoids()) {
      exact.push_back({static_cast<std::uint32_t>(o), e.id().node(), e.id().index()});
    }
  }
  std::sort(exact.begin(), exact.end());
  // Objects in canonical order (by first id): {near1, long2}, {far1, near2}, {more1}, {lone3}. The
  // two with an exact ellipsoid (80 m and 70 m semi-axes) are listed; {far1, near2} and {more1},
  // all records, follow them unlisted.
  EXPECT_EQ(exact, (std::vector<std::array<std::uint32_t, 3>>{{0, 2, 0}, {1, 3, 0}}));
  ASSERT_EQ(wire.objects_size(), 2);
  EXPECT_EQ(wire.packed_objects(), 2U);
  // Node 1's ellipsoids 400 m apart take two blocks: near1 and more1 around near1, far1 around
  // itself, a record still; node 2's near2 a block around itself (beyond reach of the common origin).
  ASSERT_EQ(wire.blocks_size(), 3);
  EXPECT_EQ(wire.blocks(0).node(), 1U);
  EXPECT_EQ(recordObjects(wire.blocks(0)), (std::vector<std::int64_t>{0, 3}));
  EXPECT_EQ(originOf(wire.blocks(0)),
            compactOriginNear(near1.center));
  EXPECT_EQ(wire.blocks(1).node(), 1U);
  EXPECT_EQ(recordObjects(wire.blocks(1)), (std::vector<std::int64_t>{2}));
  EXPECT_EQ(originOf(wire.blocks(1)),
            compactOriginNear(far1.center));
  EXPECT_EQ(wire.blocks(2).node(), 2U);
  EXPECT_EQ(recordObjects(wire.blocks(2)), (std::vector<std::int64_t>{2}));
  EXPECT_EQ(originOf(wire.blocks(2)),
            compactOriginNear(near2.center))
      << "the origin is the first centre that fits";

  const auto back = fromProto(wire);
  ASSERT_TRUE(back.ok()) << back.error().message;
  expectWithinCompactBound(back->map, m.map);
  for (const auto& o : back->map.objects) {
    for (const auto& e : o.ellipsoids) {
      for (const Ellipsoid& sent : {long2, lone3}) {
        if (e.id == sent.id) {
          EXPECT_EQ(e, roundedToFloat(sent)) << toString(e.id) << " travelled exactly";
        }
      }
    }
  }
}

// The rule for objects, on a hand-built message: object 0 holds an exact ellipsoid and, through
// block 0's object_step, a record; block 1 (the same node and frame as block 0, another origin) lists
// no objects, so each of its records is an object of its own.
TEST(ProtoConvert, RecordsOfABlockWithoutObjectListAreObjectsOfTheirOwn) {
  const std::uint64_t epoch = kSampleEpoch;
  const Ellipsoid a = ellipsoidWithAxes({1, epoch, 0}, {0.0, 0.0, 0.0}, {0.5, 0.6, 90.0});
  const Ellipsoid b = ellipsoidWithAxes({2, epoch, 0}, {0.3, 0.1, 0.0}, {0.5, 0.6, 0.7});
  const Ellipsoid c = ellipsoidWithAxes({2, epoch, 1}, {30.0, 0.0, 0.0}, {0.5, 0.6, 0.7});
  const Ellipsoid d = ellipsoidWithAxes({2, epoch, 2}, {-30.0, 0.0, 0.0}, {0.5, 0.6, 0.7});
  v1::Map wire = toProto(MapMessage{sampleHeader(), localMap({a})});
  ASSERT_EQ(wire.objects_size(), 1);
  ASSERT_EQ(wire.blocks_size(), 0);
  v1::EllipsoidBlock* shared = wire.add_blocks();
  shared->set_node(2);
  const CompactOrigin at_b = compactOriginNear(b.center);
  shared->set_origin_x_cm(at_b.x_cm);
  shared->set_origin_y_cm(at_b.y_cm);
  shared->set_origin_z_cm(at_b.z_cm);
  ASSERT_TRUE(appendCompact(b, at_b, *shared->mutable_records()));
  shared->add_object_step(0);
  v1::EllipsoidBlock* own = wire.add_blocks();
  own->set_node(2);
  own->set_frame(epoch);
  const CompactOrigin at_c = compactOriginNear(c.center);
  own->set_origin_x_cm(at_c.x_cm);
  own->set_origin_y_cm(at_c.y_cm);
  own->set_origin_z_cm(at_c.z_cm);
  ASSERT_TRUE(appendCompact(d, at_c, *own->mutable_records()));
  ASSERT_TRUE(appendCompact(c, at_c, *own->mutable_records()));

  const auto back = fromProto(wire);
  ASSERT_TRUE(back.ok()) << back.error().message;
  const Map expected = mapFromGroups(std::vector<Ellipsoid>{a, b, c, d}, std::vector<std::size_t>{0, 0, 1, 2});
  expectWithinCompactBound(back->map, expected);
  // Encoded again, the map takes the encoder's form: one block for node 2, listing objects.
  const v1::Map again = toProto(*back);
  EXPECT_EQ(again.objects_size(), 1) << "the object with an exact ellipsoid";
  EXPECT_EQ(again.packed_objects(), 2U);
  EXPECT_EQ(again.blocks_size(), 1);
}

// ---- malformed maps: exact ellipsoids --------------------------------------------------------

TEST(ProtoConvert, RejectsEllipsoidWithoutId) {
  v1::Map wire = exactSampleProtoMap();
  wire.mutable_objects(2)->mutable_ellipsoids(0)->clear_id();
  expectRejected(fromProto(wire), {"object 2", "ellipsoid 0", "id"});
}

TEST(ProtoConvert, RejectsEllipsoidWithoutCenter) {
  v1::Map wire = exactSampleProtoMap();
  wire.mutable_objects(1)->mutable_ellipsoids(1)->clear_center();
  expectRejected(fromProto(wire), {"object 1", "ellipsoid 1", "center"});
}

TEST(ProtoConvert, RejectsCenterWithoutThreeValues) {
  for (const int n : {0, 2, 4}) {
    v1::Map wire = exactSampleProtoMap();
    auto* center = wire.mutable_objects(1)->mutable_ellipsoids(1)->mutable_center();
    center->Clear();
    for (int i = 0; i < n; ++i) center->Add(1.0F);
    expectRejected(fromProto(wire), {"object 1", "ellipsoid 1", "center", std::to_string(n) + " values"});
  }
}

TEST(ProtoConvert, RejectsShapeWithoutSixValues) {
  for (const int n : {0, 5, 7, 9}) {
    v1::Map wire = exactSampleProtoMap();
    auto* shape = wire.mutable_objects(3)->mutable_ellipsoids(0)->mutable_shape();
    shape->Clear();
    for (int i = 0; i < n; ++i) shape->Add(1.0F);
    expectRejected(fromProto(wire), {"object 3", "ellipsoid 0", "shape", std::to_string(n) + " values"});
  }
}

TEST(ProtoConvert, RejectsNonFiniteNumbers) {
  for (const float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    v1::Map wire = exactSampleProtoMap();
    wire.mutable_objects(4)->mutable_ellipsoids(0)->set_center(1, bad);
    expectRejected(fromProto(wire), {"object 4", "center", "finite"});

    wire = exactSampleProtoMap();
    wire.mutable_objects(4)->mutable_ellipsoids(0)->set_shape(4, bad);
    expectRejected(fromProto(wire), {"object 4", "shape", "finite"});
  }
}

TEST(ProtoConvert, RejectsShapeNotPositiveDefinite) {
  const std::vector<std::array<float, 6>> bad = {
      {0.0F, 0.0F, 0.0F, 0.0F, 0.0F, 0.0F},    // zero
      {1.0F, 0.0F, 0.0F, -1.0F, 0.0F, 1.0F},   // negative diagonal
      {1.0F, 2.0F, 0.0F, 1.0F, 0.0F, 1.0F},    // positive diagonal, indefinite
      {1.0F, 1.0F, 1.0F, 1.0F, 1.0F, 1.0F},    // singular (rank 1)
  };
  for (const auto& values : bad) {
    v1::Map wire = exactSampleProtoMap();
    auto* shape = wire.mutable_objects(5)->mutable_ellipsoids(0)->mutable_shape();
    for (int i = 0; i < 6; ++i) shape->Set(i, values[static_cast<std::size_t>(i)]);
    expectRejected(fromProto(wire), {"object 5", "ellipsoid 0", "positive definite"});
  }
}

TEST(ProtoConvert, RejectsEmptyObject) {
  v1::Map wire = exactSampleProtoMap();
  wire.add_objects();
  expectRejected(fromProto(wire), {"object " + std::to_string(wire.objects_size() - 1), "no ellipsoids"});
}

TEST(ProtoConvert, RejectsDuplicateEllipsoidIds) {
  v1::Map wire = exactSampleProtoMap();
  *wire.mutable_objects(6)->add_ellipsoids() = wire.objects(2).ellipsoids(0);
  expectRejected(fromProto(wire), {"duplicate ellipsoid id", "object 2 ellipsoid 0 and object 6 ellipsoid 1"});
}

TEST(ProtoConvert, RejectsMalformedGlobalMapObjects) {
  GlobalMapMessage g;
  std::mt19937_64 rng(5);
  g.map = randomMap(rng, 4, Geometry::kFloat, kSampleEpoch, Wire::kExact);
  v1::GlobalMap wire = toProto(g);
  wire.mutable_objects(1)->mutable_ellipsoids(0)->mutable_shape()->RemoveLast();
  expectRejected(fromProto(wire), {"GlobalMap", "object 1", "shape"});
}

TEST(ProtoConvert, RejectsUnknownMode) {
  for (const std::string mode : {"", "MADC", "centralised"}) {
    v1::GlobalMap wire = toProto(GlobalMapMessage{});
    wire.set_mode(mode);
    expectRejected(fromProto(wire), {"mode '" + mode + "'"});
  }
}

TEST(ProtoConvert, RejectsPointLabelsNotFourBytesEach) {
  GlobalMapMessage g;
  g.point_labels = {{3, {1, 2}}};
  v1::GlobalMap wire = toProto(g);
  wire.mutable_point_labels(0)->mutable_labels()->push_back('\0');
  expectRejected(fromProto(wire), {"point_labels 0", "node 3", "9 bytes"});
}

// ---- malformed maps: compact records ---------------------------------------------------------

TEST(ProtoConvert, PackedSampleIsValidAndHasTheBlocksTheseTestsBreak) {
  const v1::Map wire = packedSampleProtoMap();
  ASSERT_EQ(wire.objects_size(), 0);
  ASSERT_EQ(wire.packed_objects(), 9U);
  ASSERT_GE(wire.blocks_size(), 2);
  EXPECT_EQ(wire.blocks(0).node(), 1U);
  EXPECT_EQ(wire.blocks(0).records().size(), 9 * kCompactEllipsoidBytes);
  EXPECT_EQ(recordObjects(wire.blocks(0)), (std::vector<std::int64_t>{0, 1, 2, 3, 4, 5, 6, 7, 8}));
  EXPECT_EQ(wire.blocks(1).records().size(), kCompactEllipsoidBytes);
  EXPECT_TRUE(fromProto(wire).ok());
}

TEST(ProtoConvert, RejectsBlockRecordsNotAMultipleOf22Bytes) {
  v1::Map wire = packedSampleProtoMap();
  wire.mutable_blocks(1)->mutable_records()->append("abc");
  expectRejected(fromProto(wire), {"Map: blocks[1]", "records has 25 bytes", "not a multiple of 22"});

  GlobalMapMessage g;
  std::mt19937_64 rng(5);
  g.map = randomMap(rng, 4);
  v1::GlobalMap global = withIndicesInRecords(toProto(g));
  global.mutable_blocks(0)->mutable_records()->resize(21);
  expectRejected(fromProto(global), {"GlobalMap: blocks[0]", "21 bytes", "not a multiple of 22"});
}

// A block that numbers its records: 20 bytes each, and no index past 2^32 - 1.
TEST(ProtoConvert, RejectsNumberedBlocksWhoseRecordsAreCutOrRunPastTheLastIndex) {
  MapMessage m;
  m.header.node = 3;
  m.header.epoch = 17'000'000'123ULL;
  std::mt19937_64 rng(8);
  m.map = localMap(sensorClusters(rng, 3, m.header.epoch, 4, {10.0, 0.0, 0.0}));
  const v1::Map numbered = toProto(m);
  ASSERT_EQ(numbered.blocks_size(), 1);
  ASSERT_TRUE(numbered.blocks(0).has_first_index());
  ASSERT_TRUE(fromProto(numbered).ok());

  v1::Map cut = numbered;
  cut.mutable_blocks(0)->mutable_records()->resize(4 * kCompactRecordBytesWithoutIndex - 1);
  expectRejected(fromProto(cut), {"Map: blocks[0]", "79 bytes", "not a multiple of 20", "first_index"});

  v1::Map last = numbered;
  last.mutable_blocks(0)->set_first_index(std::numeric_limits<std::uint32_t>::max() - 3);  // 2^32 - 4 .. 2^32 - 1
  const auto at_the_end = fromProto(last);
  ASSERT_TRUE(at_the_end.ok()) << at_the_end.error().message;
  EXPECT_EQ(at_the_end->map.objects.back().ellipsoids[0].id.index, std::numeric_limits<std::uint32_t>::max());
  last.mutable_blocks(0)->set_first_index(std::numeric_limits<std::uint32_t>::max() - 2);
  expectRejected(fromProto(last), {"Map: blocks[0]", "first_index 4294967293 and 4 records", "2^32 - 1"});

  // A block whose indices do not run on keeps them in its records.
  m.map = localMap({m.map.objects[0].ellipsoids[0], m.map.objects[2].ellipsoids[0]});
  const v1::Map gapped = toProto(m);
  ASSERT_EQ(gapped.blocks_size(), 1);
  EXPECT_FALSE(gapped.blocks(0).has_first_index());
  EXPECT_EQ(gapped.blocks(0).records().size(), 2 * kCompactEllipsoidBytes);
}

TEST(ProtoConvert, RejectsRecordObjectOutOfRange) {
  // Record 3 names object 3: every value here is one step of an int32 from it.
  for (const std::int64_t bad : {std::int64_t{9}, std::int64_t{-1}, std::int64_t{-1000},
                                 std::int64_t{std::numeric_limits<std::int32_t>::max()}}) {
    v1::Map wire = packedSampleProtoMap();
    std::vector<std::int64_t> objects = recordObjects(wire.blocks(0));
    objects[4] = bad;
    setRecordObjects(*wire.mutable_blocks(0), objects);
    expectRejected(fromProto(wire), {"Map: blocks[0] record 4", "names object " + std::to_string(bad), "out of range",
                                     "9 objects"});
  }
}

TEST(ProtoConvert, RejectsMorePackedObjectsThanRecords) {
  v1::Map wire = packedSampleProtoMap();
  std::size_t records = 0;
  for (const auto& b : wire.blocks()) records += b.records().size() / kCompactEllipsoidBytes;
  wire.set_packed_objects(static_cast<std::uint32_t>(records) + 1);
  expectRejected(fromProto(wire), {"Map: packed_objects " + std::to_string(records + 1), "exceeds the " +
                                   std::to_string(records) + " records"});
  // Sized by the records, never by the count: the largest count is refused as cheaply.
  wire.set_packed_objects(std::numeric_limits<std::uint32_t>::max());
  expectRejected(fromProto(wire), {"packed_objects 4294967295"});
}

TEST(ProtoConvert, RejectsObjectListOfAnotherLengthThanTheRecords) {
  v1::Map wire = packedSampleProtoMap();
  wire.mutable_blocks(0)->add_object_step(0);
  expectRejected(fromProto(wire), {"Map: blocks[0]", "object_step has 10 entries for 9 records"});
  wire = packedSampleProtoMap();
  wire.mutable_blocks(0)->mutable_object_step()->RemoveLast();
  expectRejected(fromProto(wire), {"Map: blocks[0]", "object_step has 8 entries for 9 records"});
  wire = packedSampleProtoMap();
  wire.add_blocks()->add_object_step(0);
  expectRejected(fromProto(wire),
                 {"blocks[" + std::to_string(wire.blocks_size() - 1) + "]", "1 entries for 0 records"});
}

TEST(ProtoConvert, RejectsRecordsTheCodecRefuses) {
  v1::Map wire = packedSampleProtoMap();
  std::string& records = *wire.mutable_blocks(0)->mutable_records();
  records[7 * kCompactEllipsoidBytes + 8] = 0;  // semi-axis 1: bytes 8..9
  records[7 * kCompactEllipsoidBytes + 9] = 0;
  expectRejected(fromProto(wire), {"Map: blocks[0] record 7", "semi-axis 1 is 0 mm"});

  wire = packedSampleProtoMap();
  wire.mutable_blocks(0)->mutable_records()->at(3 * kCompactEllipsoidBytes + 17) |= static_cast<char>(0x80);
  expectRejected(fromProto(wire), {"Map: blocks[0] record 3", "reserved bit 47"});
}

TEST(ProtoConvert, RejectsDuplicateIdsAcrossExactAndPackedEllipsoids) {
  // An exact ellipsoid with the id of node 1's record 2 (1/epoch/2).
  // Listed object 0 is the first object (packed_objects one fewer), so the records name it as before.
  v1::Map wire = packedSampleProtoMap();
  wire.set_packed_objects(wire.packed_objects() - 1);
  v1::Ellipsoid* copy = wire.add_objects()->add_ellipsoids();
  copy->mutable_id()->set_node(1);
  copy->mutable_id()->set_index(2);
  for (const float v : {1.0F, 2.0F, 3.0F}) copy->add_center(v);
  for (const float v : {1.0F, 0.0F, 0.0F, 1.0F, 0.0F, 1.0F}) copy->add_shape(v);
  expectRejected(fromProto(wire), {"Map: duplicate ellipsoid id 1/" + std::to_string(kSampleEpoch) + "/2",
                                   "object 0 ellipsoid 0 and blocks[0] record 2"});

  // A record twice in its block.
  wire = packedSampleProtoMap();
  v1::EllipsoidBlock* block = wire.mutable_blocks(0);
  block->mutable_records()->append(block->records().substr(2 * kCompactEllipsoidBytes, kCompactEllipsoidBytes));
  std::vector<std::int64_t> objects = recordObjects(*block);
  objects.push_back(objects[2]);
  setRecordObjects(*block, objects);
  expectRejected(fromProto(wire), {"duplicate ellipsoid id", "blocks[0] record 2 and blocks[0] record 9"});

  // A block twice.
  wire = packedSampleProtoMap();
  *wire.add_blocks() = wire.blocks(0);
  expectRejected(fromProto(wire), {"duplicate ellipsoid id",
                                   "blocks[0] record 0 and blocks[" + std::to_string(wire.blocks_size() - 1) +
                                       "] record 0"});
}

TEST(ProtoConvert, RejectsObjectLeftWithoutEllipsoids) {
  v1::Map wire = packedSampleProtoMap();
  std::vector<std::int64_t> objects = recordObjects(wire.blocks(0));
  objects[0] = 1;  // object 0's only ellipsoid now in object 1
  setRecordObjects(*wire.mutable_blocks(0), objects);
  expectRejected(fromProto(wire), {"Map: object 0 has no ellipsoids"});
}

// ---- MERGE on decoded maps -------------------------------------------------------------------

// A scene seen by `nodes` sensors: obstacles in a 80 m square, each seen by a sensor with
// probability 0.75 as an ellipsoid with its own noise (centre 10 cm, extents 10 %) and the aura,
// and a few clusters only one sensor sees. One local map per sensor.
std::vector<Map> randomScene(std::mt19937_64& rng, int nodes, std::uint64_t epoch) {
  std::uniform_real_distribution<double> across(-40.0, 40.0);
  std::uniform_real_distribution<double> up(0.0, 2.0);
  std::uniform_real_distribution<double> extent(0.3, 2.0);
  std::uniform_real_distribution<double> yaw(-std::numbers::pi, std::numbers::pi);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.1);
  struct Obstacle {
    Eigen::Vector3d at;
    Eigen::Vector3d semi;
    double yaw;
  };
  std::vector<Obstacle> obstacles(25);
  for (auto& o : obstacles) {
    o = {{across(rng), across(rng), up(rng)}, {extent(rng), extent(rng), extent(rng) / 2}, yaw(rng)};
  }
  const auto ellipsoid = [&](const EllipsoidId& id, const Eigen::Vector3d& at, const Eigen::Vector3d& semi,
                             double angle) {
    const Eigen::Matrix3d r = Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Matrix3d m = r * semi.cwiseAbs2().asDiagonal() * r.transpose();
    Ellipsoid e;
    e.id = id;
    e.center = at;
    e.shape = withAura(0.5 * (m + m.transpose()), 0.175);
    e.point_count = 10 + id.index;
    return e;
  };
  std::vector<Map> maps;
  for (int n = 0; n < nodes; ++n) {
    const auto node = static_cast<std::uint32_t>(n + 1);
    std::vector<Ellipsoid> seen;
    for (const auto& o : obstacles) {
      if (unit(rng) > 0.75) continue;
      // One draw a statement or in braces: the same scene whatever order a compiler evaluates arguments in.
      const Eigen::Vector3d scale = Eigen::Vector3d{noise(rng), noise(rng), noise(rng)};
      const Eigen::Vector3d at = o.at + Eigen::Vector3d{noise(rng), noise(rng), noise(rng)};
      const double angle = o.yaw + noise(rng);
      const Eigen::Vector3d semi = o.semi.cwiseProduct(Eigen::Vector3d::Constant(1.0) + 0.1 * scale);
      seen.push_back(ellipsoid({node, epoch, static_cast<std::uint32_t>(seen.size())}, at, semi, angle));
    }
    for (int k = 0; k < 5; ++k) {
      const Eigen::Vector3d at{across(rng), across(rng), up(rng)};
      const Eigen::Vector3d semi{extent(rng) / 3, extent(rng) / 3, extent(rng) / 3};
      const double angle = yaw(rng);
      seen.push_back(ellipsoid({node, epoch, static_cast<std::uint32_t>(seen.size())}, at, semi, angle));
    }
    maps.push_back(localMap(std::move(seen)));
  }
  return maps;
}

std::vector<std::vector<EllipsoidId>> partition(const Map& map) {
  std::vector<std::vector<EllipsoidId>> out;
  for (const auto& o : map.objects) {
    out.emplace_back();
    for (const auto& e : o.ellipsoids) out.back().push_back(e.id);
  }
  return out;
}

// Cross-node pairs whose intersection test could go either way when each ellipsoid moves by
// `factor` times its error bound: they meet grown by it and do not shrunk by it.
int pairsNearTouching(const std::vector<Ellipsoid>& all, double factor) {
  const auto resized = [](const Ellipsoid& e, double by) {
    Ellipsoid out = e;
    out.shape = withAura(e.shape, by);
    return out;
  };
  int near = 0;
  for (std::size_t i = 0; i < all.size(); ++i) {
    const double di = factor * compactSurfaceErrorBound(axesOf(all[i]).semi.maxCoeff());
    for (std::size_t j = i + 1; j < all.size(); ++j) {
      if (all[i].id.node == all[j].id.node) continue;
      const double dj = factor * compactSurfaceErrorBound(axesOf(all[j]).semi.maxCoeff());
      if (intersects(resized(all[i], di), resized(all[j], dj)) &&
          !intersects(resized(all[i], -di), resized(all[j], -dj))) {
        ++near;
      }
    }
  }
  return near;
}

// MERGE's grouping from decoded local maps equals its grouping from the exact ones wherever no
// cross-node pair is within the error bound of touching: a decoded surface is within the bound of
// the exact one, so each intersection test decides the same. Random scenes do have such pairs (22
// in these 32 scenes of 4,524 ellipsoids, in 11 scenes), and there a decoded pair may decide the
// other way: the test checks equality on the scenes without one, checks that every scene whose
// grouping differs has one, and counts the pairs within 1x and 2x the bound.
TEST(ProtoConvert, MergeOfDecodedLocalMapsGroupsAsMergeOfExactOnes) {
  const std::uint64_t epoch = 17'000'000'123ULL;
  constexpr std::uint64_t kScenes = 32;
  int merged_objects = 0;
  int guaranteed_scenes = 0;
  int differing_scenes = 0;
  int near_1x_total = 0;
  int near_2x_total = 0;
  for (std::uint64_t seed = 1; seed <= kScenes; ++seed) {
    std::mt19937_64 rng(seed);
    const int nodes = 4 + static_cast<int>(seed % 5);
    const std::vector<Map> exact = randomScene(rng, nodes, epoch);
    std::vector<Map> decoded;
    std::vector<Ellipsoid> all;
    for (std::size_t n = 0; n < exact.size(); ++n) {
      MapMessage m;
      m.header.node = static_cast<std::uint32_t>(n + 1);
      m.header.epoch = epoch;
      m.map = exact[n];
      v1::Map parsed;
      ASSERT_TRUE(parsed.ParseFromString(toProto(m).SerializeAsString()));
      const auto back = fromProto(parsed);
      ASSERT_TRUE(back.ok()) << back.error().message;
      decoded.push_back(back->map);
      for (const auto& o : exact[n].objects) all.insert(all.end(), o.ellipsoids.begin(), o.ellipsoids.end());
    }
    const Map from_exact = mergeAll(exact).map;
    const Map from_decoded = mergeAll(decoded).map;
    const bool same = partition(from_decoded) == partition(from_exact);
    const int near_1x = pairsNearTouching(all, 1.0);
    const int near_2x = pairsNearTouching(all, 2.0);
    near_1x_total += near_1x;
    near_2x_total += near_2x;
    for (const auto& o : from_exact.objects) merged_objects += o.ellipsoids.size() > 1 ? 1 : 0;
    std::printf("[ compact  ] scene %2llu: %d nodes, %3zu ellipsoids, %2zu objects after MERGE; cross-node pairs "
                "within 1x / 2x the bound of touching: %d / %d; grouping %s\n",
                static_cast<unsigned long long>(seed), nodes, all.size(), from_exact.objects.size(), near_1x, near_2x,
                same ? "equal" : "differs");
    if (near_1x == 0) {
      ++guaranteed_scenes;
      EXPECT_TRUE(same) << "scene " << seed << ": no pair is within the bound of touching";
    }
    if (!same) {
      ++differing_scenes;
      EXPECT_GT(near_1x, 0) << "scene " << seed << " groups otherwise without a pair near touching";
    }
  }
  std::printf("[ compact  ] %llu scenes: %d without a pair within the bound (grouping equal in each), %d grouped "
              "otherwise; pairs within 1x / 2x the bound: %d / %d\n",
              static_cast<unsigned long long>(kScenes), guaranteed_scenes, differing_scenes, near_1x_total,
              near_2x_total);
  EXPECT_GE(guaranteed_scenes, 8) << "too few scenes where equality is guaranteed to show anything";
  EXPECT_GT(merged_objects, 0) << "scenes where MERGE joins nothing would show nothing";
}

// ---- malformed point chunks ------------------------------------------------------------------

v1::PointChunk samplePointChunk() {
  PointChunk c;
  c.header.node = 4;
  c.chunk = 1;
  c.chunk_count = 3;
  c.first_point = 10;
  c.total_points = 30;
  for (int i = 0; i < 10; ++i) c.points.push_back({static_cast<float>(i), 1.0F, 2.0F, 0.0F});
  c.labels.assign(10, 0);
  return toProto(c);
}

TEST(ProtoConvert, SamplePointChunkIsValid) { EXPECT_TRUE(fromProto(samplePointChunk()).ok()); }

TEST(ProtoConvert, RejectsXyzNotMultipleOfTwelve) {
  v1::PointChunk wire = samplePointChunk();
  wire.mutable_xyz()->append("abcde");
  expectRejected(fromProto(wire), {"node 4", "xyz", "125 bytes", "multiple of 12"});
}

TEST(ProtoConvert, RejectsLabelsNotFourBytesPerPoint) {
  v1::PointChunk wire = samplePointChunk();
  wire.mutable_labels()->resize(36);
  expectRejected(fromProto(wire), {"labels", "36 bytes", "expected 40"});
}

TEST(ProtoConvert, RejectsChunkIndexNotBelowCount) {
  v1::PointChunk wire = samplePointChunk();
  wire.set_chunk(3);
  expectRejected(fromProto(wire), {"chunk 3", "chunk_count 3"});
}

TEST(ProtoConvert, RejectsZeroChunkCount) {
  v1::PointChunk wire = samplePointChunk();
  wire.set_chunk(0);
  wire.set_chunk_count(0);
  expectRejected(fromProto(wire), {"chunk_count is 0"});
}

TEST(ProtoConvert, RejectsPointsBeyondTotal) {
  v1::PointChunk wire = samplePointChunk();
  wire.set_first_point(21);
  expectRejected(fromProto(wire), {"first_point 21", "10 points", "total_points 30"});
  // A first_point near 2^32 must not wrap around.
  wire.set_first_point(std::numeric_limits<std::uint32_t>::max());
  wire.set_total_points(std::numeric_limits<std::uint32_t>::max());
  expectRejected(fromProto(wire), {"exceeds total_points"});
}

TEST(ProtoConvert, RejectsNonFinitePoints) {
  v1::PointChunk wire = samplePointChunk();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(wire.mutable_xyz()->data() + 5 * 12 + 4, &nan, sizeof nan);
  expectRejected(fromProto(wire), {"point 5", "not finite"});
}

// ---- malformed geofences ---------------------------------------------------------------------

TEST(ProtoConvert, RejectsInvalidGeofences) {
  v1::Geofence empty;
  empty.set_name("yard");
  expectRejected(fromProto(empty), {"yard", "no half-spaces"});

  v1::Geofence no_normal = toProto(boxGeofence("gate", {0, 0, 0}, {1, 1, 1}));
  no_normal.mutable_half_spaces(2)->clear_normal();
  expectRejected(fromProto(no_normal), {"gate", "half-space 2", "normal"});

  v1::Geofence zero = toProto(boxGeofence("gate", {0, 0, 0}, {1, 1, 1}));
  zero.mutable_half_spaces(1)->mutable_normal()->set_x(0.0);
  zero.mutable_half_spaces(1)->mutable_normal()->set_y(0.0);
  zero.mutable_half_spaces(1)->mutable_normal()->set_z(0.0);
  expectRejected(fromProto(zero), {"half-space 1", "zero normal"});

  v1::Geofence nan = toProto(boxGeofence("gate", {0, 0, 0}, {1, 1, 1}));
  nan.mutable_half_spaces(4)->set_offset(std::numeric_limits<double>::quiet_NaN());
  expectRejected(fromProto(nan), {"half-space 4", "offset"});
}

TEST(ProtoConvert, ContainmentRoundTripsAndUnknownValuesAreRejected) {
  for (const Containment c : {Containment::kOutside, Containment::kCrossing, Containment::kInside}) {
    const auto back = fromProto(toProto(c));
    ASSERT_TRUE(back.ok());
    EXPECT_EQ(*back, c);
  }
  EXPECT_FALSE(fromProto(v1::CONTAINMENT_UNSPECIFIED).ok());
  EXPECT_FALSE(fromProto(static_cast<v1::Containment>(42)).ok());
}

TEST(ProtoConvert, AnswersCarryTheirGrpcCode) {
  const v1::Ack applied = appliedAck(7, false);
  EXPECT_EQ(applied.sequence(), 7U);
  EXPECT_EQ(applied.status(), v1::ACK_STATUS_APPLIED);
  EXPECT_EQ(applied.code(), 0);
  EXPECT_TRUE(applied.reason().empty());
  EXPECT_EQ(appliedAck(8, true).status(), v1::ACK_STATUS_LATE);
  EXPECT_EQ(appliedAck(8, true).code(), 0);
  // Every refusal is INVALID_ARGUMENT (3) but a size bound, RESOURCE_EXHAUSTED (8).
  for (const Refusal r : {Refusal::kMalformed, Refusal::kWrongMode, Refusal::kUnknownNode, Refusal::kForgedNode,
                          Refusal::kClockSkew, Refusal::kTooLarge, Refusal::kOutOfWorld, Refusal::kBadShape,
                          Refusal::kSequenceConflict, Refusal::kEllipsoidConflict, Refusal::kInconsistentChunks}) {
    const v1::Ack refused = refusedAck(9, Refused{r, std::string("why: ") + refusalName(r)});
    EXPECT_EQ(refused.sequence(), 9U);
    EXPECT_EQ(refused.status(), v1::ACK_STATUS_REFUSED);
    EXPECT_EQ(refused.reason(), std::string("why: ") + refusalName(r));
    EXPECT_EQ(refused.code(), r == Refusal::kTooLarge ? 8 : 3) << refusalName(r);
  }
  EXPECT_EQ(refusedAck(10, resourceExhausted("queue full")).code(), 8);
  EXPECT_EQ(refusedAck(10, Error{ErrorCode::kInternal, "no parent"}).code(), 13);
}

// An edge's centroid frame whose geometry is float-representable (what an edge's doubles become on
// the wire), with one centroid's covariance singular (a cluster of points on a plane).
tracking::CentroidFrame sampleCentroidFrame() {
  tracking::CentroidFrame f;
  f.edge = "edge-north";
  f.epoch = 17'000'000'123;
  f.time_ns = 1'700'000'012'300'000'000;
  f.sensor_position = {-20.0, 0.5, 1.75};
  std::mt19937_64 rng(7);
  for (int i = 0; i < 4; ++i) {
    tracking::DisplacementCentroid c;
    c.position = Eigen::Vector3d(3.25 * i, -1.5, 0.875).cast<float>().cast<double>();
    c.covariance = randomShape(rng).cast<float>().cast<double>();
    c.point_count = static_cast<std::size_t>(10 + i);
    f.centroids.push_back(c);
  }
  f.centroids[3].covariance = Eigen::Vector3d(0.25, 0.5, 0.0).asDiagonal();
  return f;
}

TEST(ProtoConvert, CentroidFrameRoundTripIsExactThroughTheWire) {
  const tracking::CentroidFrame f = sampleCentroidFrame();
  v1::CentroidFrame parsed;
  ASSERT_TRUE(parsed.ParseFromString(toProto(f).SerializeAsString()));
  const auto back = fromProto(parsed);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->edge, f.edge);
  EXPECT_EQ(back->epoch, f.epoch);
  EXPECT_EQ(back->time_ns, f.time_ns);
  EXPECT_EQ(back->sensor_position, f.sensor_position);
  ASSERT_EQ(back->centroids.size(), f.centroids.size());
  for (std::size_t i = 0; i < f.centroids.size(); ++i) {
    EXPECT_EQ(back->centroids[i].position, f.centroids[i].position) << i;
    EXPECT_EQ(back->centroids[i].covariance, f.centroids[i].covariance) << i;
    EXPECT_EQ(back->centroids[i].point_count, f.centroids[i].point_count) << i;
  }
  // An edge that saw nothing move sends an empty frame: valid.
  tracking::CentroidFrame empty = f;
  empty.centroids.clear();
  EXPECT_TRUE(fromProto(toProto(empty)).ok());
}

TEST(ProtoConvert, CentroidFramesWithBadSizesOrValuesAreRejectedNamingTheField) {
  const v1::CentroidFrame good = toProto(sampleCentroidFrame());
  const auto rejected = [](const v1::CentroidFrame& m, const std::string& phrase) {
    const auto r = fromProto(m);
    ASSERT_FALSE(r.ok()) << "accepted, expected: " << phrase;
    EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(r.error().message.find(phrase), std::string::npos) << r.error().message;
  };
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  v1::CentroidFrame m = good;
  m.set_edge("");
  rejected(m, "edge '' is not a node name");
  m = good;
  m.mutable_centroids(1)->add_position(1.0F);
  rejected(m, "centroids[1]: position has 4 values, expected 3");
  m = good;
  m.mutable_centroids(2)->mutable_covariance()->RemoveLast();
  rejected(m, "centroids[2]: covariance has 5 values, expected 6");
  m = good;
  m.mutable_centroids(0)->set_position(2, nan);
  rejected(m, "centroids[0]: position must be finite");
  m = good;
  m.mutable_centroids(0)->set_position(0, 2e6F);
  rejected(m, "centroids[0]: position must be finite, within 1e6 m");
  m = good;
  m.mutable_centroids(3)->set_covariance(5, inf);
  rejected(m, "centroids[3]: covariance is not finite");
  m = good;
  m.mutable_centroids(3)->set_covariance(0, -0.25F);  // a negative variance
  rejected(m, "centroids[3]: covariance is not positive semi-definite");
  m = good;
  m.mutable_centroids(3)->set_covariance(1, 1.0F);  // xy beyond sqrt(xx yy)
  rejected(m, "centroids[3]: covariance is not positive semi-definite");
  m = good;
  m.mutable_centroids(3)->set_covariance(3, 1e9F);
  rejected(m, "centroids[3]: covariance has a variance above 1e8");
  m = good;
  m.mutable_centroids(1)->set_point_count(1);
  rejected(m, "centroids[1]: point_count 1");
  m = good;
  m.mutable_sensor_position()->set_y(std::numeric_limits<double>::infinity());
  rejected(m, "sensor_position must be finite");
  m = good;
  for (int i = 0; i < kMaxCentroidsPerFrame; ++i) *m.add_centroids() = good.centroids(0);
  const auto too_many = fromProto(m);
  ASSERT_FALSE(too_many.ok());
  EXPECT_EQ(too_many.error().code, ErrorCode::kResourceExhausted) << "a bound, not a broken frame";
  EXPECT_NE(too_many.error().message.find("centroids, more than " + std::to_string(kMaxCentroidsPerFrame)), std::string::npos)
      << too_many.error().message;
}

TEST(ProtoConvert, ATracksHeadingTravelsWhenItHasOneAndIsRefusedOutOfRange) {
  tracking::Track track;
  track.id = 7;
  track.label = "car";
  track.state = tracking::TrackState::kConfirmed;
  track.position = {3.0, -4.0};
  track.covariance = Eigen::Matrix2d::Identity();
  const auto without = fromProto(toProto(track));
  ASSERT_TRUE(without.ok()) << without.error().message;
  EXPECT_FALSE(without->heading_rad.has_value()) << "a person's track has none, and none is sent";
  EXPECT_FALSE(toProto(track).has_heading());

  track.heading_rad = -3.0;
  const auto with = fromProto(toProto(track));
  ASSERT_TRUE(with.ok()) << with.error().message;
  ASSERT_TRUE(with->heading_rad.has_value());
  EXPECT_EQ(*with->heading_rad, -3.0);

  for (const double bad : {4.0, -3.5, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    v1::Track wire = toProto(track);
    wire.set_heading(bad);
    const auto refused = fromProto(wire);
    ASSERT_FALSE(refused.ok()) << bad;
    EXPECT_NE(refused.error().message.find("track 7: heading"), std::string::npos) << refused.error().message;
  }
}

}  // namespace
}  // namespace fogmap
