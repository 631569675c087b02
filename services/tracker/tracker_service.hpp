#pragma once
// gRPC adapter for TrackerService: detection services push their cameras' detections and edges
// their displacement centroids (validated by proto_convert, refusals counted), subscribers read the
// tracks. Every subscriber has its own bounded queue: a slow one loses its oldest track lists
// (counted), never slows fusion; and their number is bounded (one more is refused, counted).
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/broadcaster.hpp"
#include "services/tracker/tracker_node.hpp"

namespace fogmap {

// What the adapter saw, for the metrics.
struct TrackerServiceHooks {
  std::function<void(const std::string& camera, std::size_t bytes)> on_detections;  // a frame accepted
  // A detection frame refused: `reason` is "malformed", "too_large" (more detections than a frame
  // may hold), "unknown_camera", "forged" or "clock_skew"; `why` a line for the log.
  std::function<void(const std::string& reason, const std::string& why)> on_refused;
  std::function<void(std::uint64_t n)> on_subscriber_drops;
  std::function<void()> on_subscriber_refused;  // a Subscribe call beyond max_subscribers
  std::function<void(const std::string& edge, std::size_t bytes)> on_centroids;  // a centroid frame accepted
  // A centroid frame refused: `reason` is "malformed", "too_large" (more centroids than a frame may
  // hold), "forged" or a CentroidVerdict's name (unknown_edge, late, clock_skew, duplicate), `why` a
  // line for the log.
  std::function<void(const std::string& reason, const std::string& why)> on_centroids_refused;
};

class TrackerService final : public v1::TrackerService::Service {
 public:
  // With TLS (`identify_by_certificate`) a stream may speak only for the camera (or edge) its
  // certificate names. `cameras`: the detection nodes whose frames are accepted; which edges' centroid
  // frames are is the node's (its CentroidCollector's) to say. At most `max_subscribers` Subscribe
  // calls are served at once (topology admission.max_subscribers); one more ends RESOURCE_EXHAUSTED.
  TrackerService(TrackerNode& node, std::vector<std::string> cameras, bool identify_by_certificate, TrackerServiceHooks hooks,
                 std::size_t queue_capacity = 16, std::chrono::milliseconds poll_wait = std::chrono::milliseconds(100),
                 std::size_t max_subscribers = 32);

  // Queues the tracks for every subscriber (TrackerNode's publish sink).
  void publish(const TrackSnapshot& snapshot);
  // Ends every Subscribe call once it has written what is queued, or after `drain`.
  void shutdown(std::chrono::milliseconds drain);
  std::size_t subscriberCount() const;

  grpc::Status PushDetections(grpc::ServerContext* context, grpc::ServerReader<v1::DetectionFrame>* reader,
                              v1::DetectionSummary* summary) override;
  grpc::Status PushCentroids(grpc::ServerContext* context, grpc::ServerReader<v1::CentroidFrame>* reader,
                             v1::CentroidSummary* summary) override;
  grpc::Status Subscribe(grpc::ServerContext* context, const v1::TrackSubscribeRequest* request,
                         grpc::ServerWriter<v1::TrackList>* writer) override;

 private:
  TrackerNode& node_;
  std::vector<std::string> cameras_;
  bool identify_by_certificate_;
  TrackerServiceHooks hooks_;
  std::chrono::milliseconds poll_wait_;
  Broadcaster<std::shared_ptr<const TrackSnapshot>> subscribers_;
};

// The tracks a subscriber sees: confirmed and lost ones, and tentative ones when asked.
v1::TrackList toTrackList(const TrackSnapshot& snapshot, bool include_tentative);

}  // namespace fogmap
