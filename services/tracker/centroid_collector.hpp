#pragma once
// The tracker's centroid input (topology `tracker: {input: centroids}`): the centroid frames its
// edges stream, collected per cluster epoch and merged into one LiDAR frame per epoch.
//
// Why one frame per epoch and not one per edge: the edges of a cluster share the epochs
// (common/base/epochs.hpp), so the frames of one epoch are one instant seen from several sides. Fed one
// by one, the tracker would give each camera frame to the first of them only (it fuses a detection
// frame with the LiDAR frame nearest in time), read an object the last edge did not see as lost,
// and spawn a track per extra view; merged, an object seen by several LiDARs is one measurement
// (common/tracking/centroid_merge.hpp). fogctl track-eval measured it on people, 30 % of the
// detections missed: kalman MOTA 0.95 / 1.00 / 0.89 merged, 0.80 / 0.62 / 0.63 fed per LiDAR.
//
// An epoch is emitted as soon as every edge has sent a frame of it or of a later epoch (an edge
// whose scan did not change sends nothing for that epoch), else at its deadline, the one a level-1
// aggregator keeps: start of the epoch + the topology's deadline_ms; then with what arrived. Pure
// and single-threaded (TrackerNode holds it under its lock); time comes in as arguments.
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/base/epochs.hpp"
#include "common/config/topology.hpp"
#include "common/tracking/track.hpp"

namespace fogmap {

struct CentroidCollectorConfig {
  std::vector<std::string> edges;  // the edges that send centroids to this tracker
  double merge_radius_m = 1.0;     // topology centroid_merge_m; 0: every centroid its own observation
  // The admission window, as an aggregator keeps it (topology admission.window_periods times the
  // period): a frame whose epoch starts more than this ahead of the clock, or whose epoch's deadline
  // passed more than this long ago, is refused as clock skew; so is one whose sensor time lies more
  // than this ahead of the clock or more than this before the time its epoch's frames are due
  // (sensor time + deadline_ms). A frame from the future would otherwise hold the epochs open, or
  // move the tracker's time past every honest frame.
  double window_periods = 3.0;
  std::size_t max_open_epochs = 16;  // beyond, the oldest open epoch is emitted at once
  // Topology visible_side_max_radius_m: each frame's centroids this narrow are placed on the
  // object's axis, away from the side its LiDAR (the frame's sensor position) sees; 0: off.
  double visible_side_max_radius_m = 0.0;
};

// The collector of tracker node `tracker` (input centroids) in `topology`: the edges that send to
// it, its centroid_merge_m and visible_side_max_radius_m, the admission window.
CentroidCollectorConfig centroidCollectorConfigFor(const TopologyConfig& topology, const NodeConfig& tracker);

// What became of a centroid frame.
enum class CentroidVerdict {
  kAccepted,
  kUnknownEdge,  // not one of this tracker's edges
  kLate,         // its epoch was emitted already (or a later one): the tracker has moved past it
  kClockSkew,    // its epoch or sensor time lies outside the admission window around the clock
  kDuplicate,    // the edge sent this epoch already
};
// The metric label: "accepted", "unknown_edge", "late", "clock_skew", "duplicate".
const char* centroidVerdictName(CentroidVerdict verdict);

struct CentroidCounters {
  std::uint64_t frames_accepted = 0;
  std::uint64_t epochs_emitted = 0;
  std::uint64_t epochs_partial = 0;  // emitted at the deadline (or beyond the open bound) without every edge
};

class CentroidCollector {
 public:
  CentroidCollector(CentroidCollectorConfig config, EpochSchedule schedule);

  struct Added {
    CentroidVerdict verdict = CentroidVerdict::kAccepted;
    std::string detail;                       // why it was refused, for a person (empty if accepted)
    std::vector<tracking::CloudFrame> ready;  // epochs complete now, oldest first
  };
  // Takes an edge's frame at `now_ns`; epochs whose deadline passed are emitted first.
  Added add(tracking::CentroidFrame frame, std::int64_t now_ns);
  // The open epochs whose deadline has passed at `now_ns`, oldest first.
  std::vector<tracking::CloudFrame> expire(std::int64_t now_ns);

  // One epoch's LiDAR frame: the earliest sensor time of its frames, the mean of their sensors'
  // positions, and their centroids merged within merge_radius_m (grouped as seen, placed on the
  // axis of narrow objects).
  tracking::CloudFrame merged(const std::vector<tracking::CentroidFrame>& frames) const;

  // Why a frame of `epoch` with sensor time `time_ns` lies outside the admission window at `now_ns`
  // (nothing when inside).
  std::optional<std::string> clockSkew(std::uint64_t epoch, std::int64_t time_ns, std::int64_t now_ns) const;
  std::int64_t windowNs() const;

  const CentroidCounters& counters() const { return counters_; }
  std::size_t openEpochs() const { return open_.size(); }

 private:
  bool complete(std::uint64_t epoch) const;
  void emit(std::map<std::uint64_t, std::vector<tracking::CentroidFrame>>::iterator it,
            std::vector<tracking::CloudFrame>& out);

  CentroidCollectorConfig config_;
  EpochSchedule schedule_;
  std::set<std::string> edges_;
  std::map<std::string, std::uint64_t> newest_;  // per edge, the newest epoch it sent
  std::map<std::uint64_t, std::vector<tracking::CentroidFrame>> open_;  // by epoch
  bool emitted_any_ = false;
  std::uint64_t last_emitted_ = 0;
  CentroidCounters counters_;
};

}  // namespace fogmap
