#pragma once
// What the tracker process does with what its adapter and its global-map feed see: counts it in the
// metrics, and logs every refusal and drop through one BurstLog (common/base/burst_log.hpp), so a
// flood of bad frames writes one line per reason per burst with a count, not one line per frame.
#include <string>

#include "common/base/burst_log.hpp"
#include "services/common/metrics.hpp"
#include "services/tracker/global_map_feed.hpp"
#include "services/tracker/tracker_metrics.hpp"
#include "services/tracker/tracker_node.hpp"
#include "services/tracker/tracker_service.hpp"

namespace fogmap {

// The adapter's hooks: frames accepted and refused (by reason) counted, refusals logged to `log`.
TrackerServiceHooks trackerServiceHooks(Metrics& metrics, TrackerMetrics& tracker_metrics, BurstLog& log);

// The global-map feed's hooks: each map counted and handed to `node`; malformed ones and the ones
// the node refuses counted and logged to `log`; reconnects counted. `root` names the root in the
// byte counts.
GlobalMapFeedHooks globalMapFeedHooks(Metrics& metrics, TrackerMetrics& tracker_metrics, TrackerNode& node, BurstLog& log,
                                      const std::string& root);

}  // namespace fogmap
