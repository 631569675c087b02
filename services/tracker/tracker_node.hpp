#pragma once
// The tracker service's core, in domain types: it fuses its LiDAR input (the root's global maps:
// one observation per obstacle; or its edges' displacement centroids, one LiDAR frame per epoch)
// with the detection frames its cameras send, and hands every resulting set of tracks to its
// subscribers. Thread-safe: the detection and centroid streams, the global-map feed and the
// subscribers run on their own threads.
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/clock.hpp"
#include "common/messages.hpp"
#include "common/status.hpp"
#include "common/tracking/tracker.hpp"
#include "services/tracker/centroid_collector.hpp"

namespace fogmap {

// How far apart (m) on the ground plane two global-map objects may be and still be one obstacle:
// a sparse LiDAR's rings lie further apart than eps on a person or a car's side, so MAD-C sees
// them as objects stacked above each other or side by side; the tracker works on the ground.
inline constexpr double kGroundMergeM = 0.3;

// The LiDAR observations of a global map: objects whose boxes, seen from above and grown by
// `ground_merge_m`, overlap are one obstacle (transitively); per obstacle, the point-weighted
// centroid of its ellipsoids and the spread of its points (each ellipsoid's shape is alpha^2 Sigma,
// grown by the aura; the aura is left in, a conservative measurement noise). `alpha` is the
// topology's.
tracking::CloudFrame observationsOf(const GlobalMapMessage& global, double alpha, double ground_merge_m = kGroundMergeM);

// One published set of tracks.
struct TrackSnapshot {
  std::int64_t lidar_time_ns = 0;      // the sensor time of the fused LiDAR frame (global map or epoch)
  std::int64_t published_time_ns = 0;
  tracking::Association association = tracking::Association::kKalman;
  std::vector<tracking::Track> tracks;  // every live track (subscribers choose which to show)
};

// What fusing took and did, for the metrics: the steps fused at once (usually one LiDAR frame),
// and the tracker's state after them.
struct FusionReport {
  double fusion_seconds = 0.0;
  double end_to_end_seconds = 0.0;  // from the last fused LiDAR frame's sensor time to publication
  std::vector<tracking::StepStats> steps;
  tracking::TrackerCounters counters;
  std::vector<tracking::Track> tracks;
  std::map<std::string, double> camera_staleness_s;  // per camera: seconds since its newest capture (or since the start)
  std::optional<CentroidCounters> centroids;          // with centroid input
};

// The tracker core of the service: LiDAR frames wait for the detections that belong to them
// (Tracker::offerCloud), and whenever frames are fused the tracks are published with a report.
class TrackerNode {
 public:
  using Publish = std::function<void(const TrackSnapshot&, const FusionReport&)>;
  // `centroids`: the collector of a tracker whose input is centroids (none: global maps).
  TrackerNode(tracking::Tracker tracker, double alpha, NowNs now, Publish publish,
              std::optional<CentroidCollector> centroids = std::nullopt);

  // A camera's detection frame, already validated by the adapter; may complete waiting frames.
  void addDetections(tracking::DetectionFrame frame);
  // Offers a global map's observations (late revisions are skipped: their epoch was offered).
  void addGlobalMap(const GlobalMapMessage& global);
  // An edge's centroid frame, already validated by the adapter: collected with the other edges'
  // frames of its epoch; each epoch complete is offered as one LiDAR frame. kUnknownEdge when this
  // node takes no centroids.
  CentroidVerdict addCentroids(tracking::CentroidFrame frame);
  // Offers the epochs of centroids whose deadline passed, and fuses the LiDAR frames whose wait for
  // detections is over (call it every few milliseconds).
  void tick();

  tracking::TrackerCounters counters() const;
  std::optional<CentroidCounters> centroidCounters() const;  // with centroid input
  std::vector<tracking::Track> tracks() const;

 private:
  // Publishes what `steps` (fused under the lock taken by the caller) left; the lock is released
  // before publishing.
  void publishFused(std::unique_lock<std::mutex>& lock, std::vector<tracking::StepStats> steps,
                    std::chrono::steady_clock::time_point started);

  // Offers `frames` (epochs of centroids, in order) under the lock; returns the steps fused.
  std::vector<tracking::StepStats> offer(const std::vector<tracking::CloudFrame>& frames, std::int64_t now_ns);

  mutable std::mutex mutex_;
  tracking::Tracker tracker_;
  double alpha_;
  NowNs now_;
  Publish publish_;
  std::optional<CentroidCollector> centroids_;
  std::int64_t started_ns_;  // when the node started: the staleness of a camera not heard from yet
};

}  // namespace fogmap
