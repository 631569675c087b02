#include "services/tracker/tracker_service.hpp"

#include <algorithm>
#include <utility>

#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"

namespace fogmap {

v1::TrackList toTrackList(const TrackSnapshot& snapshot, bool include_tentative) {
  v1::TrackList out;
  out.set_lidar_time_ns(snapshot.lidar_time_ns);
  out.set_published_time_ns(snapshot.published_time_ns);
  out.set_association(tracking::associationName(snapshot.association));
  for (const auto& track : snapshot.tracks) {
    if (track.state == tracking::TrackState::kTentative && !include_tentative) continue;
    *out.add_tracks() = toProto(track);
  }
  return out;
}

TrackerService::TrackerService(TrackerNode& node, std::vector<std::string> cameras, bool identify_by_certificate,
                               TrackerServiceHooks hooks, std::size_t queue_capacity, std::chrono::milliseconds poll_wait,
                               std::size_t max_subscribers)
    : node_(node),
      cameras_(std::move(cameras)),
      identify_by_certificate_(identify_by_certificate),
      hooks_(std::move(hooks)),
      queue_capacity_(std::max<std::size_t>(1, queue_capacity)),
      poll_wait_(poll_wait),
      max_subscribers_(max_subscribers) {}

void TrackerService::publish(const TrackSnapshot& snapshot) {
  const auto shared = std::make_shared<const TrackSnapshot>(snapshot);
  std::uint64_t dropped = 0;
  {
    std::lock_guard lock(mutex_);
    for (const auto& subscriber : subscribers_) {
      subscriber->queue.push_back(shared);
      while (subscriber->queue.size() > queue_capacity_) {
        subscriber->queue.pop_front();
        ++dropped;
      }
    }
  }
  published_.notify_all();
  if (dropped > 0 && hooks_.on_subscriber_drops) hooks_.on_subscriber_drops(dropped);
}

void TrackerService::shutdown(std::chrono::milliseconds drain) {
  std::unique_lock lock(mutex_);
  shutting_down_ = true;
  published_.notify_all();
  drained_.wait_for(lock, drain, [&] { return subscribers_.empty(); });
  drain_expired_ = true;
  published_.notify_all();
}

std::size_t TrackerService::subscriberCount() const {
  std::lock_guard lock(mutex_);
  return subscribers_.size();
}

grpc::Status TrackerService::PushDetections(grpc::ServerContext* context, grpc::ServerReader<v1::DetectionFrame>* reader,
                                            v1::DetectionSummary* summary) {
  std::optional<std::string> peer;
  if (identify_by_certificate_) {
    peer = peerCertificateName(*context);
    if (!peer) return {grpc::StatusCode::UNAUTHENTICATED, "the client's certificate names no camera"};
  }
  v1::DetectionFrame message;
  while (reader->Read(&message)) {
    summary->set_received(summary->received() + 1);
    const std::size_t bytes = message.ByteSizeLong();
    auto frame = fromProto(message);
    std::string reason;
    std::string refusal;
    if (!frame) {
      reason = frame.error().code == ErrorCode::kResourceExhausted ? "too_large" : "malformed";
      refusal = frame.error().message;
    } else if (std::find(cameras_.begin(), cameras_.end(), frame->camera) == cameras_.end()) {
      reason = "unknown_camera";
      refusal = "camera '" + frame->camera + "' is not a camera of this tracker";
    } else if (peer && *peer != frame->camera) {
      reason = "forged";
      refusal = "'" + *peer + "' may not speak for camera '" + frame->camera + "'";
    } else {
      const std::string camera = frame->camera;
      auto refused = node_.addDetections(std::move(*frame));
      if (!refused) {
        if (hooks_.on_detections) hooks_.on_detections(camera, bytes);
        continue;
      }
      reason = std::move(refused->reason);
      refusal = std::move(refused->detail);
    }
    summary->set_refused(summary->refused() + 1);
    summary->set_last_refusal(refusal);
    if (hooks_.on_refused) hooks_.on_refused(reason, refusal);
  }
  return grpc::Status::OK;
}

grpc::Status TrackerService::PushCentroids(grpc::ServerContext* context, grpc::ServerReader<v1::CentroidFrame>* reader,
                                           v1::CentroidSummary* summary) {
  std::optional<std::string> peer;
  if (identify_by_certificate_) {
    peer = peerCertificateName(*context);
    if (!peer) return {grpc::StatusCode::UNAUTHENTICATED, "the client's certificate names no edge"};
  }
  v1::CentroidFrame message;
  while (reader->Read(&message)) {
    summary->set_received(summary->received() + 1);
    const std::size_t bytes = message.ByteSizeLong();
    auto frame = fromProto(message);
    std::string reason;
    std::string refusal;
    if (!frame) {
      reason = frame.error().code == ErrorCode::kResourceExhausted ? "too_large" : "malformed";
      refusal = frame.error().message;
    } else if (peer && *peer != frame->edge) {
      reason = "forged";
      refusal = "'" + *peer + "' may not speak for edge '" + frame->edge + "'";
    } else {
      const std::string edge = frame->edge;
      const std::uint64_t epoch = frame->epoch;
      const auto admission = node_.addCentroids(std::move(*frame));
      if (admission.verdict == CentroidVerdict::kAccepted) {
        if (hooks_.on_centroids) hooks_.on_centroids(edge, bytes);
        continue;
      }
      reason = centroidVerdictName(admission.verdict);
      refusal = "edge '" + edge + "', epoch " + std::to_string(epoch) + ": " + reason +
                (admission.detail.empty() ? "" : ": " + admission.detail);
    }
    summary->set_refused(summary->refused() + 1);
    summary->set_last_refusal(refusal);
    if (hooks_.on_centroids_refused) hooks_.on_centroids_refused(reason, refusal);
  }
  return grpc::Status::OK;
}

grpc::Status TrackerService::Subscribe(grpc::ServerContext* context, const v1::TrackSubscribeRequest* request,
                                       grpc::ServerWriter<v1::TrackList>* writer) {
  auto subscriber = std::make_shared<Subscriber>();
  subscriber->include_tentative = request->include_tentative();
  bool full = false;
  {
    std::lock_guard lock(mutex_);
    if (shutting_down_) return {grpc::StatusCode::UNAVAILABLE, "the tracker is shutting down"};
    full = subscribers_.size() >= max_subscribers_;
    if (!full) subscribers_.push_back(subscriber);
  }
  if (full) {
    if (hooks_.on_subscriber_refused) hooks_.on_subscriber_refused();
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, "the tracker already serves " + std::to_string(max_subscribers_) +
                                                      " subscribers (admission max_subscribers)"};
  }
  const auto leave = [&] {
    std::lock_guard lock(mutex_);
    subscribers_.erase(std::remove(subscribers_.begin(), subscribers_.end(), subscriber), subscribers_.end());
    drained_.notify_all();
  };
  bool shut_down = false;
  while (!context->IsCancelled()) {
    std::shared_ptr<const TrackSnapshot> next;
    {
      std::unique_lock lock(mutex_);
      published_.wait_for(lock, poll_wait_, [&] { return !subscriber->queue.empty() || shutting_down_; });
      shut_down = shutting_down_;
      if (subscriber->queue.empty()) {
        if (shutting_down_) break;
        continue;
      }
      if (drain_expired_) break;
      next = subscriber->queue.front();
      subscriber->queue.pop_front();
    }
    if (!writer->Write(toTrackList(*next, subscriber->include_tentative))) break;
  }
  leave();
  return shut_down ? grpc::Status(grpc::StatusCode::UNAVAILABLE, "the tracker is shutting down") : grpc::Status::OK;
}

}  // namespace fogmap
