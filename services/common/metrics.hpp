#pragma once
// Prometheus metrics shared by the services (prometheus-cpp, pull model on /metrics). Names follow
// Prometheus conventions: fogmap_ prefix, base units (seconds, bytes), _total for counters; every
// series carries the constant labels service and node.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include <prometheus/counter.h>
#include <prometheus/exposer.h>
#include <prometheus/family.h>
#include <prometheus/gauge.h>
#include <prometheus/histogram.h>
#include <prometheus/registry.h>

namespace fogmap {

class Metrics {
 public:
  // Serves /metrics on bind_address (e.g. "127.0.0.1:9100"; port 0 picks a free port, see
  // listeningPort); an empty bind_address serves nothing (tests, tools). `service` and `node`
  // become constant labels. Throws std::runtime_error when the address cannot be bound.
  Metrics(const std::string& bind_address, const std::string& service, const std::string& node);
  // Starts serving /metrics on bind_address, once (a Metrics made with an empty address): a service
  // opens its port only after its own configuration is checked. Throws as the constructor does.
  void serve(const std::string& bind_address);
  // Stops serving within milliseconds (the HTTP server alone would take up to 2 s).
  ~Metrics();
  Metrics(const Metrics&) = delete;
  Metrics& operator=(const Metrics&) = delete;

  // The port /metrics is served on, 0 when nothing is served.
  int listeningPort() const;

  // `peer` names the other end (a node id or address), `kind` the message kind ("map", "points",
  // "global_map", ...).
  void bytesSent(const std::string& peer, const std::string& kind, std::size_t bytes);
  void bytesReceived(const std::string& peer, const std::string& kind, std::size_t bytes);
  void mapsIn(std::uint64_t n = 1);
  void mapsOut(std::uint64_t n = 1);
  void pointsIn(std::uint64_t n);
  void pointsOut(std::uint64_t n);
  void clusteringSeconds(double s);
  void mergeSeconds(double s);
  void pairs(std::uint64_t tested, std::uint64_t pruned);
  void endToEndSeconds(double s);
  void childrenLive(double n);
  void childrenStale(double n);
  // `what` names the rejected input kind ("map", "points", "geofence", ...).
  void malformed(const std::string& what);
  void lateMaps(std::uint64_t n = 1);
  // An upload refused by an admission rule; `reason` is refusalName(...) ("clock_skew", ...).
  void refused(const std::string& reason, std::uint64_t n = 1);
  // Epochs evicted or abandoned without being emitted (beyond the pending bound).
  void droppedEpochs(std::uint64_t n = 1);
  void fragmentsUnpublished(std::uint64_t n);
  // Root: epochs published late because it did not poll in time (a stall of its own), and the
  // longest time between two polls of its emitter.
  void caughtUpEpochs(std::uint64_t n = 1);
  void longestPollGapSeconds(double s);
  // Global maps a slow subscriber lost from its bounded queue.
  void subscriberDrops(std::uint64_t n = 1);
  // Subscribe calls refused because the service already serves admission.max_subscribers.
  void subscribersRefused();
  // SetGeofence calls refused because the peer's certificate is not a geofence client (TLS).
  void geofencesDenied();
  // Revisions of already emitted epochs (late maps merged in) and epochs emitted late (stall).
  void lateEmits(std::uint64_t n = 1);
  // Uploads the parent answered as refused (never re-sent).
  void uploadsRefused();
  // Frames the edge could not read or process (sent as empty maps flagged failed).
  void failedFrames();
  // Scan points dropped before processing; `reason` is "non_finite" (a NaN or infinite coordinate).
  void droppedPoints(const std::string& reason, std::uint64_t n);
  // Scan files with zero padding after their declared points (accepted).
  void paddedScans();
  void reconnects();
  // Upload streams given up because the parent stopped answering (ParentLink's answer timeout);
  // also sets fogmap_link_last_stall_time_seconds to now (unix time), so an observer can tell when
  // the link gave up, however late it scrapes.
  void linkStalls();
  // Re-sent copies of uploads already applied, recognised and not applied again.
  void duplicateUploads(std::uint64_t n = 1);
  void droppedUploads();
  void framesProcessed();
  // The topology's sensor period (one epoch), so alert rules compare latencies with it.
  void periodSeconds(double s);
  // Root: objects in the latest live global map.
  void globalObjects(double n);
  // Root: whether `sensor` (a node name) is missing from the latest live global map.
  void sensorMissing(const std::string& sensor, bool missing);
  // Edge (madc and ext modes): bytes the same frame's points would have cost on the wire in
  // baseline mode, so MAD-C's savings can be read beside what it sent.
  void baselineBytes(std::size_t bytes);

  prometheus::Registry& registry() { return *registry_; }

 private:
  std::shared_ptr<prometheus::Registry> registry_;
  std::unique_ptr<prometheus::Exposer> exposer_;
  std::string host_;  // of bind_address, where the exposer is reached to stop it
  prometheus::Family<prometheus::Counter>* bytes_sent_;
  prometheus::Family<prometheus::Counter>* bytes_received_;
  prometheus::Counter* maps_in_;
  prometheus::Counter* maps_out_;
  prometheus::Counter* points_in_;
  prometheus::Counter* points_out_;
  prometheus::Histogram* clustering_seconds_;
  prometheus::Histogram* merge_seconds_;
  prometheus::Counter* pairs_tested_;
  prometheus::Counter* pairs_pruned_;
  prometheus::Histogram* end_to_end_seconds_;
  prometheus::Gauge* children_live_;
  prometheus::Gauge* children_stale_;
  prometheus::Family<prometheus::Counter>* malformed_;
  prometheus::Counter* late_maps_;
  prometheus::Counter* reconnects_;
  prometheus::Counter* link_stalls_;
  prometheus::Gauge* link_last_stall_;
  prometheus::Counter* duplicate_uploads_;
  prometheus::Counter* dropped_uploads_;
  prometheus::Counter* frames_;
  prometheus::Family<prometheus::Counter>* refused_;
  prometheus::Counter* dropped_epochs_;
  prometheus::Counter* fragments_unpublished_;
  prometheus::Counter* caught_up_epochs_;
  prometheus::Gauge* longest_poll_gap_;
  prometheus::Counter* subscriber_drops_;
  prometheus::Counter* subscribers_refused_;
  prometheus::Counter* geofences_denied_;
  prometheus::Counter* late_emits_;
  prometheus::Counter* uploads_refused_;
  prometheus::Counter* failed_frames_;
  prometheus::Family<prometheus::Counter>* dropped_points_;
  prometheus::Counter* padded_scans_;
  prometheus::Gauge* period_seconds_;
  prometheus::Family<prometheus::Gauge>* global_objects_;
  prometheus::Family<prometheus::Gauge>* sensor_missing_;
  prometheus::Counter* baseline_bytes_;
};

}  // namespace fogmap
