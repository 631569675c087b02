#pragma once
// The merge-aggregator's core (DESIGN.md 2.2): collect maps (or points) per epoch from the direct
// children, MERGE them into the epoch's working map, and emit the epoch once every live child has
// reported or its deadline has passed. Domain types only; the clock is injected (every call that
// depends on time takes now_ns, unix nanoseconds), so tests drive deadlines by hand. Not
// thread-safe: the service wraps it in SharedAggregator.
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <variant>
#include <vector>

#include "common/geofence.hpp"
#include "common/madc.hpp"
#include "common/map.hpp"
#include "common/messages.hpp"
#include "common/status.hpp"

namespace fogmap {

// A direct child and the sensor (edge) nodes in its subtree; for an edge child that is itself.
struct ChildConfig {
  std::uint32_t id = 0;
  std::vector<std::uint32_t> sensors;
};

struct AggregatorConfig {
  std::uint32_t node = 0;               // this aggregator's id
  Mode mode = Mode::kMadc;
  bool is_root = false;                 // the sink: emits global maps instead of uploading
  std::vector<ChildConfig> children;    // direct children (TopologyConfig::children / sensorsBelow)
  double deadline_ms = 80.0;            // an epoch is emitted this long after its first arrival
  MadcParams madc;                      // baseline root: the central clustering and ellipsoids
  std::size_t max_pending_epochs = 64;  // beyond this the oldest open epoch is dropped (counted)
};

// What happened to an accepted upload.
enum class Arrival {
  kAccepted,  // stored or merged into an open epoch
  kLate,      // its epoch was already emitted (or dropped): counted and discarded
  kRelay,     // an intermediate's point chunk: forward it to the parent unchanged
};

struct PointsArrival {
  Arrival arrival = Arrival::kAccepted;
  std::optional<PointChunk> relay;  // set when arrival == kRelay
};

// One emitted epoch. `message` is a MapMessage for the parent at an intermediate and a
// GlobalMapMessage at the root.
struct EpochOutput {
  std::uint64_t epoch = 0;
  bool complete = false;       // false: emitted because the deadline passed
  MergeStats stats;            // summed over the epoch's merges
  double merge_seconds = 0.0;  // merging, or central clustering at a baseline root
  std::variant<MapMessage, GlobalMapMessage> message;
};

struct GeofenceIntrusion {
  std::string geofence;
  std::size_t object_index = 0;  // index into the global map's objects
  Containment containment = Containment::kCrossing;
  Box box;
  std::vector<EllipsoidId> ellipsoids;
};

struct GeofenceReport {
  std::uint64_t epoch = 0;  // the global map queried; 0 before the first one
  std::vector<GeofenceIntrusion> intrusions;
};

struct AggregatorCounters {
  std::uint64_t accepted = 0;        // maps and chunks accepted into open epochs
  std::uint64_t late = 0;            // uploads for epochs already emitted or dropped
  std::uint64_t relayed = 0;         // chunks passed through an intermediate
  std::uint64_t emitted = 0;         // epochs emitted
  std::uint64_t dropped_epochs = 0;  // open epochs evicted beyond max_pending_epochs
};

class MergeAggregator {
 public:
  // Validates the config (unique children, finite positive deadline, at least one pending epoch).
  static Expected<MergeAggregator> create(AggregatorConfig config);

  const AggregatorConfig& config() const { return config_; }
  // Expected sensor nodes below this aggregator, sorted.
  const std::vector<std::uint32_t>& sensors() const { return sensors_; }

  // A child's upload stream opened; `sender` is the node in its first upload's header: the direct
  // child itself, or a sensor below it (chunks relayed by an intermediate keep the sensor's id).
  // Returns the direct child, now live. Streams are counted, so a reconnect that overlaps the old
  // stream keeps the child live until both have closed.
  Expected<std::uint32_t> childConnected(std::uint32_t sender);
  // The stream of `child` (as returned by childConnected) closed.
  void childDisconnected(std::uint32_t child);
  std::size_t liveChildren() const;
  std::size_t staleChildren() const { return config_.children.size() - liveChildren(); }

  // Merges a child's map into its epoch. header.node must be a direct child. Not in baseline mode.
  Expected<Arrival> onMap(const MapMessage& message, std::int64_t now_ns);
  // Baseline and ext: relays a chunk at an intermediate, stores it at the root. header.node must
  // be a sensor below this aggregator.
  Expected<PointsArrival> onPoints(PointChunk chunk, std::int64_t now_ns);
  // Emits every epoch that is complete or past its deadline, oldest epoch first.
  std::vector<EpochOutput> poll(std::int64_t now_ns);

  // Root only: adds a geofence or replaces the one with the same name; returns the fence count.
  Expected<std::size_t> setGeofence(Geofence fence);
  // Root only: intrusions into the named geofence (every geofence when empty) on the latest
  // global map.
  Expected<GeofenceReport> queryGeofences(const std::string& name) const;
  // The emitted global map with the highest epoch (root only).
  const std::optional<GlobalMapMessage>& latestGlobalMap() const { return latest_; }

  const AggregatorCounters& counters() const { return counters_; }
  std::size_t pendingEpochs() const { return pending_.size(); }

 private:
  struct SensorPoints {
    std::uint32_t chunk_count = 0;
    std::uint32_t total_points = 0;
    std::map<std::uint32_t, PointChunk> chunks;  // by chunk index
    bool complete() const { return chunks.size() == chunk_count; }
  };

  struct Epoch {
    std::int64_t first_arrival_ns = 0;
    std::optional<std::int64_t> sensor_time_ns;  // earliest known sensor timestamp
    Map working;
    MergeStats stats;
    double merge_seconds = 0.0;
    std::set<std::uint32_t> contributing;       // sensors whose maps are merged in
    std::set<std::uint32_t> reported_children;  // direct children whose map arrived
    std::map<std::uint32_t, SensorPoints> points;  // root, baseline and ext: by sensor
  };

  explicit MergeAggregator(AggregatorConfig config);

  std::optional<std::uint32_t> childOf(std::uint32_t node) const;
  bool isClosed(std::uint64_t epoch) const;
  void close(std::uint64_t epoch);
  Epoch& openEpoch(std::uint64_t epoch, std::int64_t now_ns);
  bool isComplete(const Epoch& epoch) const;
  EpochOutput emit(std::uint64_t epoch_id, Epoch& epoch, bool complete);
  MapHeader headerFor(std::uint64_t epoch_id, const Epoch& epoch,
                      const std::set<std::uint32_t>& contributing) const;

  AggregatorConfig config_;
  std::vector<std::uint32_t> sensors_;
  std::map<std::uint32_t, int> open_streams_;  // direct child -> open upload streams
  std::map<std::uint64_t, Epoch> pending_;
  // Closed (emitted or dropped) epochs: the most recent ones exactly, older ones by a floor, so
  // late detection keeps bounded memory.
  std::set<std::uint64_t> closed_;
  std::optional<std::uint64_t> closed_floor_;
  std::vector<Geofence> geofences_;
  std::optional<GlobalMapMessage> latest_;
  AggregatorCounters counters_;
};

}  // namespace fogmap
