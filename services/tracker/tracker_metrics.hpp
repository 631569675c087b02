#pragma once
// The tracker's observations as Prometheus metrics, beside the shared ones (bytes, end-to-end
// latency, reconnects): tracks by state, tracks created and deleted, updates by kind (a camera's
// detection fused with LiDAR, or LiDAR alone), detection frames dropped by reason, per-camera
// staleness, the fusion step's time, its measurement budget and the measurements it shed; with
// centroid input, centroid frames received per edge, rejected by reason, and epochs fused without
// every edge; subscribers refused beyond the bound.
#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include <prometheus/counter.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>

#include "common/tracking/tracker.hpp"
#include "services/common/metrics.hpp"
#include "services/tracker/tracker_node.hpp"

namespace fogmap {

// Thread-safe: the node publishes fused reports from whichever thread fused them.
class TrackerMetrics {
 public:
  // Adds the tracker's families to `metrics`' registry with its constant labels; `cameras` get a
  // staleness series from the start, `edges` (those sending centroids) a received series.
  TrackerMetrics(Metrics& metrics, const std::string& node, const std::vector<std::string>& cameras,
                 const std::vector<std::string>& edges = {});

  // After frames were fused: what the report says.
  void fused(const FusionReport& report);
  // A detection frame refused; `reason` as TrackerServiceHooks::on_refused gives it (malformed,
  // unknown_camera and forged are counted as "refused").
  void detectionsRefused(const std::string& reason);
  // Every camera's staleness now (TrackerNode::tick), in seconds.
  void cameraStaleness(const std::map<std::string, double>& seconds);
  // A Subscribe call refused: the tracker serves admission.max_subscribers already.
  void subscriberRefused();
  // A global map the node refused (input global_map); `reason` as TrackerNode::Refusal gives it.
  void globalMapRefused(const std::string& reason);
  // A centroid frame accepted from `edge`, of `bytes` serialised bytes.
  void centroidsReceived(const std::string& edge, std::size_t bytes);
  // A centroid frame rejected; `reason` as TrackerServiceHooks::on_centroids_refused gives it.
  void centroidsRejected(const std::string& reason);

 private:
  Metrics& metrics_;
  prometheus::Family<prometheus::Gauge>* tracks_;
  prometheus::Counter* created_;
  prometheus::Counter* deleted_;
  prometheus::Counter* recovered_;
  prometheus::Family<prometheus::Counter>* updates_;
  prometheus::Family<prometheus::Counter>* dropped_;
  prometheus::Family<prometheus::Gauge>* staleness_;
  prometheus::Histogram* fusion_seconds_;
  prometheus::Family<prometheus::Counter>* centroid_frames_;
  prometheus::Family<prometheus::Counter>* centroid_rejected_;
  prometheus::Counter* centroid_epochs_partial_;
  prometheus::Family<prometheus::Counter>* shed_;
  prometheus::Gauge* budget_;
  prometheus::Family<prometheus::Counter>* global_maps_refused_;
  void setStaleness(const std::map<std::string, double>& seconds);  // under mutex_

  std::mutex mutex_;                // fused() and cameraStaleness() come from several threads
  tracking::TrackerCounters last_;  // counters already exported (the highest seen)
  std::uint64_t last_partial_ = 0;
};

}  // namespace fogmap
