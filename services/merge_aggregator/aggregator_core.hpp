#pragma once
// The merge-aggregator's core (DESIGN.md 2.2, docs/design.md "Epochs", "Admission", "Delivery"):
// admit uploads from the direct children, collect them per epoch, MERGE maps into the epoch's
// working map, and emit the epoch once every live child has reported or its absolute deadline
// (common/base/epochs.hpp) has passed. Maps that arrive after their epoch was emitted are merged into
// the retained epoch and emitted again as a revision flagged late. Domain types only; the clock is
// injected (every call that depends on time takes now_ns, unix nanoseconds), so tests drive
// deadlines by hand. Not thread-safe: the service wraps it in SharedAggregator.
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <variant>
#include <vector>

#include "common/base/epochs.hpp"
#include "common/base/status.hpp"
#include "common/config/admission.hpp"
#include "common/config/topology.hpp"
#include "common/geometry/geofence.hpp"
#include "common/geometry/map.hpp"
#include "common/io/messages.hpp"
#include "common/perception/madc.hpp"
#include "common/perception/preprocess.hpp"

namespace fogmap {

// A direct child and the sensor (edge) nodes in its subtree; for an edge child that is itself.
struct ChildConfig {
  std::uint32_t id = 0;
  std::vector<std::uint32_t> sensors;
  std::string name;  // the node's name: with TLS, the common name of its certificate
};

struct AggregatorConfig {
  std::uint32_t node = 0;             // this aggregator's id
  Mode mode = Mode::kMadc;
  bool is_root = false;               // the sink: emits global maps instead of uploading
  std::vector<ChildConfig> children;  // direct children
  int levels = 1;                     // levels of aggregators at and below this one (1 over edges)
  double period_ms = 100.0;           // the cluster period (epoch length)
  double deadline_ms = 80.0;          // per level: epoch k is emitted at k period + levels deadline
  AdmissionLimits admission;
  MadcParams madc;                      // baseline root: the central clustering and ellipsoids
  // Baseline root whose edges ship whole scans: each is pre-processed here (no transform: the
  // edges moved them into the common frame), as an edge would, before the central clustering.
  std::optional<PreprocessConfig> preprocess;
  std::size_t max_pending_epochs = 64;  // beyond this the oldest open epoch is dropped (counted)
};

// The configuration of aggregator `name` in `topology`: its children and their sensors, its
// level, the cluster period, deadline, admission limits and MAD-C parameters.
Expected<AggregatorConfig> aggregatorConfigFor(const TopologyConfig& topology, const std::string& name);

// What happened to an admitted upload.
enum class Arrival {
  kAccepted,   // stored or merged into an open epoch (or a re-sent copy of one already applied)
  kLate,       // its epoch was already emitted: merged into the retained epoch, a revision follows
  kRelay,      // an intermediate's point chunk: forward it to the parent unchanged
};

// The answer to one upload: admitted (with its arrival) or refused with a reason.
struct Outcome {
  Arrival arrival = Arrival::kAccepted;
  std::optional<Refused> refused;
  std::optional<PointChunk> relay;  // set when arrival == kRelay
  bool ok() const { return !refused.has_value(); }
};

// Identifies an upload on a child's stream: the stream's sequence number and a fingerprint of
// its content, so a re-sent copy is recognised and the same sequence with other content refused.
struct UploadKey {
  std::uint64_t sequence = 0;
  std::uint64_t fingerprint = 0;
};

// The central clustering of a baseline root, run by the caller outside the core's lock.
struct BaselineJob {
  std::uint32_t node = 0;  // the root, for the ellipsoid ids
  MadcParams madc;
  std::vector<std::pair<std::uint32_t, Cloud>> scans;  // (sensor, its scan), sensor order
  std::optional<PreprocessConfig> preprocess;          // whole scans: pre-process each first
  GlobalMapMessage message;  // header and flags set; map and labels filled by clusterCentrally
};
// Clusters the union of the scans (each pre-processed first when the job says so; the point
// labels are then those of the pre-processed points) and fills the job's global map (objects,
// point labels, the time it took, pre-processing included).
GlobalMapMessage clusterCentrally(BaselineJob job);

// One emitted epoch. `message` is a MapMessage for the parent at an intermediate, a
// GlobalMapMessage at the root, or a BaselineJob at a baseline root (finish it with
// clusterCentrally, then hand the result to MergeAggregator::published).
struct EpochOutput {
  std::uint64_t epoch = 0;
  bool complete = false;       // false: emitted because the deadline passed
  std::uint32_t revision = 0;  // 0 for the first emission of the epoch
  bool late = false;           // a revision, or emitted after deadline + one period (a stall)
  MergeStats stats;            // summed over the epoch's merges
  double merge_seconds = 0.0;  // merging
  std::variant<MapMessage, GlobalMapMessage, BaselineJob> message;
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
  std::uint64_t duplicates = 0;      // re-sent copies of uploads already applied
  std::uint64_t late = 0;            // maps merged into an already emitted epoch
  std::uint64_t relayed = 0;         // chunks passed through an intermediate
  std::uint64_t emitted = 0;         // epochs emitted (revisions included)
  std::uint64_t revisions = 0;       // emissions of an epoch after its first
  std::uint64_t late_emits = 0;      // emissions flagged late (revisions and stale epochs)
  std::uint64_t dropped_epochs = 0;  // open epochs evicted beyond max_pending_epochs
  // Root: objects of merged maps left out of the published map for having fewer than min_points
  // points over all their sensors (lone fragments), over all emissions.
  std::uint64_t fragments_unpublished = 0;
  // Root: epochs nobody reported that it opened more than a period after their deadline, because
  // it did not poll in time (a stall of its own: SIGSTOP, a starved process); published late.
  std::uint64_t caught_up = 0;
  std::int64_t longest_poll_gap_ns = 0;  // the longest time between two polls
  std::map<Refusal, std::uint64_t> refused;  // by reason
  std::uint64_t refusedTotal() const;
};

class MergeAggregator {
 public:
  // Sequence fingerprints remembered per child, for recognising re-sent copies: far more than the
  // uploads of any admission window; the oldest (lowest sequence) are forgotten first.
  static constexpr std::size_t kUploadHistory = 4096;
  // Geofences the root keeps; setting one more (a new name) is refused as resource exhausted.
  static constexpr std::size_t kMaxGeofences = 256;

  // Validates the config (unique children, positive period and deadline, admission limits, at
  // least one pending epoch).
  static Expected<MergeAggregator> create(AggregatorConfig config);

  const AggregatorConfig& config() const { return config_; }
  // Expected sensor nodes below this aggregator, sorted.
  const std::vector<std::uint32_t>& sensors() const { return sensors_; }

  // A child's upload stream opened; `sender` is the node in its first upload's header: the direct
  // child itself, or a sensor below it (chunks relayed by an intermediate keep the sensor's id).
  // Returns the direct child, now live: the stream speaks for that child only from now on.
  // Streams are counted, so a reconnect that overlaps the old stream keeps the child live.
  Expected<std::uint32_t> childConnected(std::uint32_t sender);
  // With TLS the stream's child is the one its peer certificate names (`certificate_name`, empty
  // when the peer has none) instead of its first upload: returns that child, now live as with
  // childConnected, or std::nullopt when no direct child has that name; every upload on such a
  // stream is then refused as unknown_peer (see refuse).
  std::optional<std::uint32_t> peerConnected(const std::string& certificate_name);
  // The stream of `child` (as returned by childConnected) closed. The child stays live for a
  // grace of one period plus one deadline, so a brief reconnect does not cost it its epochs.
  void childDisconnected(std::uint32_t child, std::int64_t now_ns);
  std::size_t liveChildren(std::int64_t now_ns) const;
  std::size_t staleChildren(std::int64_t now_ns) const { return config_.children.size() - liveChildren(now_ns); }

  // Admits and merges a map from the stream of `child`. `wire_bytes` is its serialised size.
  Outcome onMap(std::uint32_t child, const UploadKey& key, const MapMessage& message, std::size_t wire_bytes,
                std::int64_t now_ns);
  // Baseline and ext: relays a chunk at an intermediate, stores it at the root.
  Outcome onPoints(std::uint32_t child, const UploadKey& key, PointChunk chunk, std::size_t wire_bytes,
                   std::int64_t now_ns);
  // Counts a refusal decided outside the core (a message that does not convert, an oversized
  // one) and returns it, so every refusal shows in counters().refused.
  Refused refuse(Refusal reason, std::string message);

  // Emits every epoch that is complete or past its deadline, in epoch order (an epoch complete
  // before an older one is due waits for it), and a revision of every retained epoch that took
  // late maps, oldest epoch first. The root also publishes the epochs nobody reported, every one
  // of them after a stall of its own (late and flagged), up to max_pending_epochs.
  std::vector<EpochOutput> poll(std::int64_t now_ns);
  // Emits every open epoch now, complete or not (shutdown: nothing acknowledged is abandoned).
  std::vector<EpochOutput> drain(std::int64_t now_ns);

  // The total drops of this node's own upload link (intermediates), added to the drops its
  // children report in the headers of the maps it emits.
  void setLinkDrops(std::uint64_t dropped) { link_drops_ = dropped; }

  // Root: records a global map finished outside the core (baseline) as the latest when it is.
  void published(const GlobalMapMessage& message);

  // Root only: adds a geofence or replaces the one with the same name; returns the fence count.
  Expected<std::size_t> setGeofence(Geofence fence);
  // Root only: intrusions into the named geofence (every geofence when empty) on the latest
  // global map.
  Expected<GeofenceReport> queryGeofences(const std::string& name) const;
  // The latest on-time global map (root only): the highest epoch emitted, never a late one.
  const std::optional<GlobalMapMessage>& latestGlobalMap() const { return latest_; }

  const AggregatorCounters& counters() const { return counters_; }
  // What the core holds, for checking its bounds: open epochs, emitted epochs retained for late
  // maps, and sequence fingerprints remembered over all children (at most kUploadHistory each).
  std::size_t pendingEpochs() const { return pending_.size(); }
  std::size_t retainedEpochs() const { return emitted_.size(); }
  std::size_t rememberedUploads() const;
  // The most distinct epochs the admission window admits at one instant, floor((2 W + L D) / P)
  // + 1 for window W, levels L, deadline D and period P. Right after poll(now),
  // pendingEpochs() + retainedEpochs() never exceed it, however many epochs were offered.
  std::size_t windowEpochs() const;

 private:
  struct SensorPoints {
    std::uint32_t chunk_count = 0;
    std::uint32_t total_points = 0;
    std::uint64_t stored_points = 0;             // over the chunks: at most total_points
    std::map<std::uint32_t, PointChunk> chunks;  // by chunk index
    bool complete() const { return chunks.size() == chunk_count; }
  };

  struct Epoch {
    std::optional<std::int64_t> sensor_time_ns;  // earliest known sensor timestamp
    Map working;
    std::map<EllipsoidId, Ellipsoid> ellipsoids;  // every ellipsoid merged in, by id
    std::map<std::uint32_t, std::size_t> ellipsoids_of;  // their count per sensor (id.node)
    MergeStats stats;
    double merge_seconds = 0.0;
    std::set<std::uint32_t> contributing;          // sensors whose data is merged in
    std::set<std::uint32_t> failed;                // sensors that reported a failed frame
    std::set<std::uint32_t> reported_children;     // direct children whose map arrived
    std::map<std::uint32_t, SensorPoints> points;  // root, baseline and ext: by sensor
    std::uint32_t revision = 0;                    // emissions so far
    bool dirty = false;                            // retained, with late data not yet emitted
  };

  struct Child {
    std::string name;
    std::vector<std::uint32_t> sensors;  // sorted
    int open_streams = 0;
    std::optional<std::int64_t> disconnected_ns;  // when the last stream closed
    std::uint64_t dropped = 0;                    // latest drop count its maps reported
    std::map<std::uint64_t, std::uint64_t> uploads;  // sequence -> fingerprint, recent ones
  };

  explicit MergeAggregator(AggregatorConfig config, EpochSchedule schedule);
  std::optional<std::uint64_t> silent_from_;  // the root: first epoch not yet checked for silence
  std::optional<std::int64_t> last_poll_ns_;

  std::optional<std::uint32_t> childOf(std::uint32_t node) const;
  bool isLive(const Child& child, std::int64_t now_ns) const;
  // The admission rules every upload passes: the epoch window, the stream's identity and the
  // sequence. Returns a refusal, or nothing; sets `duplicate` for a re-sent copy.
  std::optional<Refused> admit(std::uint32_t child, const UploadKey& key, const MapHeader& header,
                               std::size_t wire_bytes, std::int64_t now_ns, const std::string& what, bool& duplicate);
  void rememberUpload(std::uint32_t child, const UploadKey& key);
  Outcome refusedOutcome(Refused refused);
  bool speaksFor(const Child& child, std::uint32_t sensor) const;
  std::optional<Refused> checkEllipsoids(std::uint32_t child, const MapMessage& message, const Epoch* epoch,
                                         const std::string& what) const;
  Epoch& openEpoch(std::uint64_t epoch);
  // The root: opens, empty, the epochs whose deadline passed without any upload.
  void openSilentEpochs(std::int64_t now_ns);
  void mergeInto(Epoch& epoch, const MapMessage& message);
  bool isComplete(const Epoch& epoch, std::int64_t now_ns) const;
  EpochOutput emit(std::uint64_t epoch_id, Epoch& epoch, bool complete, std::int64_t now_ns);
  MapHeader headerFor(std::uint64_t epoch_id, const Epoch& epoch, const std::set<std::uint32_t>& contributing) const;
  void forgetOldEpochs(std::int64_t now_ns);
  std::int64_t windowNs() const;

  AggregatorConfig config_;
  EpochSchedule schedule_;
  std::vector<std::uint32_t> sensors_;
  std::map<std::uint32_t, Child> children_;
  std::map<std::uint64_t, Epoch> pending_;
  // Emitted epochs still inside the admission window: late maps merge into them (revisions).
  std::map<std::uint64_t, Epoch> emitted_;
  std::uint64_t link_drops_ = 0;
  std::vector<Geofence> geofences_;
  std::optional<GlobalMapMessage> latest_;
  AggregatorCounters counters_;
};

}  // namespace fogmap
