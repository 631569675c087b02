#pragma once
// gRPC adapter for GlobalMapService (the root only): live global maps for subscribers, and
// geofences set and queried on the latest global map.
//
// Every subscriber has its own bounded queue: a slow subscriber loses its oldest global maps
// (counted) and never slows the emitter or the other subscribers. At most the topology's
// admission.max_subscribers streams are served at once; one more is refused RESOURCE_EXHAUSTED
// (counted), so subscribers that never read cannot hold memory without bound.
//
// With TLS (allowGeofenceSetters) only the certificate names listed may call SetGeofence; any other
// peer is answered PERMISSION_DENIED and counted. Subscribe and QueryGeofences are open to every
// peer the server let in (any certificate the CA issued).
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/broadcaster.hpp"
#include "services/common/metrics.hpp"
#include "services/merge_aggregator/aggregator_runtime.hpp"

namespace fogmap {

class GlobalMapService final : public v1::GlobalMapService::Service {
 public:
  // `metrics` may be null. `poll_wait` bounds how long a Subscribe handler sleeps before it looks
  // for a cancelled client again.
  GlobalMapService(SharedAggregator& aggregator, Metrics* metrics, std::size_t queue_capacity = 16,
                   std::chrono::milliseconds poll_wait = std::chrono::milliseconds(100));

  // Queues the global map for every subscriber (the emitter's publish sink).
  void publish(const GlobalMapMessage& message);
  // Refuses new subscribers and ends every Subscribe call (UNAVAILABLE) once it has written what
  // is queued for it, or after `drain` at the most; call before Server::Shutdown.
  void shutdown(std::chrono::milliseconds drain = std::chrono::milliseconds(500));
  std::size_t subscriberCount() const;
  std::uint64_t droppedMessages() const;
  // Subscribe calls refused because max_subscribers streams were being served.
  std::uint64_t refusedSubscribers() const;
  // From now on SetGeofence is allowed only to peers whose certificate names one of `names`. Set
  // before the server starts.
  void allowGeofenceSetters(std::vector<std::string> names) { geofence_setters_ = std::move(names); }
  // SetGeofence calls refused because the peer may not set geofences.
  std::uint64_t deniedGeofences() const { return denied_geofences_.load(); }

  grpc::Status Subscribe(grpc::ServerContext* context, const v1::SubscribeRequest* request,
                         grpc::ServerWriter<v1::GlobalMap>* writer) override;
  grpc::Status SetGeofence(grpc::ServerContext* context, const v1::Geofence* request,
                           v1::SetGeofenceReply* reply) override;
  grpc::Status QueryGeofences(grpc::ServerContext* context, const v1::GeofenceQuery* request,
                              v1::GeofenceReport* reply) override;

 private:
  // A global map shared by every subscriber that wants this form of it, with its wire size.
  struct Published {
    std::shared_ptr<const v1::GlobalMap> map;
    std::size_t bytes = 0;
  };
  // What a subscriber asked for.
  struct Wants {
    bool point_labels = false;
    bool on_time_only = false;
  };
  using Subscribers = Broadcaster<Published, Wants>;

  SharedAggregator& aggregator_;
  Metrics* metrics_;
  std::chrono::milliseconds poll_wait_;
  Subscribers subscribers_;  // bounded by the core's admission.max_subscribers
  std::optional<std::vector<std::string>> geofence_setters_;  // none: everyone may (plaintext)
  std::atomic<std::uint64_t> denied_geofences_{0};
};

}  // namespace fogmap
