#include "services/common/proto_convert.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>

#include <Eigen/Geometry>
#include <google/protobuf/descriptor.h>
#include <google/protobuf/unknown_field_set.h>

namespace fogmap {
namespace {

// Symmetric positive definite, and exactly symmetric as withAura produces them (the wire carries
// the upper triangle only). In double precision: see roundedToFloat.
Eigen::Matrix3d randomShape(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> axis(0.1, 3.0);
  std::normal_distribution<double> normal;
  const Eigen::Matrix3d r =
      Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized().toRotationMatrix();
  const Eigen::Vector3d semi(axis(rng), axis(rng), axis(rng));
  const Eigen::Matrix3d m = r * semi.cwiseAbs2().asDiagonal() * r.transpose();
  return 0.5 * (m + m.transpose());
}

// The wire carries centres and shapes as float32: a round trip is exact for geometry whose values
// are floats, and rounds every other value to the nearest float once.
enum class Geometry { kFloat, kDouble };

// The ellipsoid with every centre and shape value rounded to the nearest float (element by
// element, so an exactly symmetric shape stays exactly symmetric).
Ellipsoid roundedToFloat(Ellipsoid e) {
  e.center = e.center.cast<float>().cast<double>();
  e.shape = e.shape.cast<float>().cast<double>();
  return e;
}

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
              std::uint64_t epoch = kSampleEpoch) {
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

MapMessage sampleMapMessage() {
  std::mt19937_64 rng(11);
  return {sampleHeader(), randomMap(rng, 9)};
}

v1::Map sampleProtoMap() { return toProto(sampleMapMessage()); }

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

// ---- round trips -----------------------------------------------------------------------------

// Float geometry (randomMap's default) round-trips exactly, ids with and without a frame on the
// wire included; double geometry is rounded (DoubleGeometryIsRoundedToFloatOnceThenRoundTripsExactly).
TEST(ProtoConvert, MapRoundTripIsExact) {
  std::mt19937_64 rng(1);
  for (int trial = 0; trial < 50; ++trial) {
    const MapMessage m{sampleHeader(), randomMap(rng, trial)};
    const auto back = fromProto(toProto(m));
    ASSERT_TRUE(back.ok()) << back.error().message;
    ASSERT_EQ(*back, m) << "trial " << trial;
  }
}

TEST(ProtoConvert, MapRoundTripSurvivesSerialisation) {
  const MapMessage m = sampleMapMessage();
  const std::string bytes = toProto(m).SerializeAsString();
  v1::Map parsed;
  ASSERT_TRUE(parsed.ParseFromString(bytes));
  const auto back = fromProto(parsed);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(*back, m);
}

TEST(ProtoConvert, DoubleGeometryIsRoundedToFloatOnceThenRoundTripsExactly) {
  std::mt19937_64 rng(6);
  const MapMessage m{sampleHeader(), randomMap(rng, 20, Geometry::kDouble)};
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
  g.map = randomMap(rng, 15, Geometry::kDouble);
  const auto g_once = fromProto(toProto(g));
  ASSERT_TRUE(g_once.ok()) << g_once.error().message;
  EXPECT_NE(g_once->map, g.map);
  const auto g_twice = fromProto(toProto(*g_once));
  ASSERT_TRUE(g_twice.ok()) << g_twice.error().message;
  EXPECT_EQ(*g_twice, *g_once);
}

// The wire id of the ellipsoid (node, index) in `objects`; fails the test when there is none.
template <class Objects>
const v1::EllipsoidId& wireId(const Objects& objects, std::uint32_t node, std::uint32_t index) {
  for (const auto& o : objects) {
    for (const auto& e : o.ellipsoids()) {
      if (e.id().node() == node && e.id().index() == index) return e.id();
    }
  }
  ADD_FAILURE() << "no ellipsoid " << node << "/" << index << " on the wire";
  return v1::EllipsoidId::default_instance();
}

Ellipsoid ballAt(const EllipsoidId& id, double x) {
  Ellipsoid e;
  e.id = id;
  e.center = {x, 0.5, -1.25};
  e.shape = Eigen::Matrix3d::Identity() * 0.25;
  e.point_count = 3;
  return e;
}

TEST(ProtoConvert, FrameIsLeftOutWhenItIsTheEpoch) {
  const std::uint64_t epoch = 42;
  MapMessage m;
  m.header.node = 9;
  m.header.epoch = epoch;
  m.map = localMap({ballAt({3, epoch, 0}, 0.0), ballAt({3, epoch - 1, 1}, 4.0), ballAt({4, 0, 2}, 8.0),
                    ballAt({5, epoch + 1, 0}, 12.0)});
  const v1::Map wire = toProto(m);
  EXPECT_FALSE(wireId(wire.objects(), 3, 0).has_frame()) << "frame == epoch is left out";
  ASSERT_TRUE(wireId(wire.objects(), 3, 1).has_frame());
  EXPECT_EQ(wireId(wire.objects(), 3, 1).frame(), epoch - 1);
  ASSERT_TRUE(wireId(wire.objects(), 4, 2).has_frame()) << "frame 0 is a value, not absence";
  EXPECT_EQ(wireId(wire.objects(), 4, 2).frame(), 0U);
  ASSERT_TRUE(wireId(wire.objects(), 5, 0).has_frame());
  EXPECT_EQ(wireId(wire.objects(), 5, 0).frame(), epoch + 1);

  // Decoded: an absent frame is the epoch, a present one is kept (also through bytes).
  v1::Map parsed;
  ASSERT_TRUE(parsed.ParseFromString(wire.SerializeAsString()));
  EXPECT_FALSE(wireId(parsed.objects(), 3, 0).has_frame());
  EXPECT_TRUE(wireId(parsed.objects(), 4, 2).has_frame());
  const auto back = fromProto(parsed);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(*back, m);

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

  // An explicit frame equal to the epoch (an encoder that always sends it) decodes the same.
  v1::Map explicit_frame = wire;
  for (auto& o : *explicit_frame.mutable_objects()) {
    for (auto& e : *o.mutable_ellipsoids()) {
      if (!e.id().has_frame()) e.mutable_id()->set_frame(epoch);
    }
  }
  const auto explicit_back = fromProto(explicit_frame);
  ASSERT_TRUE(explicit_back.ok()) << explicit_back.error().message;
  EXPECT_EQ(*explicit_back, m);

  // Global maps follow the same rule.
  GlobalMapMessage g;
  g.header = m.header;
  g.map = m.map;
  const v1::GlobalMap global_wire = toProto(g);
  EXPECT_FALSE(wireId(global_wire.objects(), 3, 0).has_frame());
  ASSERT_TRUE(wireId(global_wire.objects(), 3, 1).has_frame());
  EXPECT_EQ(wireId(global_wire.objects(), 3, 1).frame(), epoch - 1);
  const auto global_back = fromProto(global_wire);
  ASSERT_TRUE(global_back.ok()) << global_back.error().message;
  EXPECT_EQ(*global_back, g);
}

TEST(ProtoConvert, WireObjectsCarryNoBoxAndBoxesAreRecomputed) {
  // The box is gone from the schema; its field number is reserved.
  const google::protobuf::Descriptor* object_type = v1::MapObject::descriptor();
  EXPECT_EQ(object_type->field_count(), 1);
  EXPECT_EQ(object_type->FindFieldByName("box"), nullptr);
  EXPECT_EQ(object_type->FindFieldByNumber(2), nullptr);
  EXPECT_TRUE(object_type->IsReservedNumber(2));

  const MapMessage m = sampleMapMessage();
  v1::Map wire = toProto(m);
  for (const auto& o : wire.objects()) {
    EXPECT_TRUE(o.GetReflection()->GetUnknownFields(o).empty()) << "nothing but ellipsoids is sent";
  }
  // A box from an old sender (field 2) is skipped as an unknown field, never trusted.
  v1::Box bogus;
  bogus.mutable_min()->set_x(-1e9);
  bogus.mutable_max()->set_x(-1e9 + 1);
  v1::MapObject* first = wire.mutable_objects(0);
  first->GetReflection()->MutableUnknownFields(first)->AddLengthDelimited(2, bogus.SerializeAsString());
  v1::Map parsed;
  ASSERT_TRUE(parsed.ParseFromString(wire.SerializeAsString()));

  const auto back = fromProto(parsed);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(*back, m);
  ASSERT_FALSE(back->map.objects.empty());
  for (std::size_t o = 0; o < back->map.objects.size(); ++o) {
    const MapObject& object = back->map.objects[o];
    EXPECT_FALSE(object.box.empty());
    EXPECT_EQ(object.box, unionOfDelimitingBoxes(object.ellipsoids)) << "object " << o;
  }
}

TEST(ProtoConvert, MapIsRebuiltInCanonicalForm) {
  const MapMessage m = sampleMapMessage();
  v1::Map wire = toProto(m);
  // Reverse the object order and the ellipsoids within each object.
  std::reverse(wire.mutable_objects()->begin(), wire.mutable_objects()->end());
  for (auto& o : *wire.mutable_objects()) std::reverse(o.mutable_ellipsoids()->begin(), o.mutable_ellipsoids()->end());
  // Unsorted node lists come back sorted.
  wire.mutable_header()->clear_contributing_nodes();
  for (const std::uint32_t n : {5U, 1U, 2U}) wire.mutable_header()->add_contributing_nodes(n);
  const auto back = fromProto(wire);
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(*back, m);
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

TEST(ProtoConvert, GlobalMapRoundTripIsExact) {
  std::mt19937_64 rng(4);
  for (const Mode mode : {Mode::kMadc, Mode::kBaseline, Mode::kExt}) {
    GlobalMapMessage g;
    g.header = sampleHeader();
    g.map = randomMap(rng, 12);
    g.mode = mode;
    g.published_time_ns = 1700000000999999999LL;
    g.merge_seconds = 0.000123456789;
    g.pairs_all = 1234;
    g.pairs_tested = 56;
    g.point_labels = {{1, {0, 0, -1, 2}}, {4, {}}, {9, {std::numeric_limits<std::int32_t>::max()}}};
    const auto back = fromProto(toProto(g));
    ASSERT_TRUE(back.ok()) << back.error().message;
    EXPECT_EQ(*back, g) << modeName(mode);
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

// ---- malformed maps --------------------------------------------------------------------------

TEST(ProtoConvert, RejectsEllipsoidWithoutId) {
  v1::Map wire = sampleProtoMap();
  wire.mutable_objects(2)->mutable_ellipsoids(0)->clear_id();
  expectRejected(fromProto(wire), {"object 2", "ellipsoid 0", "id"});
}

TEST(ProtoConvert, RejectsEllipsoidWithoutCenter) {
  v1::Map wire = sampleProtoMap();
  wire.mutable_objects(1)->mutable_ellipsoids(1)->clear_center();
  expectRejected(fromProto(wire), {"object 1", "ellipsoid 1", "center"});
}

TEST(ProtoConvert, RejectsCenterWithoutThreeValues) {
  for (const int n : {0, 2, 4}) {
    v1::Map wire = sampleProtoMap();
    auto* center = wire.mutable_objects(1)->mutable_ellipsoids(1)->mutable_center();
    center->Clear();
    for (int i = 0; i < n; ++i) center->Add(1.0F);
    expectRejected(fromProto(wire), {"object 1", "ellipsoid 1", "center", std::to_string(n) + " values"});
  }
}

TEST(ProtoConvert, RejectsShapeWithoutSixValues) {
  for (const int n : {0, 5, 7, 9}) {
    v1::Map wire = sampleProtoMap();
    auto* shape = wire.mutable_objects(3)->mutable_ellipsoids(0)->mutable_shape();
    shape->Clear();
    for (int i = 0; i < n; ++i) shape->Add(1.0F);
    expectRejected(fromProto(wire), {"object 3", "ellipsoid 0", "shape", std::to_string(n) + " values"});
  }
}

TEST(ProtoConvert, RejectsNonFiniteNumbers) {
  for (const float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity()}) {
    v1::Map wire = sampleProtoMap();
    wire.mutable_objects(4)->mutable_ellipsoids(0)->set_center(1, bad);
    expectRejected(fromProto(wire), {"object 4", "center", "finite"});

    wire = sampleProtoMap();
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
    v1::Map wire = sampleProtoMap();
    auto* shape = wire.mutable_objects(5)->mutable_ellipsoids(0)->mutable_shape();
    for (int i = 0; i < 6; ++i) shape->Set(i, values[static_cast<std::size_t>(i)]);
    expectRejected(fromProto(wire), {"object 5", "ellipsoid 0", "positive definite"});
  }
}

TEST(ProtoConvert, RejectsEmptyObject) {
  v1::Map wire = sampleProtoMap();
  wire.add_objects();
  expectRejected(fromProto(wire), {"object " + std::to_string(wire.objects_size() - 1), "no ellipsoids"});
}

TEST(ProtoConvert, RejectsDuplicateEllipsoidIds) {
  v1::Map wire = sampleProtoMap();
  *wire.mutable_objects(6)->add_ellipsoids() = wire.objects(2).ellipsoids(0);
  expectRejected(fromProto(wire), {"duplicate ellipsoid id", "objects 2 and 6"});
}

TEST(ProtoConvert, RejectsMalformedGlobalMapObjects) {
  GlobalMapMessage g;
  std::mt19937_64 rng(5);
  g.map = randomMap(rng, 4);
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

}  // namespace
}  // namespace fogmap
