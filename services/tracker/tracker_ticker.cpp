#include "services/tracker/tracker_ticker.hpp"

#include <utility>

namespace fogmap {

TrackerTicker::TrackerTicker(TrackerNode& node, TrackerMetrics& metrics, BurstLog& log, std::chrono::nanoseconds period,
                             std::shared_ptr<Pacer> pacer)
    : node_(node), metrics_(metrics), log_(log), ticks_([this] { tick(); }, period, std::move(pacer)) {}

void TrackerTicker::tick() {
  metrics_.cameraStaleness(node_.tick());
  log_.flush();
}

}  // namespace fogmap
