#include "services/tracker/tracker_service.hpp"

#include <algorithm>
#include <optional>
#include <utility>
#include <variant>

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
      poll_wait_(poll_wait),
      subscribers_(queue_capacity, max_subscribers,
                   BroadcasterHooks{hooks_.on_subscriber_drops, hooks_.on_subscriber_refused}) {}

void TrackerService::publish(const TrackSnapshot& snapshot) {
  subscribers_.publish(std::make_shared<const TrackSnapshot>(snapshot));
}

void TrackerService::shutdown(std::chrono::milliseconds drain) { subscribers_.shutdown(drain); }

std::size_t TrackerService::subscriberCount() const { return subscribers_.subscriberCount(); }

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
  using Subscribers = decltype(subscribers_);
  auto joined = subscribers_.subscribe();
  if (const auto* refusal = std::get_if<Subscribers::Refusal>(&joined)) {
    if (*refusal == Subscribers::Refusal::kShuttingDown) {
      return {grpc::StatusCode::UNAVAILABLE, "the tracker is shutting down"};
    }
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, "the tracker already serves " +
                                                      std::to_string(subscribers_.maxSubscribers()) +
                                                      " subscribers (admission max_subscribers)"};
  }
  auto& subscription = std::get<Subscribers::Subscription>(joined);
  const bool include_tentative = request->include_tentative();
  // Bounded waits: a cancelled client raises no condition variable, so look again regularly.
  while (!context->IsCancelled()) {
    auto next = subscription.next(poll_wait_);
    if (next.ended) return {grpc::StatusCode::UNAVAILABLE, "the tracker is shutting down"};
    if (!next.message) continue;
    if (!writer->Write(toTrackList(**next.message, include_tentative))) break;  // the client is gone
  }
  return grpc::Status::OK;
}

}  // namespace fogmap
