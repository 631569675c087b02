#include "services/common/proto_convert.hpp"

#include <algorithm>
#include <cassert>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <google/protobuf/io/coded_stream.h>

#include "common/base/little_endian.hpp"
#include "common/config/topology.hpp"
#include "common/geometry/compact_ellipsoid.hpp"
#include "common/geometry/compact_view.hpp"

namespace fogmap {
namespace {

static_assert(sizeof(float) == 4 && std::numeric_limits<float>::is_iec559,
              "the wire carries IEEE-754 binary32 points");

constexpr std::size_t kBytesPerPoint = 12;
constexpr std::size_t kBytesPerLabel = 4;

std::string packLabels(const std::vector<std::int32_t>& labels) {
  std::string out;
  out.reserve(labels.size() * kBytesPerLabel);
  for (const auto l : labels) putU32(out, static_cast<std::uint32_t>(l));
  return out;
}

std::vector<std::int32_t> unpackLabels(const std::string& bytes) {
  std::vector<std::int32_t> labels(bytes.size() / kBytesPerLabel);
  for (std::size_t i = 0; i < labels.size(); ++i) {
    labels[i] = static_cast<std::int32_t>(getU32(bytes, i * kBytesPerLabel));
  }
  return labels;
}

// ---- domain -> wire --------------------------------------------------------------------------

void toProto(const MapHeader& h, v1::MapHeader* out) {
  out->set_node(h.node);
  out->set_epoch(h.epoch);
  out->set_sensor_time_ns(h.sensor_time_ns);
  for (const auto n : h.contributing_nodes) out->add_contributing_nodes(n);
  for (const auto n : h.missing_nodes) out->add_missing_nodes(n);
  for (const auto n : h.failed_nodes) out->add_failed_nodes(n);
  out->set_dropped_uploads(h.dropped_uploads);
}

// The frame is left out when it is the map's epoch (the usual case).
void toProto(const EllipsoidId& id, std::uint64_t epoch, v1::EllipsoidId* out) {
  out->set_node(id.node);
  if (id.frame != epoch) out->set_frame(id.frame);
  out->set_index(id.index);
}

void toProto(const Ellipsoid& e, std::uint64_t epoch, v1::Ellipsoid* out) {
  toProto(e.id, epoch, out->mutable_id());
  for (int k = 0; k < 3; ++k) out->add_center(static_cast<float>(e.center[k]));
  const Eigen::Matrix3d& m = e.shape;
  for (const double v : {m(0, 0), m(0, 1), m(0, 2), m(1, 1), m(1, 2), m(2, 2)}) out->add_shape(static_cast<float>(v));
  out->set_point_count(e.point_count);
  if (e.box) {
    v1::OrientedBox* box = out->mutable_box();
    for (int k = 0; k < 3; ++k) box->add_centre(static_cast<float>(e.box->centre[k]));
    box->set_length(static_cast<float>(e.box->length));
    box->set_width(static_cast<float>(e.box->width));
    box->set_height(static_cast<float>(e.box->height));
    box->set_yaw(static_cast<float>(e.box->yaw));
    box->set_anchor(static_cast<std::uint32_t>(e.box->anchor));
  }
  if (e.label) {
    out->mutable_label()->set_object_class(static_cast<std::uint32_t>(e.label->object_class));
    out->mutable_label()->set_confidence(static_cast<float>(e.label->confidence));
  }
}

using WireObjects = google::protobuf::RepeatedPtrField<v1::MapObject>;
using WireBlocks = google::protobuf::RepeatedPtrField<v1::EllipsoidBlock>;

// The records of one (node, frame), before they go on the wire.
struct PackedBlock {
  std::uint32_t node = 0;
  std::uint64_t frame = 0;
  CompactOrigin origin;
  std::string records;
  std::string views;                   // one entry per record (compact_view.hpp)
  bool any_view = false;               // else `views` stays off the wire
  std::vector<std::size_t> object_of;  // the map object of each record
  std::vector<std::uint32_t> indices;  // the ellipsoid index of each record
  bool own_objects = true;             // every record is the only ellipsoid of its object
};

// The first index when the records' indices run first, first + 1, ... and there are at least two
// (one record saves 2 bytes and first_index costs 2).
std::optional<std::uint32_t> consecutiveFrom(const std::vector<std::uint32_t>& indices) {
  if (indices.size() < 2) return std::nullopt;
  for (std::size_t k = 1; k < indices.size(); ++k) {
    if (indices[k] != indices[0] + k) return std::nullopt;
  }
  return indices[0];
}

// The records without their last 2 bytes (the index) each.
std::string withoutIndices(const std::string& records) {
  std::string out;
  out.reserve(records.size() / kCompactEllipsoidBytes * kCompactRecordBytesWithoutIndex);
  for (std::size_t at = 0; at < records.size(); at += kCompactEllipsoidBytes) {
    out.append(records, at, kCompactRecordBytesWithoutIndex);
  }
  return out;
}

// Packs every ellipsoid that fits into a block of its (node, frame), whose origin is the common
// frame's (left off the wire: 9 bytes less a block) when every centre of the (node, frame) is within
// a record's reach of it (+-327.67 m per axis), else the first packed centre in canonical
// order (rounded to cm, which a decoded map's centre already is, so the origin survives a decode and
// re-encode); an ellipsoid beyond reach of the newest 4 blocks of its (node, frame) opens another
// around its centre. Only ellipsoids no record holds (axes, point count, index) go exactly in their
// objects. A block whose records are all objects of
// their own leaves object_step out, and those objects are not listed in `objects`; nor are the
// objects whose ellipsoids are all records (`packed_objects` counts them).
void toProto(const Map& map, std::uint64_t epoch, EllipsoidWire wire, WireObjects* objects, WireBlocks* blocks,
             std::uint32_t* packed_objects) {
  const CompactOrigin common_origin{0, 0, 0};
  std::map<std::pair<std::uint32_t, std::uint64_t>, bool> at_common_origin;
  for (const MapObject& object : map.objects) {
    for (const Ellipsoid& e : object.ellipsoids) {
      auto [it, fresh] = at_common_origin.emplace(std::make_pair(e.id.node, e.id.frame), true);
      it->second = it->second && compactCentreFits(e.center, common_origin);
    }
  }
  std::vector<PackedBlock> packed;
  std::map<std::pair<std::uint32_t, std::uint64_t>, std::vector<std::size_t>> blocks_of;
  constexpr std::size_t kBlocksTried = 4;  // the newest blocks of a (node, frame) an ellipsoid may join
  std::vector<std::vector<const Ellipsoid*>> exact(map.objects.size());
  std::vector<std::size_t> lone_block(map.objects.size(), SIZE_MAX);  // a one-ellipsoid object's block
  for (std::size_t o = 0; o < map.objects.size(); ++o) {
    const auto& ellipsoids = map.objects[o].ellipsoids;
    const bool lone = ellipsoids.size() == 1;
    for (const Ellipsoid& e : ellipsoids) {
      if (wire == EllipsoidWire::kExact || !viewFitsCompact(e)) {
        exact[o].push_back(&e);
        continue;
      }
      const auto key = std::make_pair(e.id.node, e.id.frame);
      std::vector<std::size_t>& candidates = blocks_of[key];  // this (node, frame)'s blocks, newest last
      std::size_t chosen = SIZE_MAX;
      for (std::size_t t = 0; t < std::min(candidates.size(), kBlocksTried) && chosen == SIZE_MAX; ++t) {
        const std::size_t b = candidates[candidates.size() - 1 - t];
        if (appendCompact(e, packed[b].origin, packed[b].records)) chosen = b;
      }
      if (chosen == SIZE_MAX) {
        // A block of its own around it, when the others' origins are too far (a relay's map may
        // hold a node's ellipsoids hundreds of metres apart): a record still, never float32.
        const CompactOrigin origin =
            candidates.empty() && at_common_origin.at(key) ? common_origin : compactOriginNear(e.center);
        PackedBlock fresh{e.id.node, e.id.frame, origin, {}, {}, false, {}, {}, true};
        if (!appendCompact(e, fresh.origin, fresh.records)) {
          exact[o].push_back(&e);
          continue;
        }
        chosen = packed.size();
        candidates.push_back(chosen);
        packed.push_back(std::move(fresh));
      }
      PackedBlock& block = packed[chosen];
      [[maybe_unused]] const bool view_written = appendCompactView(e, block.views);
      assert(view_written);  // viewFitsCompact(e) was checked above
      block.any_view = block.any_view || hasView(e);
      block.object_of.push_back(o);
      block.indices.push_back(e.id.index);
      block.own_objects = block.own_objects && lone;
      if (lone) lone_block[o] = chosen;
    }
  }

  // Objects with exact ellipsoids are listed first; objects with records only follow, unlisted.
  std::vector<std::uint32_t> wire_index(map.objects.size(), 0);
  std::vector<std::size_t> unlisted;
  for (std::size_t o = 0; o < map.objects.size(); ++o) {
    if (exact[o].empty()) {
      if (lone_block[o] == SIZE_MAX || !packed[lone_block[o]].own_objects) unlisted.push_back(o);
      continue;
    }
    wire_index[o] = static_cast<std::uint32_t>(objects->size());
    v1::MapObject* object = objects->Add();
    object->mutable_ellipsoids()->Reserve(static_cast<int>(exact[o].size()));
    for (const Ellipsoid* e : exact[o]) toProto(*e, epoch, object->add_ellipsoids());
  }
  for (std::size_t k = 0; k < unlisted.size(); ++k) {
    wire_index[unlisted[k]] = static_cast<std::uint32_t>(static_cast<std::size_t>(objects->size()) + k);
  }
  *packed_objects = static_cast<std::uint32_t>(unlisted.size());
  blocks->Reserve(static_cast<int>(packed.size()));
  for (PackedBlock& block : packed) {
    v1::EllipsoidBlock* out = blocks->Add();
    out->set_node(block.node);
    if (block.frame != epoch) out->set_frame(block.frame);
    out->set_origin_x_cm(block.origin.x_cm);
    out->set_origin_y_cm(block.origin.y_cm);
    out->set_origin_z_cm(block.origin.z_cm);
    if (const auto first = consecutiveFrom(block.indices)) {
      out->set_first_index(*first);
      out->set_records(withoutIndices(block.records));
    } else {
      out->set_records(std::move(block.records));
    }
    if (block.any_view) out->set_views(std::move(block.views));
    if (block.own_objects) continue;
    out->mutable_object_step()->Reserve(static_cast<int>(block.object_of.size()));
    std::int64_t previous = 0;
    for (const std::size_t o : block.object_of) {
      const std::int64_t index = wire_index[o];
      out->add_object_step(static_cast<std::int32_t>(index - previous));
      previous = index;
    }
  }
}

// ---- wire -> domain --------------------------------------------------------------------------

std::vector<std::uint32_t> sortedNodes(const google::protobuf::RepeatedField<std::uint32_t>& nodes) {
  std::vector<std::uint32_t> out(nodes.begin(), nodes.end());
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

MapHeader fromProto(const v1::MapHeader& h) {
  MapHeader out;
  out.node = h.node();
  out.epoch = h.epoch();
  out.sensor_time_ns = h.sensor_time_ns();
  out.contributing_nodes = sortedNodes(h.contributing_nodes());
  out.missing_nodes = sortedNodes(h.missing_nodes());
  out.failed_nodes = sortedNodes(h.failed_nodes());
  out.dropped_uploads = h.dropped_uploads();
  return out;
}

std::string ellipsoidLabel(const std::string& where, int object, int ellipsoid) {
  return where + ": object " + std::to_string(object) + " ellipsoid " + std::to_string(ellipsoid);
}

Expected<Ellipsoid> fromProto(const v1::Ellipsoid& e, std::uint64_t epoch, const std::string& label) {
  if (!e.has_id()) return invalidArgument(label + ": missing id");
  if (e.center_size() != 3) {
    return invalidArgument(label + ": center has " + std::to_string(e.center_size()) + " values, expected 3 (x y z)");
  }
  if (e.shape_size() != 6) {
    return invalidArgument(label + ": shape has " + std::to_string(e.shape_size()) +
                           " values, expected 6 (upper triangle xx xy xz yy yz zz)");
  }
  Ellipsoid out;
  out.id = {e.id().node(), e.id().has_frame() ? e.id().frame() : epoch, e.id().index()};
  out.center = {e.center(0), e.center(1), e.center(2)};
  if (!out.center.allFinite()) return invalidArgument(label + ": center is not finite");
  const auto& s = e.shape();
  out.shape << s[0], s[1], s[2],  //
      s[1], s[3], s[4],           //
      s[2], s[4], s[5];
  if (!out.shape.allFinite()) return invalidArgument(label + ": shape is not finite");
  // Symmetric by construction; positive definite is what the intersection test relies on.
  if (out.shape.diagonal().minCoeff() <= 0.0 ||
      Eigen::LLT<Eigen::Matrix3d>(out.shape).info() != Eigen::Success) {
    return invalidArgument(label + ": shape is not positive definite");
  }
  out.point_count = e.point_count();
  if (e.has_box()) {
    const v1::OrientedBox& b = e.box();
    if (b.centre_size() != 3) {
      return invalidArgument(label + ": box centre has " + std::to_string(b.centre_size()) + " values, expected 3 (x y z)");
    }
    if (b.anchor() > static_cast<std::uint32_t>(BoxAnchor::kRearRight)) {
      return invalidArgument(label + ": box anchor " + std::to_string(b.anchor()) + " is not one of 0 to 8");
    }
    // Values (finite, sizes, yaw) are the admission's to judge: checkMapBounds counts bad_box.
    out.box = OrientedBox{{b.centre(0), b.centre(1), b.centre(2)}, b.length(), b.width(), b.height(), b.yaw(),
                          static_cast<BoxAnchor>(b.anchor())};
  }
  if (e.has_label()) {
    if (e.label().object_class() >= kObjectClassCount) {
      return invalidArgument(label + ": object_class " + std::to_string(e.label().object_class()) + " is not one of 0 to " +
                             std::to_string(kObjectClassCount - 1));
    }
    out.label = ObjectLabel{static_cast<ObjectClass>(e.label().object_class()), e.label().confidence()};
  }
  return out;
}

// Where an ellipsoid was in the message: exact (object, ellipsoid) or packed (block, record).
struct WirePlace {
  bool packed = false;
  int group = 0;          // the object, or the block
  std::size_t item = 0;   // the ellipsoid, or the record
  std::string text() const {
    return packed ? "blocks[" + std::to_string(group) + "] record " + std::to_string(item)
                  : "object " + std::to_string(group) + " ellipsoid " + std::to_string(item);
  }
};

std::size_t recordBytesOf(const v1::EllipsoidBlock& block) {
  return compactRecordBytes(block.has_first_index() ? CompactIndex::kImplicit : CompactIndex::kInRecord);
}

std::string recordLabel(const std::string& where, int block, std::size_t record) {
  return where + ": " + WirePlace{true, block, record}.text();
}

// The objects of a Map or GlobalMap: exact ellipsoids in `objects`, records in `blocks` attached to
// the object their object_step names (listed, or one of the `packed_objects` numbered after them),
// or objects of their own (numbered after both).
Expected<Map> fromProto(const WireObjects& objects, const WireBlocks& blocks, std::uint32_t packed_objects,
                        std::uint64_t epoch, const std::string& where) {
  std::vector<Ellipsoid> ellipsoids;
  std::vector<std::size_t> object_of;
  std::vector<WirePlace> places;
  // Every object has an ellipsoid: more unlisted objects than records is malformed (and checked
  // before anything is sized by it).
  std::size_t records_in_blocks = 0;
  for (int b = 0; b < blocks.size(); ++b) {
    const std::size_t bytes = blocks[b].records().size();
    const std::size_t size = recordBytesOf(blocks[b]);
    if (bytes % size != 0) {
      return invalidArgument(where + ": blocks[" + std::to_string(b) + "]: records has " + std::to_string(bytes) +
                             " bytes, not a multiple of " + std::to_string(size) + " (one compact ellipsoid each" +
                             (blocks[b].has_first_index() ? ", without its index: the block has first_index)" : ")"));
    }
    const std::size_t count = bytes / size;
    if (blocks[b].has_first_index() && count > 0 &&
        count - 1 > std::numeric_limits<std::uint32_t>::max() - blocks[b].first_index()) {
      return invalidArgument(where + ": blocks[" + std::to_string(b) + "]: first_index " +
                             std::to_string(blocks[b].first_index()) + " and " + std::to_string(count) +
                             " records run past the last ellipsoid index, 2^32 - 1");
    }
    records_in_blocks += count;
  }
  if (packed_objects > records_in_blocks) {
    return invalidArgument(where + ": packed_objects " + std::to_string(packed_objects) + " exceeds the " +
                           std::to_string(records_in_blocks) + " records of its blocks (each needs one)");
  }
  const std::size_t listed = static_cast<std::size_t>(objects.size()) + packed_objects;
  std::vector<std::size_t> members(listed, 0);
  for (int o = 0; o < objects.size(); ++o) {
    const v1::MapObject& object = objects[o];
    for (int k = 0; k < object.ellipsoids_size(); ++k) {
      auto e = fromProto(object.ellipsoids(k), epoch, ellipsoidLabel(where, o, k));
      if (!e) return e.error();
      ellipsoids.push_back(std::move(e).value());
      object_of.push_back(static_cast<std::size_t>(o));
      places.push_back({false, o, static_cast<std::size_t>(k)});
      ++members[static_cast<std::size_t>(o)];
    }
  }
  std::size_t own_object = listed;  // the next object of its own
  for (int b = 0; b < blocks.size(); ++b) {
    const v1::EllipsoidBlock& block = blocks[b];
    const std::string_view records = block.records();
    const std::string label = where + ": blocks[" + std::to_string(b) + "]";
    const std::size_t record_bytes = recordBytesOf(block);
    const std::size_t count = records.size() / record_bytes;
    const auto listed_objects = static_cast<std::size_t>(block.object_step_size());
    if (listed_objects != 0 && listed_objects != count) {
      return invalidArgument(label + ": object_step has " + std::to_string(listed_objects) + " entries for " +
                             std::to_string(count) +
                             " records (one per record, or none when each is an object of its own)");
    }
    std::int64_t step_sum = 0;
    const CompactOrigin origin{block.origin_x_cm(), block.origin_y_cm(), block.origin_z_cm()};
    const std::uint64_t frame = block.has_frame() ? block.frame() : epoch;
    const std::string_view views = block.views();
    std::size_t view_at = 0;
    for (std::size_t r = 0; r < count; ++r) {
      std::size_t object = own_object;
      if (listed_objects == 0) {
        ++own_object;
      } else {
        step_sum += block.object_step(static_cast<int>(r));  // int32 steps, < 2^32 records: no overflow
        if (step_sum < 0 || static_cast<std::uint64_t>(step_sum) >= listed) {
          return invalidArgument(recordLabel(where, b, r) + ": object_step names object " + std::to_string(step_sum) +
                                 ", out of range (the message has " + std::to_string(listed) +
                                 " objects: listed and packed_objects)");
        }
        object = static_cast<std::size_t>(step_sum);
        ++members[object];
      }
      const auto index = block.has_first_index()
                             ? std::optional<std::uint32_t>(block.first_index() + static_cast<std::uint32_t>(r))
                             : std::nullopt;
      auto e = decodeCompact(records.substr(r * record_bytes, record_bytes), origin, block.node(), frame, index);
      if (!e) return invalidArgument(recordLabel(where, b, r) + ": " + e.error().message);
      if (!views.empty()) {
        if (const Status read = readCompactView(views, view_at, *e); !read) {
          return invalidArgument(recordLabel(where, b, r) + ": " + read.error().message);
        }
      }
      ellipsoids.push_back(std::move(e).value());
      object_of.push_back(object);
      places.push_back({true, b, r});
    }
    if (view_at != views.size()) {
      return invalidArgument(label + ": views has " + std::to_string(views.size() - view_at) +
                             " bytes beyond its " + std::to_string(count) + " entries (one per record)");
    }
  }
  for (std::size_t o = 0; o < listed; ++o) {
    if (members[o] == 0) return invalidArgument(where + ": object " + std::to_string(o) + " has no ellipsoids");
  }
  // Canonical maps have unique ids; a duplicate would be merged with itself downstream.
  std::vector<std::size_t> order(ellipsoids.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return ellipsoids[a].id < ellipsoids[b].id || (ellipsoids[a].id == ellipsoids[b].id && a < b);
  });
  for (std::size_t i = 1; i < order.size(); ++i) {
    if (ellipsoids[order[i - 1]].id == ellipsoids[order[i]].id) {
      return invalidArgument(where + ": duplicate ellipsoid id " + toString(ellipsoids[order[i]].id) + " (" +
                             places[order[i - 1]].text() + " and " + places[order[i]].text() + ")");
    }
  }
  // Every listed object has an ellipsoid, so there are at most as many objects as ellipsoids.
  return mapFromGroups(ellipsoids, object_of);
}

std::optional<Mode> modeFromName(const std::string& name) {
  for (const Mode m : {Mode::kMadc, Mode::kBaseline, Mode::kExt}) {
    if (name == modeName(m)) return m;
  }
  return std::nullopt;
}

}  // namespace

void toProto(const Eigen::Vector3d& v, v1::Vec3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

Eigen::Vector3d fromProto(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

v1::Map toProto(const MapMessage& message, EllipsoidWire wire) {
  v1::Map out;
  toProto(message.header, out.mutable_header());
  std::uint32_t packed_objects = 0;
  toProto(message.map, message.header.epoch, wire, out.mutable_objects(), out.mutable_blocks(), &packed_objects);
  out.set_packed_objects(packed_objects);
  return out;
}

Expected<Map> throughGlobalWire(const Map& map) {
  GlobalMapMessage message;
  message.map = map;
  auto decoded = fromProto(toProto(message));
  if (!decoded) return decoded.error();
  return std::move(decoded->map);
}

v1::PointChunk toProto(const PointChunk& chunk) {
  v1::PointChunk out;
  toProto(chunk.header, out.mutable_header());
  out.set_chunk(chunk.chunk);
  out.set_chunk_count(chunk.chunk_count);
  out.set_first_point(chunk.first_point);
  out.set_total_points(chunk.total_points);
  std::string xyz;
  xyz.reserve(chunk.points.size() * kBytesPerPoint);
  for (const Point& p : chunk.points) {
    putFloat(xyz, p.x);
    putFloat(xyz, p.y);
    putFloat(xyz, p.z);
  }
  out.set_xyz(std::move(xyz));
  if (!chunk.labels.empty()) out.set_labels(packLabels(chunk.labels));
  return out;
}

v1::GlobalMap toProto(const GlobalMapMessage& message, EllipsoidWire wire) {
  v1::GlobalMap out;
  toProto(message.header, out.mutable_header());
  std::uint32_t packed_objects = 0;
  toProto(message.map, message.header.epoch, wire, out.mutable_objects(), out.mutable_blocks(), &packed_objects);
  out.set_packed_objects(packed_objects);
  out.set_mode(modeName(message.mode));
  out.set_published_time_ns(message.published_time_ns);
  out.set_merge_seconds(message.merge_seconds);
  out.set_pairs_all(message.pairs_all);
  out.set_pairs_tested(message.pairs_tested);
  out.set_revision(message.revision);
  out.set_late(message.late);
  for (const auto& nl : message.point_labels) {
    v1::NodeLabels* l = out.add_point_labels();
    l->set_node(nl.node);
    l->set_labels(packLabels(nl.labels));
  }
  return out;
}

v1::Geofence toProto(const Geofence& fence) {
  v1::Geofence out;
  out.set_name(fence.name);
  for (const auto& h : fence.half_spaces) {
    v1::HalfSpace* hs = out.add_half_spaces();
    toProto(h.normal, hs->mutable_normal());
    hs->set_offset(h.offset);
  }
  return out;
}

Expected<MapMessage> fromProto(const v1::Map& message) {
  auto map = fromProto(message.objects(), message.blocks(), message.packed_objects(), message.header().epoch(), "Map");
  if (!map) return map.error();
  return MapMessage{fromProto(message.header()), std::move(map).value()};
}

Expected<PointChunk> fromProto(const v1::PointChunk& chunk) {
  const std::string where = "PointChunk from node " + std::to_string(chunk.header().node());
  if (chunk.chunk_count() == 0) return invalidArgument(where + ": chunk_count is 0");
  if (chunk.chunk() >= chunk.chunk_count()) {
    return invalidArgument(where + ": chunk " + std::to_string(chunk.chunk()) + " is not below chunk_count " +
                           std::to_string(chunk.chunk_count()));
  }
  const std::string& xyz = chunk.xyz();
  if (xyz.size() % kBytesPerPoint != 0) {
    return invalidArgument(where + ": xyz has " + std::to_string(xyz.size()) +
                           " bytes, not a multiple of 12 (float32 x, y, z per point)");
  }
  const std::size_t count = xyz.size() / kBytesPerPoint;
  // 64-bit sum: a 32-bit first_point plus a count cannot overflow it.
  if (static_cast<std::uint64_t>(chunk.first_point()) + count > chunk.total_points()) {
    return invalidArgument(where + ": first_point " + std::to_string(chunk.first_point()) + " + " +
                           std::to_string(count) + " points exceeds total_points " +
                           std::to_string(chunk.total_points()));
  }
  if (!chunk.labels().empty() && chunk.labels().size() != count * kBytesPerLabel) {
    return invalidArgument(where + ": labels has " + std::to_string(chunk.labels().size()) + " bytes, expected " +
                           std::to_string(count * kBytesPerLabel) + " (int32 per point)");
  }
  PointChunk out;
  out.header = fromProto(chunk.header());
  out.chunk = chunk.chunk();
  out.chunk_count = chunk.chunk_count();
  out.first_point = chunk.first_point();
  out.total_points = chunk.total_points();
  out.points.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::size_t at = i * kBytesPerPoint;
    Point& q = out.points[i];
    q.x = getFloat(xyz, at);
    q.y = getFloat(xyz, at + 4);
    q.z = getFloat(xyz, at + 8);
    if (!std::isfinite(q.x) || !std::isfinite(q.y) || !std::isfinite(q.z)) {
      return invalidArgument(where + ": xyz point " + std::to_string(i) + " is not finite");
    }
  }
  out.labels = unpackLabels(chunk.labels());
  return out;
}

Expected<GlobalMapMessage> fromProto(const v1::GlobalMap& message) {
  GlobalMapMessage out;
  const auto mode = modeFromName(message.mode());
  if (!mode) {
    return invalidArgument("GlobalMap: mode '" + message.mode() + "' is unknown (expected madc, baseline or ext)");
  }
  out.mode = *mode;
  if (!std::isfinite(message.merge_seconds())) return invalidArgument("GlobalMap: merge_seconds is not finite");
  auto map = fromProto(message.objects(), message.blocks(), message.packed_objects(), message.header().epoch(),
                       "GlobalMap");
  if (!map) return map.error();
  out.header = fromProto(message.header());
  out.map = std::move(map).value();
  out.published_time_ns = message.published_time_ns();
  out.merge_seconds = message.merge_seconds();
  out.pairs_all = message.pairs_all();
  out.pairs_tested = message.pairs_tested();
  out.revision = message.revision();
  out.late = message.late();
  out.point_labels.reserve(static_cast<std::size_t>(message.point_labels_size()));
  for (int i = 0; i < message.point_labels_size(); ++i) {
    const v1::NodeLabels& nl = message.point_labels(i);
    if (nl.labels().size() % kBytesPerLabel != 0) {
      return invalidArgument("GlobalMap: point_labels " + std::to_string(i) + " (node " + std::to_string(nl.node()) +
                             ") has " + std::to_string(nl.labels().size()) +
                             " bytes, not a multiple of 4 (int32 per point)");
    }
    out.point_labels.push_back(NodeLabels{nl.node(), unpackLabels(nl.labels())});
  }
  return out;
}

Expected<Geofence> fromProto(const v1::Geofence& fence) {
  Geofence out;
  out.name = fence.name();
  out.half_spaces.reserve(static_cast<std::size_t>(fence.half_spaces_size()));
  for (int i = 0; i < fence.half_spaces_size(); ++i) {
    const v1::HalfSpace& h = fence.half_spaces(i);
    if (!h.has_normal()) {
      return invalidArgument("Geofence '" + out.name + "': half-space " + std::to_string(i) + " has no normal");
    }
    out.half_spaces.push_back(HalfSpace{fromProto(h.normal()), h.offset()});
  }
  if (auto status = validateGeofence(out); !status) return status.error();
  return out;
}

v1::Containment toProto(Containment containment) {
  switch (containment) {
    case Containment::kOutside: return v1::CONTAINMENT_OUTSIDE;
    case Containment::kCrossing: return v1::CONTAINMENT_CROSSING;
    case Containment::kInside: return v1::CONTAINMENT_INSIDE;
  }
  return v1::CONTAINMENT_UNSPECIFIED;
}

v1::Ack appliedAck(std::uint64_t sequence, bool late) {
  v1::Ack ack;
  ack.set_sequence(sequence);
  ack.set_status(late ? v1::ACK_STATUS_LATE : v1::ACK_STATUS_APPLIED);
  ack.set_code(0);  // OK
  return ack;
}

v1::Ack refusedAck(std::uint64_t sequence, const Refused& refused) {
  return refusedAck(sequence, Error{refusalCode(refused.reason), refused.message});
}

v1::Ack refusedAck(std::uint64_t sequence, const Error& error) {
  v1::Ack ack;
  ack.set_sequence(sequence);
  ack.set_status(v1::ACK_STATUS_REFUSED);
  ack.set_reason(error.message);
  ack.set_code(rpcCode(error.code));
  return ack;
}

Expected<Containment> fromProto(v1::Containment containment) {
  switch (containment) {
    case v1::CONTAINMENT_OUTSIDE: return Containment::kOutside;
    case v1::CONTAINMENT_CROSSING: return Containment::kCrossing;
    case v1::CONTAINMENT_INSIDE: return Containment::kInside;
    default: return invalidArgument("containment: unknown value " + std::to_string(static_cast<int>(containment)));
  }
}

std::size_t baselineUploadBytes(const MapHeader& header, std::size_t points, std::size_t max_points_per_chunk,
                                std::uint64_t first_sequence) {
  using google::protobuf::io::CodedOutputStream;
  const std::size_t per_chunk = std::max<std::size_t>(1, max_points_per_chunk);
  const std::size_t count = std::max<std::size_t>(1, (points + per_chunk - 1) / per_chunk);
  PointChunk chunk;  // no points: their bytes are added below
  chunk.header = header;
  chunk.chunk_count = static_cast<std::uint32_t>(count);
  chunk.total_points = static_cast<std::uint32_t>(points);
  std::size_t total = 0;
  for (std::size_t c = 0; c < count; ++c) {
    chunk.chunk = static_cast<std::uint32_t>(c);
    chunk.first_point = static_cast<std::uint32_t>(c * per_chunk);
    const std::size_t xyz = 12 * (std::min(points, (c + 1) * per_chunk) - c * per_chunk);
    // bytes xyz = 6: one tag byte, the length, the bytes (absent when empty, as proto3 does).
    const std::size_t inner = toProto(chunk).ByteSizeLong() +
                              (xyz == 0 ? 0 : 1 + CodedOutputStream::VarintSize64(xyz) + xyz);
    // Upload: sequence = 1 (absent when 0), points = 3 (one tag byte, the length, the chunk).
    const std::uint64_t sequence = first_sequence + c;
    total += (sequence == 0 ? 0 : 1 + CodedOutputStream::VarintSize64(sequence)) + 1 +
             CodedOutputStream::VarintSize64(inner) + inner;
  }
  return total;
}

}  // namespace fogmap
