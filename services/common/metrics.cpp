#include "services/common/metrics.hpp"

#include "services/common/http_stop.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <utility>

#include "common/config/admission.hpp"
#include "common/base/clock.hpp"

namespace fogmap {
namespace {

// What an edge reports as malformed (EdgeRunner): scan files, frames, scans with non-finite points.
constexpr const char* kMalformedKinds[] = {"scan", "non_finite_points", "frame"};

using prometheus::Histogram;
using prometheus::Labels;
using prometheus::Registry;

prometheus::Family<prometheus::Counter>& counterFamily(Registry& registry, const std::string& name,
                                                       const std::string& help, const Labels& constant) {
  return prometheus::BuildCounter().Name(name).Help(help).Labels(constant).Register(registry);
}

prometheus::Counter& counter(Registry& registry, const std::string& name, const std::string& help,
                             const Labels& constant) {
  return counterFamily(registry, name, help, constant).Add({});
}

prometheus::Gauge& gauge(Registry& registry, const std::string& name, const std::string& help,
                         const Labels& constant) {
  return prometheus::BuildGauge().Name(name).Help(help).Labels(constant).Register(registry).Add({});
}

Histogram& histogram(Registry& registry, const std::string& name, const std::string& help, const Labels& constant,
                     Histogram::BucketBoundaries buckets) {
  return prometheus::BuildHistogram().Name(name).Help(help).Labels(constant).Register(registry).Add(
      {}, std::move(buckets));
}

}  // namespace

Metrics::Metrics(const std::string& bind_address, const std::string& service, const std::string& node)
    : registry_(std::make_shared<Registry>()) {
  const Labels c{{"service", service}, {"node", node}};
  Registry& r = *registry_;
  bytes_sent_ = &counterFamily(r, "fogmap_bytes_sent_total", "Serialised bytes sent, by peer and message kind.", c);
  bytes_received_ =
      &counterFamily(r, "fogmap_bytes_received_total", "Serialised bytes received, by peer and message kind.", c);
  maps_in_ = &counter(r, "fogmap_maps_in_total", "Maps received from children.", c);
  maps_out_ = &counter(r, "fogmap_maps_out_total", "Maps sent to the parent or subscribers.", c);
  points_in_ = &counter(r, "fogmap_points_in_total", "Points received (baseline and ext modes).", c);
  points_out_ = &counter(r, "fogmap_points_out_total", "Points sent (baseline and ext modes).", c);
  // Clustering one scan takes milliseconds to a second or two.
  clustering_seconds_ = &histogram(r, "fogmap_clustering_seconds", "Time to cluster one scan.", c,
                                   {0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5});
  // MERGE of summaries is sub-millisecond to about a second.
  merge_seconds_ = &histogram(r, "fogmap_merge_seconds", "Time to merge one epoch's maps.", c,
                              {0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1});
  pairs_tested_ = &counter(r, "fogmap_merge_pairs_tested_total",
                           "Ellipsoid pairs given the exact intersection test after box pruning.", c);
  pairs_pruned_ = &counter(r, "fogmap_merge_pairs_pruned_total",
                           "Cross-node ellipsoid pairs ruled out by box pruning.", c);
  end_to_end_seconds_ = &histogram(r, "fogmap_end_to_end_seconds",
                                   "Time from the earliest sensor timestamp to the global map.", c,
                                   {0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2});
  children_live_ = &gauge(r, "fogmap_children_live", "Children that delivered the last epoch in time.", c);
  children_stale_ = &gauge(r, "fogmap_children_stale", "Children that missed the last epoch (dead or late).", c);
  malformed_ = &counterFamily(r, "fogmap_malformed_inputs_total", "Inputs rejected as malformed, by kind.", c);
  late_maps_ = &counter(r, "fogmap_late_maps_total", "Maps that arrived after their epoch was emitted.", c);
  reconnects_ = &counter(r, "fogmap_reconnects_total", "Upload streams re-opened after a failure.", c);
  link_stalls_ = &counter(r, "fogmap_link_stalls_total",
                          "Upload streams given up because the parent owed an answer for too long.", c);
  link_last_stall_ = &gauge(r, "fogmap_link_last_stall_time_seconds",
                            "Unix time at which the upload stream was last given up (0: never).", c);
  duplicate_uploads_ = &counter(r, "fogmap_duplicate_uploads_total",
                                "Re-sent copies of uploads already applied: recognised, answered, not applied again.", c);
  dropped_uploads_ = &counter(r, "fogmap_dropped_uploads_total",
                              "Unacknowledged uploads dropped because the send queue was full.", c);
  frames_ = &counter(r, "fogmap_frames_total", "Sensor frames processed.", c);
  refused_ = &counterFamily(r, "fogmap_refused_uploads_total",
                            "Uploads refused by an admission rule, by reason (clock_skew, forged_node, ...).", c);
  dropped_epochs_ = &counter(r, "fogmap_dropped_epochs_total", "Epochs dropped without being emitted.", c);
  fragments_unpublished_ = &counter(r, "fogmap_fragments_unpublished_total",
                                    "Root: merged objects left out of the published map for having fewer than "
                                    "min_points points over all their sensors (lone fragments).",
                                    c);
  caught_up_epochs_ = &counter(r, "fogmap_caught_up_epochs_total",
                               "Root: epochs published late because the emitter did not poll in time (a stall).", c);
  longest_poll_gap_ = &gauge(r, "fogmap_emitter_longest_poll_gap_seconds",
                             "The longest time between two polls of the aggregator's emitter.", c);
  subscriber_drops_ = &counter(r, "fogmap_subscriber_drops_total",
                               "Global maps a slow subscriber lost from its bounded queue.", c);
  subscribers_refused_ = &counter(r, "fogmap_subscribers_refused_total",
                                  "Subscribe calls refused: the service already serves admission.max_subscribers.", c);
  geofences_denied_ = &counter(r, "fogmap_geofence_denied_total",
                               "SetGeofence calls refused: the peer's certificate is not a geofence client.", c);
  late_emits_ = &counter(r, "fogmap_late_emits_total",
                         "Epochs emitted as late revisions (late maps merged in, or emitted after a stall).", c);
  uploads_refused_ = &counter(r, "fogmap_uploads_refused_by_parent_total",
                              "Uploads the parent answered as refused (not re-sent).", c);
  failed_frames_ = &counter(r, "fogmap_failed_frames_total",
                            "Frames that could not be read or processed (sent as empty maps flagged failed).", c);
  dropped_points_ = &counterFamily(r, "fogmap_dropped_points_total",
                                  "Scan points dropped before processing, by reason (non_finite: a NaN or infinite "
                                  "coordinate).",
                                  c);
  padded_scans_ = &counter(r, "fogmap_padded_scans_total",
                           "Scan files accepted with zero padding after their declared points.", c);
  period_seconds_ = &gauge(r, "fogmap_period_seconds", "The sensor period of the topology (one epoch).", c);
  // Root-only series appear with the root's first live global map, not on every service.
  global_objects_ = &prometheus::BuildGauge()
                         .Name("fogmap_global_objects")
                         .Help("Root: objects in the latest live global map.")
                         .Labels(c)
                         .Register(r);
  sensor_missing_ = &prometheus::BuildGauge()
                         .Name("fogmap_sensor_missing")
                         .Help("Root: 1 when the sensor is missing from the latest live global map, 0 when it is in it.")
                         .Labels(c)
                         .Register(r);
  baseline_bytes_ = &counter(r, "fogmap_baseline_equivalent_bytes_total",
                             "Edge: bytes the frames' points would have cost on the wire in baseline mode.", c);
  // Labelled series exist from the start at 0, so rates and alerts over them have data before the
  // first rejection (Prometheus's advice: initialise the label values you know).
  for (int reason = 0; reason <= static_cast<int>(kLastRefusal); ++reason) {
    refused_->Add({{"reason", refusalName(static_cast<Refusal>(reason))}});
  }
  for (const char* what : kMalformedKinds) malformed_->Add({{"what", what}});
  serve(bind_address);
}

void Metrics::serve(const std::string& bind_address) {
  if (!bind_address.empty() && !exposer_) {
    host_ = bind_address.substr(0, bind_address.rfind(':'));
    try {
      exposer_ = std::make_unique<prometheus::Exposer>(bind_address);
    } catch (const std::exception&) {
      // civetweb only says "null context when constructing CivetServer"; a bind failure is almost
      // always another process on the port.
      throw std::runtime_error("cannot serve /metrics on " + bind_address +
                               ": the port is in use (or the address is not one of this host's)");
    }
    exposer_->RegisterCollectable(registry_);
  }
}

Metrics::~Metrics() {
  if (!exposer_) return;
  stopHttpServer([this] { exposer_.reset(); }, host_, listeningPort());
}

int Metrics::listeningPort() const {
  if (!exposer_) return 0;
  const auto ports = exposer_->GetListeningPorts();
  return ports.empty() ? 0 : ports.front();
}

void Metrics::bytesSent(const std::string& peer, const std::string& kind, std::size_t bytes) {
  bytes_sent_->Add({{"peer", peer}, {"kind", kind}}).Increment(static_cast<double>(bytes));
}
void Metrics::bytesReceived(const std::string& peer, const std::string& kind, std::size_t bytes) {
  bytes_received_->Add({{"peer", peer}, {"kind", kind}}).Increment(static_cast<double>(bytes));
}
void Metrics::mapsIn(std::uint64_t n) { maps_in_->Increment(static_cast<double>(n)); }
void Metrics::mapsOut(std::uint64_t n) { maps_out_->Increment(static_cast<double>(n)); }
void Metrics::pointsIn(std::uint64_t n) { points_in_->Increment(static_cast<double>(n)); }
void Metrics::pointsOut(std::uint64_t n) { points_out_->Increment(static_cast<double>(n)); }
void Metrics::clusteringSeconds(double s) { clustering_seconds_->Observe(s); }
void Metrics::mergeSeconds(double s) { merge_seconds_->Observe(s); }
void Metrics::pairs(std::uint64_t tested, std::uint64_t pruned) {
  pairs_tested_->Increment(static_cast<double>(tested));
  pairs_pruned_->Increment(static_cast<double>(pruned));
}
void Metrics::endToEndSeconds(double s) { end_to_end_seconds_->Observe(s); }
void Metrics::childrenLive(double n) { children_live_->Set(n); }
void Metrics::childrenStale(double n) { children_stale_->Set(n); }
void Metrics::malformed(const std::string& what) { malformed_->Add({{"what", what}}).Increment(); }
void Metrics::lateMaps(std::uint64_t n) { late_maps_->Increment(static_cast<double>(n)); }
void Metrics::reconnects() { reconnects_->Increment(); }
void Metrics::linkStalls() {
  link_stalls_->Increment();
  link_last_stall_->Set(static_cast<double>(systemNowNs()) * 1e-9);
}
void Metrics::duplicateUploads(std::uint64_t n) { duplicate_uploads_->Increment(static_cast<double>(n)); }
void Metrics::droppedUploads() { dropped_uploads_->Increment(); }
void Metrics::framesProcessed() { frames_->Increment(); }
void Metrics::refused(const std::string& reason, std::uint64_t n) {
  refused_->Add({{"reason", reason}}).Increment(static_cast<double>(n));
}
void Metrics::droppedEpochs(std::uint64_t n) { dropped_epochs_->Increment(static_cast<double>(n)); }
void Metrics::fragmentsUnpublished(std::uint64_t n) { fragments_unpublished_->Increment(static_cast<double>(n)); }
void Metrics::caughtUpEpochs(std::uint64_t n) { caught_up_epochs_->Increment(static_cast<double>(n)); }
void Metrics::longestPollGapSeconds(double s) { longest_poll_gap_->Set(s); }
void Metrics::subscriberDrops(std::uint64_t n) { subscriber_drops_->Increment(static_cast<double>(n)); }
void Metrics::subscribersRefused() { subscribers_refused_->Increment(); }
void Metrics::lateEmits(std::uint64_t n) { late_emits_->Increment(static_cast<double>(n)); }
void Metrics::geofencesDenied() { geofences_denied_->Increment(); }

void Metrics::periodSeconds(double s) { period_seconds_->Set(s); }
void Metrics::globalObjects(double n) { global_objects_->Add({}).Set(n); }
void Metrics::sensorMissing(const std::string& sensor, bool missing) {
  sensor_missing_->Add({{"sensor", sensor}}).Set(missing ? 1.0 : 0.0);
}
void Metrics::baselineBytes(std::size_t bytes) { baseline_bytes_->Increment(static_cast<double>(bytes)); }

void Metrics::uploadsRefused() { uploads_refused_->Increment(); }
void Metrics::failedFrames() { failed_frames_->Increment(); }
void Metrics::paddedScans() { padded_scans_->Increment(); }
void Metrics::droppedPoints(const std::string& reason, std::uint64_t n) {
  dropped_points_->Add({{"reason", reason}}).Increment(static_cast<double>(n));
}

}  // namespace fogmap
