#pragma once
// One tracker process as its topology node says: the tracker core (TrackerNode) with its metrics
// and its one log of refusals, the adapter (TrackerService), its LiDAR input (the feed of the root's
// global maps, or the collector of its edges' centroids, which reach the adapter) and its tick; and
// how it serves and stops (serveUntilStopped):
//   serving:           the feed subscribes to the root (input global_map), the tick runs
//   stop accepting:    the tick ends, the feed unsubscribes
//   end subscriptions: subscribers read the tracks queued for them
//   flush:             every burst of refusals still counting is written
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/base/burst_log.hpp"
#include "common/base/status.hpp"
#include "services/common/service_main.hpp"
#include "services/tracker/global_map_feed.hpp"
#include "services/tracker/tracker_metrics.hpp"
#include "services/tracker/tracker_node.hpp"
#include "services/tracker/tracker_service.hpp"
#include "services/tracker/tracker_ticker.hpp"

namespace fogmap {

class TrackerProcess {
 public:
  // Track lists a subscriber may lag behind, and how often its handler looks for a cancelled client.
  static constexpr std::size_t kSubscriberQueue = 16;
  static constexpr std::chrono::milliseconds kSubscriberPoll{100};

  // Builds everything from `context` (which must outlive it); an error when the node's tracker
  // settings or the topology's schedule are invalid.
  static Expected<std::unique_ptr<TrackerProcess>> create(const ServiceContext& context);
  TrackerProcess(const TrackerProcess&) = delete;
  TrackerProcess& operator=(const TrackerProcess&) = delete;

  std::vector<grpc::Service*> services() { return {&service_}; }
  ServiceLifecycle lifecycle();

 private:
  TrackerProcess(const ServiceContext& context, tracking::Tracker tracker, std::optional<CentroidCollector> collector,
                 const std::vector<std::string>& cameras, const std::vector<std::string>& edges);

  const ServiceContext& context_;
  TrackerMetrics tracker_metrics_;
  BurstLog refusal_log_;
  TrackerNode node_;
  TrackerService service_;  // after the node, which publishes to it only once frames arrive
  std::optional<GlobalMapFeed> feed_;  // input global_map, once serving
  TrackerTicker ticker_;               // last: stopped before what it ticks goes
};

}  // namespace fogmap
