#pragma once
// What travels between fogmap services, in domain types (the wire form is protos/; only
// services/common/proto_convert translates).
#include <cstdint>
#include <string>
#include <vector>

#include "common/geometry/cloud.hpp"
#include "common/geometry/map.hpp"

namespace fogmap {

enum class Mode { kMadc, kBaseline, kExt };
const char* modeName(Mode mode);

struct MapHeader {
  std::uint32_t node = 0;                       // the sender
  std::uint64_t epoch = 0;                      // frame sequence: maps of one epoch are merged together
  std::int64_t sensor_time_ns = 0;              // earliest sensor timestamp of the data (unix ns)
  std::vector<std::uint32_t> contributing_nodes;  // sensor nodes whose data is in the message (sorted)
  std::vector<std::uint32_t> missing_nodes;       // expected sensor nodes whose data is not (sorted)
  std::vector<std::uint32_t> failed_nodes;        // reported a failed frame (also missing; sorted)
  std::uint64_t dropped_uploads = 0;              // uploads dropped by bounded queues in the subtree
  bool operator==(const MapHeader&) const = default;
};

struct MapMessage {
  MapHeader header;
  Map map;
  bool operator==(const MapMessage&) const = default;
};

// A slice of one sensor's pre-processed scan, in the common frame.
struct PointChunk {
  MapHeader header;                  // header.node = the sensor node that produced the points
  std::uint32_t chunk = 0;
  std::uint32_t chunk_count = 1;
  std::uint32_t first_point = 0;
  std::uint32_t total_points = 0;
  Cloud points;                      // intensity is not transmitted (0)
  std::vector<std::int32_t> labels;  // ext mode: local cluster label per point, else empty
  bool operator==(const PointChunk&) const = default;
};

struct NodeLabels {
  std::uint32_t node = 0;
  std::vector<std::int32_t> labels;  // per point of the node's scan; -1 noise
  bool operator==(const NodeLabels&) const = default;
};

struct GlobalMapMessage {
  MapHeader header;
  Map map;
  Mode mode = Mode::kMadc;
  std::int64_t published_time_ns = 0;
  double merge_seconds = 0.0;
  std::uint64_t pairs_all = 0;
  std::uint64_t pairs_tested = 0;
  std::vector<NodeLabels> point_labels;  // baseline and ext roots: global object per point
  std::uint32_t revision = 0;            // 0: first publication of the epoch; n: n-th revision
  bool late = false;                     // published after the epoch's deadline plus one period
  bool operator==(const GlobalMapMessage&) const = default;
};

}  // namespace fogmap
