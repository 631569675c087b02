#include "services/tracker/tracker_process.hpp"

#include <iostream>
#include <utility>

#include "common/base/epochs.hpp"
#include "common/config/camera_node.hpp"
#include "common/config/tracker_node.hpp"
#include "services/common/grpc_options.hpp"
#include "services/tracker/tracker_hooks.hpp"

namespace fogmap {

Expected<std::unique_ptr<TrackerProcess>> TrackerProcess::create(const ServiceContext& context) {
  const TopologyConfig& topology = context.topology;
  std::vector<camera::PinholeCamera> cameras;
  std::vector<std::string> camera_names;
  for (const NodeConfig* c : topology.camerasOf(context.node.name)) {
    cameras.push_back(c->camera->calibration);
    camera_names.push_back(c->name);
  }
  auto tracker = tracking::Tracker::create(context.node.tracker->tracking, cameras);
  if (!tracker) return tracker.error();
  std::vector<std::string> edge_names;
  for (const NodeConfig* e : topology.centroidEdgesOf(context.node.name)) edge_names.push_back(e->name);
  std::optional<CentroidCollector> collector;
  if (context.node.tracker->input == TrackerInput::kCentroids) {
    const auto schedule = EpochSchedule::create(topology.period_ms, topology.deadline_ms);
    if (!schedule) return schedule.error();
    collector.emplace(centroidCollectorConfigFor(topology, context.node), *schedule);
  }
  return std::unique_ptr<TrackerProcess>(
      new TrackerProcess(context, std::move(*tracker), std::move(collector), camera_names, edge_names));
}

TrackerProcess::TrackerProcess(const ServiceContext& context, tracking::Tracker tracker,
                               std::optional<CentroidCollector> collector, const std::vector<std::string>& cameras,
                               const std::vector<std::string>& edges)
    : context_(context),
      tracker_metrics_(context.metrics, context.node.name, cameras, edges),
      refusal_log_(
          context.prefix(), [](const std::string& line) { std::cerr << line << "\n"; }, systemNowNs),
      node_(
          std::move(tracker), context.topology.madc.alpha, systemNowNs,
          [this](const TrackSnapshot& snapshot, const FusionReport& report) {
            tracker_metrics_.fused(report);
            service_.publish(snapshot);
          },
          std::move(collector), trackerNodeLimitsFor(context.topology)),
      service_(node_, cameras, context.tls.has_value(),
               trackerServiceHooks(context.metrics, tracker_metrics_, refusal_log_), kSubscriberQueue, kSubscriberPoll,
               context.topology.admission.max_subscribers),
      ticker_(node_, tracker_metrics_, refusal_log_) {
  context.metrics.periodSeconds(context.topology.period_ms / 1000.0);
}

ServiceLifecycle TrackerProcess::lifecycle() {
  ServiceLifecycle steps;
  steps.serving = [this](int /*port*/) {
    // Input global_map: the root's maps; input centroids: the edges' streams reach the service.
    if (context_.node.tracker->input != TrackerInput::kCentroids) {
      const NodeConfig& root = *context_.topology.root();
      feed_.emplace(makeChannel(endpoint(root.host, root.port), channelCredentials(context_.tls),
                                context_.topology.max_message_bytes),
                    globalMapFeedHooks(context_.metrics, tracker_metrics_, node_, refusal_log_, root.name));
    }
    ticker_.start();
  };
  steps.stop_accepting = [this] {
    ticker_.stop();
    if (feed_) feed_->stop();
  };
  steps.end_subscriptions = [this](std::chrono::milliseconds budget) { service_.shutdown(budget); };
  steps.flush = [this](std::chrono::milliseconds /*budget*/) { refusal_log_.flush(true); };
  return steps;
}

}  // namespace fogmap
