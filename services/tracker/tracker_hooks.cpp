#include "services/tracker/tracker_hooks.hpp"

namespace fogmap {

TrackerServiceHooks trackerServiceHooks(Metrics& metrics, TrackerMetrics& tracker_metrics, BurstLog& log) {
  TrackerServiceHooks hooks;
  hooks.on_detections = [&metrics](const std::string& camera, std::size_t bytes) {
    metrics.bytesReceived(camera, "detections", bytes);
  };
  hooks.on_refused = [&tracker_metrics, &log](const std::string& reason, const std::string& why) {
    tracker_metrics.detectionsRefused(reason);
    log.note("refused detection frames (" + reason + ")", why);
  };
  hooks.on_subscriber_drops = [&metrics](std::uint64_t n) { metrics.subscriberDrops(n); };
  hooks.on_subscriber_refused = [&tracker_metrics, &log] {
    tracker_metrics.subscriberRefused();
    log.note("refused subscribers", "Subscribe beyond admission max_subscribers");
  };
  hooks.on_centroids = [&tracker_metrics](const std::string& edge, std::size_t bytes) {
    tracker_metrics.centroidsReceived(edge, bytes);
  };
  hooks.on_centroids_refused = [&tracker_metrics, &log](const std::string& reason, const std::string& why) {
    tracker_metrics.centroidsRejected(reason);
    log.note("refused centroid frames (" + reason + ")", why);
  };
  return hooks;
}

GlobalMapFeedHooks globalMapFeedHooks(Metrics& metrics, TrackerMetrics& tracker_metrics, TrackerNode& node, BurstLog& log,
                                      const std::string& root) {
  GlobalMapFeedHooks hooks;
  hooks.on_map = [&metrics, &tracker_metrics, &node, &log, root](const GlobalMapMessage& global, std::size_t bytes) {
    metrics.bytesReceived(root, "global_map", bytes);
    if (auto refused = node.addGlobalMap(global)) {
      tracker_metrics.globalMapRefused(refused->reason);
      log.note("refused global maps (" + refused->reason + ")", refused->detail);
    }
  };
  hooks.on_malformed = [&metrics, &log](const std::string& why) {
    metrics.malformed("global_map");
    log.note("malformed global maps", why);
  };
  hooks.on_reconnect = [&metrics] { metrics.reconnects(); };
  return hooks;
}

}  // namespace fogmap
