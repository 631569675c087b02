#include "services/merge_aggregator/global_map_service.hpp"

#include <algorithm>
#include <optional>
#include <string>
#include <utility>
#include <variant>

#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"

namespace fogmap {
namespace {

// The geofence report's domain type belongs to the aggregator core; its conversion lives here.
v1::Vec3 toProto(const Eigen::Vector3d& v) {
  v1::Vec3 out;
  out.set_x(v.x());
  out.set_y(v.y());
  out.set_z(v.z());
  return out;
}

v1::GeofenceReport toProto(const GeofenceReport& report) {
  v1::GeofenceReport out;
  out.set_epoch(report.epoch);
  for (const auto& intrusion : report.intrusions) {
    auto* proto = out.add_intrusions();
    proto->set_geofence(intrusion.geofence);
    proto->set_object_index(static_cast<std::uint32_t>(intrusion.object_index));
    proto->set_containment(toProto(intrusion.containment));
    *proto->mutable_box()->mutable_min() = toProto(intrusion.box.min);
    *proto->mutable_box()->mutable_max() = toProto(intrusion.box.max);
    for (const auto& id : intrusion.ellipsoids) {
      auto* proto_id = proto->add_ellipsoids();
      proto_id->set_node(id.node);
      proto_id->set_frame(id.frame);
      proto_id->set_index(id.index);
    }
  }
  return out;
}

}  // namespace

GlobalMapService::GlobalMapService(SharedAggregator& aggregator, Metrics* metrics, std::size_t queue_capacity,
                                   std::chrono::milliseconds poll_wait)
    : aggregator_(aggregator),
      metrics_(metrics),
      poll_wait_(poll_wait),
      subscribers_(queue_capacity,
                   aggregator.with([](MergeAggregator& core) { return core.config().admission.max_subscribers; }),
                   BroadcasterHooks{[metrics](std::uint64_t n) {
                                      if (metrics != nullptr) metrics->subscriberDrops(n);
                                    },
                                    [metrics] {
                                      if (metrics != nullptr) metrics->subscribersRefused();
                                    }}) {}

void GlobalMapService::publish(const GlobalMapMessage& message) {
  // Converted once, shared by every subscriber; the label-free copy only when someone wants it.
  const auto full = std::make_shared<const v1::GlobalMap>(toProto(message));
  const Published with_labels{full, full->ByteSizeLong()};
  std::optional<Published> without_labels;
  subscribers_.publishEach([&](const Wants& wants) -> std::optional<Published> {
    if (wants.on_time_only && message.late) return std::nullopt;
    if (wants.point_labels) return with_labels;
    if (!without_labels) {
      auto copy = std::make_shared<v1::GlobalMap>(*full);
      copy->clear_point_labels();
      const std::size_t bytes = copy->ByteSizeLong();
      without_labels = Published{std::move(copy), bytes};
    }
    return without_labels;
  });
}

void GlobalMapService::shutdown(std::chrono::milliseconds drain) { subscribers_.shutdown(drain); }

std::size_t GlobalMapService::subscriberCount() const { return subscribers_.subscriberCount(); }

std::uint64_t GlobalMapService::droppedMessages() const { return subscribers_.dropped(); }

std::uint64_t GlobalMapService::refusedSubscribers() const { return subscribers_.refused(); }

grpc::Status GlobalMapService::Subscribe(grpc::ServerContext* context, const v1::SubscribeRequest* request,
                                         grpc::ServerWriter<v1::GlobalMap>* writer) {
  auto joined = subscribers_.subscribe({request->include_point_labels(), request->on_time_only()});
  if (const auto* refusal = std::get_if<Subscribers::Refusal>(&joined)) {
    if (*refusal == Subscribers::Refusal::kShuttingDown) {
      return {grpc::StatusCode::UNAVAILABLE, "the aggregator is shutting down"};
    }
    return {grpc::StatusCode::RESOURCE_EXHAUSTED,
            "the root already serves " + std::to_string(subscribers_.maxSubscribers()) +
                " subscribers, its bound (topology admission.max_subscribers); retry later"};
  }
  auto& subscription = std::get<Subscribers::Subscription>(joined);
  // Bounded waits: a cancelled client raises no condition variable, so look again regularly.
  while (!context->IsCancelled()) {
    auto next = subscription.next(poll_wait_);
    if (next.ended) return {grpc::StatusCode::UNAVAILABLE, "the aggregator is shutting down"};
    if (!next.message) continue;
    if (!writer->Write(*next.message->map)) break;  // the client is gone
    if (metrics_ != nullptr) metrics_->bytesSent("subscriber", "global_map", next.message->bytes);
  }
  return grpc::Status::OK;
}

grpc::Status GlobalMapService::SetGeofence(grpc::ServerContext* context, const v1::Geofence* request,
                                           v1::SetGeofenceReply* reply) {
  if (geofence_setters_) {
    const std::optional<std::string> peer = peerCertificateName(*context);
    if (!peer || std::find(geofence_setters_->begin(), geofence_setters_->end(), *peer) == geofence_setters_->end()) {
      ++denied_geofences_;
      if (metrics_ != nullptr) metrics_->geofencesDenied();
      std::string message = peer ? "'" + *peer + "'" : std::string("a peer without a certificate name");
      message += " may not set geofences: the topology's tls.geofence_clients does not list it";
      return {grpc::StatusCode::PERMISSION_DENIED, message};
    }
  }
  auto fence = fromProto(*request);
  if (!fence) return toGrpcStatus(fence.error());
  const auto count = aggregator_.with([&](MergeAggregator& core) { return core.setGeofence(std::move(*fence)); });
  if (!count) return toGrpcStatus(count.error());
  reply->set_geofence_count(static_cast<std::uint32_t>(*count));
  return grpc::Status::OK;
}

grpc::Status GlobalMapService::QueryGeofences(grpc::ServerContext* /*context*/, const v1::GeofenceQuery* request,
                                              v1::GeofenceReport* reply) {
  const auto report = aggregator_.with([&](const MergeAggregator& core) { return core.queryGeofences(request->name()); });
  if (!report) return toGrpcStatus(report.error());
  *reply = toProto(*report);
  return grpc::Status::OK;
}

}  // namespace fogmap
