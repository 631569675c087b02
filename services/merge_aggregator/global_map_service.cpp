#include "services/merge_aggregator/global_map_service.hpp"

#include <algorithm>
#include <optional>
#include <string>
#include <utility>

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
      queue_capacity_(std::max<std::size_t>(1, queue_capacity)),
      max_subscribers_(aggregator.with([](MergeAggregator& core) { return core.config().admission.max_subscribers; })),
      poll_wait_(poll_wait) {}

void GlobalMapService::publish(const GlobalMapMessage& message) {
  // Converted once, shared by every subscriber; the label-free copy only when someone wants it.
  const auto full = std::make_shared<const v1::GlobalMap>(toProto(message));
  const Published with_labels{full, full->ByteSizeLong()};
  std::optional<Published> without_labels;
  std::uint64_t newly_dropped = 0;
  {
    std::lock_guard lock(mutex_);
    for (const auto& subscriber : subscribers_) {
      if (subscriber->on_time_only && message.late) continue;
      if (!subscriber->point_labels && !without_labels) {
        auto copy = std::make_shared<v1::GlobalMap>(*full);
        copy->clear_point_labels();
        const std::size_t bytes = copy->ByteSizeLong();
        without_labels = Published{std::move(copy), bytes};
      }
      subscriber->queue.push_back(subscriber->point_labels ? with_labels : *without_labels);
      while (subscriber->queue.size() > queue_capacity_) {
        subscriber->queue.pop_front();
        ++dropped_;
        ++newly_dropped;
      }
    }
  }
  published_.notify_all();
  if (newly_dropped > 0 && metrics_ != nullptr) metrics_->subscriberDrops(newly_dropped);
}

void GlobalMapService::shutdown(std::chrono::milliseconds drain) {
  std::unique_lock lock(mutex_);
  shutting_down_ = true;
  published_.notify_all();
  // The handlers end themselves once their queues are empty (or the client is gone).
  drained_.wait_for(lock, drain, [&] { return subscribers_.empty(); });
  drain_expired_ = true;
  published_.notify_all();
}

std::size_t GlobalMapService::subscriberCount() const {
  std::lock_guard lock(mutex_);
  return subscribers_.size();
}

std::uint64_t GlobalMapService::droppedMessages() const {
  std::lock_guard lock(mutex_);
  return dropped_;
}

std::uint64_t GlobalMapService::refusedSubscribers() const {
  std::lock_guard lock(mutex_);
  return refused_subscribers_;
}

grpc::Status GlobalMapService::Subscribe(grpc::ServerContext* context, const v1::SubscribeRequest* request,
                                         grpc::ServerWriter<v1::GlobalMap>* writer) {
  auto subscriber = std::make_shared<Subscriber>();
  subscriber->point_labels = request->include_point_labels();
  subscriber->on_time_only = request->on_time_only();
  {
    std::lock_guard lock(mutex_);
    if (shutting_down_) return {grpc::StatusCode::UNAVAILABLE, "the aggregator is shutting down"};
    if (subscribers_.size() >= max_subscribers_) {
      ++refused_subscribers_;
      if (metrics_ != nullptr) metrics_->subscribersRefused();
      return {grpc::StatusCode::RESOURCE_EXHAUSTED,
              "the root already serves " + std::to_string(subscribers_.size()) +
                  " subscribers, its bound (topology admission.max_subscribers); retry later"};
    }
    subscribers_.push_back(subscriber);
  }
  struct Unsubscribe {
    GlobalMapService& service;
    const std::shared_ptr<Subscriber>& subscriber;
    ~Unsubscribe() {
      {
        std::lock_guard lock(service.mutex_);
        std::erase(service.subscribers_, subscriber);
      }
      service.drained_.notify_all();
    }
  } unsubscribe{*this, subscriber};

  // Bounded waits: a cancelled client raises no condition variable, so look again regularly.
  while (!context->IsCancelled()) {
    Published next;
    {
      std::unique_lock lock(mutex_);
      published_.wait_for(lock, poll_wait_, [&] { return shutting_down_ || !subscriber->queue.empty(); });
      // What was published before the shutdown is still delivered (within the drain time).
      if (shutting_down_ && (subscriber->queue.empty() || drain_expired_)) {
        return {grpc::StatusCode::UNAVAILABLE, "the aggregator is shutting down"};
      }
      if (subscriber->queue.empty()) continue;
      next = std::move(subscriber->queue.front());
      subscriber->queue.pop_front();
    }
    if (!writer->Write(*next.map)) break;  // the client is gone
    if (metrics_ != nullptr) metrics_->bytesSent("subscriber", "global_map", next.bytes);
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
