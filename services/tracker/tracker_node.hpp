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

#include "common/base/clock.hpp"
#include "common/io/messages.hpp"
#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "common/tracking/track_snapshot.hpp"
#include "common/tracking/tracker.hpp"
#include "services/tracker/centroid_collector.hpp"

namespace fogmap {

// How far apart (m) on the ground plane two global-map objects may be and still be one obstacle:
// a sparse LiDAR's rings lie further apart than eps on a person or a car's side, so MAD-C sees
// them as objects stacked above each other or side by side; the tracker works on the ground.
inline constexpr double kGroundMergeM = 0.3;

// The LiDAR observations of a global map: objects whose boxes, seen from above and grown by
// `ground_merge_m`, overlap are one obstacle (transitively); per obstacle, the point-weighted
// centroid of its ellipsoids (each where its view places the object: below) and the spread of its points (each ellipsoid's shape is alpha^2 Sigma,
// grown by the aura; the aura is left in, a conservative measurement noise). `alpha` is the
// topology's. Where the edges fit boxes and classify (topology objects:), each obstacle also has
// its views' class and box (objectLabel, objectBox, the box as the views give it); a vehicle
// (vehiclePriorFor: by its class or its size) is then observed at the centre of its box grown to
// its class's size from the faces seen (grownFromAnchor), kVehicleCentreSigmaM apart on the ground.
// Objects whose vehicle boxes (so grown) overlap are one obstacle too: the parts of a car that the
// map holds as two objects.
// Each view (one sensor's ellipsoid) of a narrow object (its box, with the face or corner its
// sensor saw, no longer than kNarrowObjectMaxM and no vehicle's: a person, a pole) counts in the
// obstacle's centroid at the centre of its box grown to a square away from that face or corner: on
// the object's axis, where its points' centre lies half its depth short of it, toward the sensor
// (about 0.13 m for a person).
inline constexpr double kNarrowObjectMaxM = 0.8;
inline constexpr double kVehicleCentreSigmaM = 0.3;
tracking::CloudFrame observationsOf(const GlobalMapMessage& global, double alpha, double ground_merge_m = kGroundMergeM);

// One published set of tracks (common/tracking/track_snapshot.hpp).
using TrackSnapshot = tracking::TrackSnapshot;

// What fusing took and did, for the metrics: the steps fused at once (usually one LiDAR frame),
// and the tracker's state after them.
struct FusionReport {
  double fusion_seconds = 0.0;
  std::size_t measurement_budget = 0;  // observations a step takes from now on (0: all)
  double end_to_end_seconds = 0.0;  // from the last fused LiDAR frame's sensor time to publication
  std::vector<tracking::StepStats> steps;
  tracking::TrackerCounters counters;
  std::vector<tracking::Track> tracks;
  // Per camera: seconds since its newest capture (or since the start), never negative.
  std::map<std::string, double> camera_staleness_s;
  std::optional<CentroidCounters> centroids;  // with centroid input
};

// What the node holds to at its door and in its steps.
struct TrackerNodeLimits {
  // The admission window (topology admission.window_periods x period_ms, as an aggregator keeps it):
  // a detection frame captured more than this ahead of the clock is refused as clock skew, and so is
  // one captured more than this before the oldest instant a LiDAR frame may still wait for it
  // (now - max_detection_wait_s - eps_sync_s). A frame from the future would otherwise count as
  // the camera's newest (its staleness negative, every LiDAR frame fused without waiting) and stay
  // in the camera's buffer while the honest frames are dropped as overflow.
  std::int64_t window_ns = 300'000'000;
  // Fusion budget: a step should take at most `fusion_share` of the period (topology period_ms).
  // The node measures what a step costs per observation it takes (the cost rises at once with a
  // dearer step and falls slowly) and gives the tracker the budget of observations that fits,
  // never below `min_budget` (one descheduled step must not starve an honest scene). 0: no budget.
  std::int64_t period_ns = 100'000'000;
  double fusion_share = 0.5;
  std::size_t min_budget = 64;
  // Measures the fusion steps (a steady clock in ns; empty: std::chrono::steady_clock). Tests
  // inject it to give steps the cost they want.
  NowNs stopwatch;
};
// The tracker node's window and period in `topology`.
TrackerNodeLimits trackerNodeLimitsFor(const TopologyConfig& topology);

// The tracker core of the service: LiDAR frames wait for the detections that belong to them
// (Tracker::offerCloud), and whenever frames are fused the tracks are published with a report.
class TrackerNode {
 public:
  using Publish = std::function<void(const TrackSnapshot&, const FusionReport&)>;
  // `centroids`: the collector of a tracker whose input is centroids (none: global maps).
  TrackerNode(tracking::Tracker tracker, double alpha, NowNs now, Publish publish,
              std::optional<CentroidCollector> centroids = std::nullopt, TrackerNodeLimits limits = {});

  // Why a frame was refused: the metric's reason and a line for a person.
  struct Refusal {
    std::string reason;
    std::string detail;
  };
  // A camera's detection frame, already validated by the adapter; may complete waiting frames.
  // Refused (reason "clock_skew") when captured outside the admission window around the clock.
  std::optional<Refusal> addDetections(tracking::DetectionFrame frame);
  // Offers a global map's observations (revisions are skipped: their epoch was offered; a late
  // first publication is taken).
  // Refused ("clock_skew") when its sensor time lies more than the admission window ahead of the
  // clock: it would become the tracker's time and every later frame would be out of order.
  std::optional<Refusal> addGlobalMap(const GlobalMapMessage& global);
  // An edge's centroid frame, already validated by the adapter: collected with the other edges'
  // frames of its epoch; each epoch complete is offered as one LiDAR frame. kUnknownEdge when this
  // node takes no centroids; `detail` says why a frame was refused.
  struct CentroidAdmission {
    CentroidVerdict verdict = CentroidVerdict::kAccepted;
    std::string detail;
  };
  CentroidAdmission addCentroids(tracking::CentroidFrame frame);
  // Offers the epochs of centroids whose deadline passed, and fuses the LiDAR frames whose wait for
  // detections is over (call it every few milliseconds). Returns every camera's staleness now, so
  // that its gauge moves whether or not anything is fused (a camera that stopped grows).
  std::map<std::string, double> tick();

  tracking::TrackerCounters counters() const;
  std::optional<CentroidCounters> centroidCounters() const;  // with centroid input
  std::vector<tracking::Track> tracks() const;
  std::size_t measurementBudget() const;

 private:
  // Publishes what `steps` (fused under the lock taken by the caller) left; the lock is released
  // before publishing.
  void publishFused(std::unique_lock<std::mutex>& lock, std::vector<tracking::StepStats> steps, std::int64_t started_ns);
  // Seconds since each camera's newest capture at `now_ns` (since the start for one not heard from), never negative.
  std::map<std::string, double> staleness(std::int64_t now_ns) const;
  // The budget of the steps to come, from what `steps` cost in `seconds`.
  void updateBudget(const std::vector<tracking::StepStats>& steps, double seconds);

  // Offers `frames` (epochs of centroids, in order) under the lock; returns the steps fused.
  std::vector<tracking::StepStats> offer(const std::vector<tracking::CloudFrame>& frames, std::int64_t now_ns);

  mutable std::mutex mutex_;
  tracking::Tracker tracker_;
  double alpha_;
  NowNs now_;
  Publish publish_;
  std::optional<CentroidCollector> centroids_;
  TrackerNodeLimits limits_;
  std::int64_t started_ns_;  // when the node started: the staleness of a camera not heard from yet
  double cost_per_measurement_s_ = 0.0;  // of a step, as measured (0: not yet)
};

}  // namespace fogmap
