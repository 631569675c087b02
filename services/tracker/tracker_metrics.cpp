#include "services/tracker/tracker_metrics.hpp"

#include <algorithm>

#include <prometheus/registry.h>

#include "common/config/topology.hpp"

namespace fogmap {

namespace {

// Exports what `now` adds to what was exported (`exported`), and remembers it. Reports can come
// out of order (several threads publish), so an older one adds nothing and never lowers it.
void addDelta(prometheus::Counter& counter, std::uint64_t now, std::uint64_t& exported) {
  if (now <= exported) return;
  counter.Increment(static_cast<double>(now - exported));
  exported = now;
}

}  // namespace

TrackerMetrics::TrackerMetrics(Metrics& metrics, const std::string& node, const std::vector<std::string>& cameras,
                               const std::vector<std::string>& edges)
    : metrics_(metrics) {
  prometheus::Registry& r = metrics.registry();
  const prometheus::Labels c{{"service", serviceName(Role::kTracker)}, {"node", node}};
  tracks_ = &prometheus::BuildGauge().Name("fogmap_tracks").Help("Tracks by state (tentative, confirmed, lost).").Labels(c).Register(r);
  for (const char* state : {"tentative", "confirmed", "lost"}) tracks_->Add({{"state", state}});
  created_ = &prometheus::BuildCounter().Name("fogmap_tracks_created_total").Help("Tracks created.").Labels(c).Register(r).Add({});
  deleted_ = &prometheus::BuildCounter()
                  .Name("fogmap_tracks_deleted_total")
                  .Help("Tracks deleted after going unobserved too long.")
                  .Labels(c)
                  .Register(r)
                  .Add({});
  recovered_ = &prometheus::BuildCounter()
                    .Name("fogmap_tracks_recovered_total")
                    .Help("Tracks that took a measurement beyond their gate near where they were last measured (recovery).")
                    .Labels(c)
                    .Register(r)
                    .Add({});
  updates_ = &prometheus::BuildCounter()
                  .Name("fogmap_track_updates_total")
                  .Help("Track updates by kind: overlay (a camera detection fused with LiDAR) or cloud_only (LiDAR alone).")
                  .Labels(c)
                  .Register(r);
  for (const char* kind : {"overlay", "cloud_only"}) updates_->Add({{"kind", kind}});
  dropped_ = &prometheus::BuildCounter()
                  .Name("fogmap_detection_frames_dropped_total")
                  .Help("Detection frames never fused, by reason: stale (older than eps_sync before every LiDAR frame "
                        "still to come), overflow (beyond the per-camera buffer), refused (malformed, unknown camera, "
                        "another camera's identity), too_large (more detections than a frame may hold), clock_skew "
                        "(captured outside the admission window around the tracker's clock).")
                  .Labels(c)
                  .Register(r);
  for (const char* reason : {"stale", "overflow", "refused", "too_large", "clock_skew"}) dropped_->Add({{"reason", reason}});
  staleness_ = &prometheus::BuildGauge()
                    .Name("fogmap_camera_staleness_seconds")
                    .Help("Seconds since the camera's newest capture, refreshed every tick (a camera that stopped grows); "
                          "never negative.")
                    .Labels(c)
                    .Register(r);
  for (const auto& camera : cameras) staleness_->Add({{"camera", camera}});
  fusion_seconds_ = &prometheus::BuildHistogram()
                         .Name("fogmap_fusion_seconds")
                         .Help("Time of one fusion step: synchronise, associate, update, spawn, prune.")
                         .Labels(c)
                         .Register(r)
                         .Add({}, prometheus::Histogram::BucketBoundaries{1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1});
  centroid_frames_ = &prometheus::BuildCounter()
                          .Name("fogmap_centroid_frames_received_total")
                          .Help("Centroid frames accepted from each edge (input centroids).")
                          .Labels(c)
                          .Register(r);
  for (const auto& edge : edges) centroid_frames_->Add({{"edge", edge}});
  centroid_rejected_ = &prometheus::BuildCounter()
                            .Name("fogmap_centroid_frames_rejected_total")
                            .Help("Centroid frames never fused, by reason: malformed (bad sizes, non-finite values, a "
                                  "covariance not positive semi-definite), too_large (more centroids than a frame may "
                                  "hold), forged (another edge's identity), unknown_edge, late (their epoch was fused), "
                                  "clock_skew (epoch or sensor time outside the admission window around the clock), "
                                  "duplicate (the edge sent that epoch already).")
                            .Labels(c)
                            .Register(r);
  for (const char* reason : {"malformed", "too_large", "forged", "unknown_edge", "late", "clock_skew", "duplicate"}) {
    centroid_rejected_->Add({{"reason", reason}});
  }
  centroid_epochs_partial_ = &prometheus::BuildCounter()
                                  .Name("fogmap_centroid_epochs_partial_total")
                                  .Help("Epochs of centroids fused at their deadline without every edge's frame.")
                                  .Labels(c)
                                  .Register(r)
                                  .Add({});
  shed_ = &prometheus::BuildCounter()
               .Name("fogmap_measurements_shed_total")
               .Help("LiDAR observations left out of fusion steps, by reason: over_budget (beyond the observations a "
                     "step can take within its share of the period; those nearest the tracks and with the most "
                     "points are kept).")
               .Labels(c)
               .Register(r);
  shed_->Add({{"reason", "over_budget"}});
  global_maps_refused_ = &prometheus::BuildCounter()
                              .Name("fogmap_global_maps_refused_total")
                              .Help("Global maps never fused, by reason: clock_skew (sensor time beyond the admission "
                                    "window ahead of the tracker's clock).")
                              .Labels(c)
                              .Register(r);
  global_maps_refused_->Add({{"reason", "clock_skew"}});
  budget_ = &prometheus::BuildGauge()
                 .Name("fogmap_fusion_budget_measurements")
                 .Help("Observations a fusion step takes at most, from its measured cost (0: not measured yet, all).")
                 .Labels(c)
                 .Register(r)
                 .Add({});
}

void TrackerMetrics::fused(const FusionReport& report) {
  // Fusion publishes from the thread that fused (a stream's handler, the tick, the global-map
  // feed), after the node's lock is released: the exported state is guarded here.
  std::lock_guard lock(mutex_);
  const auto& counters = report.counters;
  fusion_seconds_->Observe(report.fusion_seconds);
  metrics_.endToEndSeconds(report.end_to_end_seconds);
  for (std::size_t i = 0; i < report.steps.size(); ++i) metrics_.framesProcessed();
  // Gauges from the newest report only: an older one, published a moment later, must not undo it.
  const bool newest = counters.steps >= last_.steps;
  last_.steps = std::max(last_.steps, counters.steps);
  addDelta(*created_, counters.tracks_created, last_.tracks_created);
  addDelta(*deleted_, counters.tracks_deleted, last_.tracks_deleted);
  addDelta(*recovered_, counters.tracks_recovered, last_.tracks_recovered);
  addDelta(updates_->Add({{"kind", "overlay"}}), counters.updates_overlay, last_.updates_overlay);
  addDelta(updates_->Add({{"kind", "cloud_only"}}), counters.updates_cloud_only, last_.updates_cloud_only);
  addDelta(dropped_->Add({{"reason", "stale"}}), counters.detection_frames_stale, last_.detection_frames_stale);
  addDelta(dropped_->Add({{"reason", "overflow"}}), counters.detection_frames_overflow, last_.detection_frames_overflow);
  addDelta(shed_->Add({{"reason", "over_budget"}}), counters.measurements_shed, last_.measurements_shed);
  if (report.centroids) addDelta(*centroid_epochs_partial_, report.centroids->epochs_partial, last_partial_);
  if (!newest) return;
  budget_->Set(static_cast<double>(report.measurement_budget));
  std::map<std::string, double> by_state{{"tentative", 0.0}, {"confirmed", 0.0}, {"lost", 0.0}};
  for (const auto& t : report.tracks) by_state[tracking::trackStateName(t.state)] += 1.0;
  for (const auto& [state, n] : by_state) tracks_->Add({{"state", state}}).Set(n);
  setStaleness(report.camera_staleness_s);
}

void TrackerMetrics::cameraStaleness(const std::map<std::string, double>& seconds) {
  std::lock_guard lock(mutex_);
  setStaleness(seconds);
}

void TrackerMetrics::setStaleness(const std::map<std::string, double>& seconds) {
  for (const auto& [camera, s] : seconds) staleness_->Add({{"camera", camera}}).Set(std::max(0.0, s));
}

void TrackerMetrics::detectionsRefused(const std::string& reason) {
  const bool own = reason == "too_large" || reason == "clock_skew";
  dropped_->Add({{"reason", own ? reason : "refused"}}).Increment();
}

void TrackerMetrics::subscriberRefused() { metrics_.subscribersRefused(); }

void TrackerMetrics::globalMapRefused(const std::string& reason) { global_maps_refused_->Add({{"reason", reason}}).Increment(); }

void TrackerMetrics::centroidsReceived(const std::string& edge, std::size_t bytes) {
  centroid_frames_->Add({{"edge", edge}}).Increment();
  metrics_.bytesReceived(edge, "centroids", bytes);
}

void TrackerMetrics::centroidsRejected(const std::string& reason) { centroid_rejected_->Add({{"reason", reason}}).Increment(); }

}  // namespace fogmap
