#pragma once
// The tracker's tick (docs/design.md "Tracker: admission and load"): every period (10 ms) the node
// fuses the LiDAR frames whose wait for late detections is over and offers the epochs of centroids
// whose deadline passed, even when nothing else arrives (a camera or an edge that stopped); the
// cameras' staleness gauges move, and quiet bursts of refusals are summarised.
#include <chrono>
#include <memory>

#include "common/base/burst_log.hpp"
#include "services/common/periodic.hpp"
#include "services/tracker/tracker_metrics.hpp"
#include "services/tracker/tracker_node.hpp"

namespace fogmap {

inline constexpr std::chrono::milliseconds kTrackerTick{10};

class TrackerTicker {
 public:
  // `pacer`: how the thread waits between ticks (empty: the steady clock).
  TrackerTicker(TrackerNode& node, TrackerMetrics& metrics, BurstLog& log,
                std::chrono::nanoseconds period = kTrackerTick, std::shared_ptr<Pacer> pacer = nullptr);

  // Ticks on a thread: at once, then every period, until stop().
  void start() { ticks_.start(); }
  // Returns once the tick in progress, if any, has ended.
  void stop() { ticks_.stop(); }
  // One tick, on the calling thread.
  void tick();

 private:
  TrackerNode& node_;
  TrackerMetrics& metrics_;
  BurstLog& log_;
  Periodic ticks_;  // last: its thread stops before the members it ticks with go
};

}  // namespace fogmap
