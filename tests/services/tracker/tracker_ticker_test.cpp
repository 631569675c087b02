// The tracker's tick on time the test moves by hand (the node's clock, the burst log's and the
// tick's pace are one ManualTime): every period the cameras' staleness moves although nothing is
// fused, a LiDAR frame whose wait for detections is over is fused without anything else arriving,
// and quiet bursts of refusals are summarised.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/base/burst_log.hpp"
#include "services/common/metrics.hpp"
#include "services/tracker/tracker_metrics.hpp"
#include "services/tracker/tracker_node.hpp"
#include "services/tracker/tracker_ticker.hpp"
#include "tests/support/front_camera.hpp"
#include "tests/support/manual_time.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
using test_support::ManualTime;

constexpr std::int64_t kStart = 1'700'000'000'000'000'000;

double staleness(Metrics& metrics, const std::string& camera) {
  for (const auto& f : metrics.registry().Collect()) {
    if (f.name != "fogmap_camera_staleness_seconds") continue;
    for (const auto& m : f.metric) {
      for (const auto& l : m.label) {
        if (l.name == "camera" && l.value == camera) return m.gauge.value;
      }
    }
  }
  return std::nan("");
}

GlobalMapMessage oneObstacleAt(std::int64_t sensor_time_ns) {
  Ellipsoid e;
  e.id = {1, 1, 0};
  e.center = Eigen::Vector3d(8, 0, 0.5);
  e.shape = Eigen::Matrix3d::Identity() * 0.09;
  e.point_count = 50;
  GlobalMapMessage g;
  g.header.epoch = 1;
  g.header.sensor_time_ns = sensor_time_ns;
  g.map = localMap({e});
  return g;
}

// A tracker node with one camera, its metrics and burst log, and its tick, all on one ManualTime.
class TickedTracker {
 public:
  TickedTracker()
      : time_(std::make_shared<ManualTime>(kStart)),
        metrics_("", "tracker", "tracker"),
        tracker_metrics_(metrics_, "tracker", {"cam-1"}),
        log_("tracker tracker: ",
             [this](const std::string& line) {
               std::lock_guard lock(mutex_);
               lines_.push_back(line);
             },
             time_->clock()),
        node_(makeTracker(), 1.5, time_->clock(),
              [this](const TrackSnapshot& snapshot, const FusionReport&) {
                std::lock_guard lock(mutex_);
                fused_.push_back(snapshot.lidar_time_ns);
              }),
        ticker_(node_, tracker_metrics_, log_, kTrackerTick, time_) {}

  static tracking::Tracker makeTracker() {
    auto tracker = tracking::Tracker::create({}, {test_support::frontCamera()});
    EXPECT_TRUE(tracker.ok());
    return std::move(*tracker);
  }

  ManualTime& time() { return *time_; }
  Metrics& metrics() { return metrics_; }
  BurstLog& log() { return log_; }
  TrackerNode& node() { return node_; }
  TrackerTicker& ticker() { return ticker_; }
  std::vector<std::int64_t> fused() {
    std::lock_guard lock(mutex_);
    return fused_;
  }
  std::vector<std::string> lines() {
    std::lock_guard lock(mutex_);
    return lines_;
  }

 private:
  std::shared_ptr<ManualTime> time_;
  Metrics metrics_;
  TrackerMetrics tracker_metrics_;
  std::mutex mutex_;
  std::vector<std::int64_t> fused_;
  std::vector<std::string> lines_;
  BurstLog log_;
  TrackerNode node_;
  TrackerTicker ticker_;
};

TEST(TrackerTicker, EveryTickMovesTheCamerasStalenessWithNothingFused) {
  TickedTracker t;
  EXPECT_FALSE(t.node().addDetections({"cam-1", kStart, {}}));
  t.ticker().start();
  ASSERT_TRUE(t.time().awaitWaits(1));
  EXPECT_DOUBLE_EQ(staleness(t.metrics(), "cam-1"), 0.0);
  t.time().advance(10ms);
  ASSERT_TRUE(t.time().awaitWaits(2));
  EXPECT_DOUBLE_EQ(staleness(t.metrics(), "cam-1"), 0.01);
  t.time().advance(2s);  // a stalled tick: one tick, the gauge at the clock
  ASSERT_TRUE(t.time().awaitWaits(3));
  EXPECT_DOUBLE_EQ(staleness(t.metrics(), "cam-1"), 2.01);
  t.ticker().stop();
  EXPECT_TRUE(t.fused().empty());
  EXPECT_EQ(t.time().waits(), (std::vector<std::chrono::nanoseconds>{kTrackerTick, kTrackerTick, kTrackerTick}));
}

TEST(TrackerTicker, ALidarFrameWhoseWaitForDetectionsIsOverIsFusedOnTheNextTick) {
  TickedTracker t;
  // The camera is silent: the frame waits for it at most max_detection_wait_s (0.25 s).
  EXPECT_FALSE(t.node().addGlobalMap(oneObstacleAt(kStart)));
  t.ticker().start();
  ASSERT_TRUE(t.time().awaitWaits(1));
  t.time().advance(240ms);
  ASSERT_TRUE(t.time().awaitWaits(2));
  EXPECT_TRUE(t.fused().empty()) << "still waiting for the camera";
  t.time().advance(20ms);
  ASSERT_TRUE(t.time().awaitWaits(3));
  EXPECT_EQ(t.fused(), (std::vector<std::int64_t>{kStart})) << "fused although nothing else arrived";
}

TEST(TrackerTicker, AQuietBurstOfRefusalsIsSummarisedOnATick) {
  TickedTracker t;
  t.log().note("refused detection frames (forged)", "'cam-2' may not speak for camera 'cam-1'");
  t.log().note("refused detection frames (forged)", "'cam-2' may not speak for camera 'cam-1'");
  ASSERT_EQ(t.lines().size(), 1U) << "the first at once, the second counted";
  t.ticker().start();
  ASSERT_TRUE(t.time().awaitWaits(1));
  EXPECT_EQ(t.lines().size(), 1U);
  t.time().advance(6s);  // quiet for more than 5 s
  ASSERT_TRUE(t.time().awaitWaits(2));
  const auto lines = t.lines();
  ASSERT_EQ(lines.size(), 2U);
  EXPECT_NE(lines[1].find("1 more in the last"), std::string::npos) << lines[1];
}

}  // namespace
}  // namespace fogmap
