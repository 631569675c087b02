#include "services/edge_cluster/edge_runner.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/io/cloud_io.hpp"
#include "services/common/metrics.hpp"
#include "services/edge_cluster/edge_metrics.hpp"
#include "tests/support/metric_values.hpp"

namespace fogmap {
namespace {

constexpr std::uint32_t kRunnerNode = 5;
constexpr std::int64_t kMsNs = 1'000'000;
constexpr double kPeriodMs = 100.0;
constexpr std::int64_t kPeriodNs = 100 * kMsNs;
// A service started at an arbitrary instant of real unix time: 37 ms into epoch 16,999,999,999,
// so that the first epoch shipped, 17e9, is even (at 5 Hz, epochs 2j and 2j + 1 show scan j).
constexpr std::int64_t kStartNs = 1'699'999'999'937'000'000;

EpochSchedule schedule() {
  Expected<EpochSchedule> created = EpochSchedule::create(kPeriodMs, 50.0);
  EXPECT_TRUE(created.ok());
  return *created;
}

std::uint64_t firstEpoch() { return schedule().epochAt(kStartNs) + 1; }

std::int64_t sensorPeriodNs(double rate_hz) { return std::llround(1e9 / rate_hz); }

EdgeConfig runnerConfig(Mode mode = Mode::kMadc) {
  EdgeConfig config;
  config.node = kRunnerNode;
  config.mode = mode;
  config.max_points_per_chunk = 10;  // a scene of 24 to 28 points gives three chunks
  return config;
}

// Scan n: two boxes of 3 x 2 x 2 points 0.1 m apart (two clusters), 20 m from each other, and
// n mod 5 isolated noise points, so that neighbouring scans differ in points_in.
Cloud sceneOf(std::uint64_t n) {
  Cloud cloud;
  for (const float x0 : {0.0F, 20.0F}) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 2; ++j) {
        for (int k = 0; k < 2; ++k) cloud.push_back({x0 + 0.1F * i, 0.1F * j, 0.1F * k, 1.0F});
      }
    }
  }
  for (std::uint64_t i = 0; i < n % 5; ++i) cloud.push_back({40.0F + 10.0F * static_cast<float>(i), 0.0F, 0.0F, 1.0F});
  return cloud;
}
std::size_t sceneSize(std::uint64_t n) { return 24 + n % 5; }

using ScanPredicate = std::function<bool(std::uint64_t)>;
bool holds(const ScanPredicate& predicate, std::uint64_t n) { return predicate && predicate(n); }

// Scans by number, made on the fly; done() once `limit` scans were read. Selected numbers are
// unreadable, unprocessable (a point a million metres out overflows a 1 cm voxel grid), padded
// or had non-finite points dropped.
class FakeScans : public ScanProvider {
 public:
  bool done() const override { return reads_.size() >= limit; }
  Expected<ScanFrame> at(std::uint64_t n) override {
    EXPECT_FALSE(done()) << "at(" << n << ") called when done";
    reads_.push_back(n);
    ScanFrame frame;
    frame.sequence = n;
    frame.file = "scan_" + std::to_string(n % file_count) + ".bin";
    if (holds(unreadable, n)) return ioError(frame.file.string() + ": cannot read");
    frame.points = sceneOf(n);
    if (holds(unprocessable, n)) frame.points.push_back({1e6F, 0.0F, 0.0F, 1.0F});
    if (holds(padded, n)) frame.trailing_zero_bytes = 8;
    if (holds(non_finite, n)) frame.dropped_non_finite = 2;
    return frame;
  }
  // Every scan number read, in order.
  const std::vector<std::uint64_t>& reads() const { return reads_; }

  std::size_t limit = std::numeric_limits<std::size_t>::max();
  std::uint64_t file_count = std::numeric_limits<std::uint64_t>::max();  // scan n is file n mod this
  ScanPredicate unreadable;
  ScanPredicate unprocessable;
  ScanPredicate padded;
  ScanPredicate non_finite;

 private:
  std::vector<std::uint64_t> reads_;
};

class RecordingObserver : public EdgeObserver {
 public:
  void scanProcessed(const EdgeOutput& /*output*/) override { ++scans_processed; }
  void shipped(const EdgeOutput& /*output*/) override { ++shipped_outputs; }
  void failedFrame() override { ++failed_frames; }
  void malformed(const std::string& what) override { malformed_inputs.push_back(what); }
  void paddedScan() override { ++padded_scans; }

  int scans_processed = 0;
  int shipped_outputs = 0;
  int failed_frames = 0;
  int padded_scans = 0;
  std::vector<std::string> malformed_inputs;
};

struct Shipped {
  EdgeOutput output;
  std::int64_t at_ns = 0;  // the manual clock when the sink got it
};

// A runner on a manual clock: waiting moves the clock to the instant waited for (never back); a
// stall is the clock jumping further, during a ship or during a wait. Members are public for the
// tests to set up and inspect; the runner is built last, from the members before it.
class Replay {
 public:
  explicit Replay(double sensor_rate_hz, EdgeConfig config = runnerConfig(), bool report_dropped_uploads = true)
      : with_dropped_hook(report_dropped_uploads),
        runner(EdgeNode(config), scans, schedule(), sensor_rate_hz, makeHooks()) {}
  Replay(const Replay&) = delete;
  Replay& operator=(const Replay&) = delete;

  // Epochs of the outputs shipped so far, in order.
  std::vector<std::uint64_t> shippedEpochs() const;
  int logLinesContaining(const std::string& text) const {
    return static_cast<int>(std::count_if(logs.begin(), logs.end(),
                                          [&](const std::string& line) { return line.find(text) != std::string::npos; }));
  }

  FakeScans scans;
  std::int64_t now_ns = kStartNs;
  std::vector<std::int64_t> waits;                                       // every until_ns waited for
  std::size_t stop_from_wait = std::numeric_limits<std::size_t>::max();  // this wait and later ones report a stop
  std::map<std::size_t, std::int64_t> stall_in_wait;                     // wait index -> ns the clock overshoots
  std::map<std::size_t, std::int64_t> stall_in_ship;                     // ship index -> ns the clock jumps during it
  const bool with_dropped_hook;
  std::uint64_t dropped_uploads = 0;  // what the dropped-uploads hook reports
  std::vector<std::string> logs;
  std::vector<Shipped> shipped;
  RecordingObserver observer;
  EdgeRunner runner;

 private:
  EdgeRunnerHooks makeHooks() {
    EdgeRunnerHooks hooks;
    hooks.now = [this] { return now_ns; };
    hooks.wait_until = [this](std::int64_t until_ns) {
      const std::size_t index = waits.size();
      waits.push_back(until_ns);
      if (index >= stop_from_wait) return false;
      now_ns = std::max(now_ns, until_ns);
      if (stall_in_wait.count(index) > 0) now_ns += stall_in_wait.at(index);
      return true;
    };
    hooks.ship = [this](const EdgeOutput& output) {
      shipped.push_back({output, now_ns});
      if (stall_in_ship.count(shipped.size() - 1) > 0) now_ns += stall_in_ship.at(shipped.size() - 1);
    };
    if (with_dropped_hook) hooks.dropped_uploads = [this] { return dropped_uploads; };
    hooks.log = [this](const std::string& line) { logs.push_back(line); };
    hooks.link_status = [] { return std::string("link up"); };
    hooks.observer = &observer;
    return hooks;
  }
};

// Every header an output carries: the map's, then each chunk's.
std::vector<MapHeader> headersOf(const EdgeOutput& output) {
  std::vector<MapHeader> headers;
  if (output.map) headers.push_back(output.map->header);
  for (const PointChunk& chunk : output.chunks) headers.push_back(chunk.header);
  return headers;
}

std::uint64_t epochOf(const EdgeOutput& output) {
  const std::vector<MapHeader> headers = headersOf(output);
  EXPECT_FALSE(headers.empty());
  for (const MapHeader& header : headers) EXPECT_EQ(header.epoch, headers.front().epoch);
  return headers.empty() ? 0 : headers.front().epoch;
}

std::vector<std::uint64_t> Replay::shippedEpochs() const {
  std::vector<std::uint64_t> epochs;
  for (const Shipped& s : shipped) epochs.push_back(epochOf(s.output));
  return epochs;
}

// The oracle for a shipped scan: the core run directly on that scan for that epoch.
EdgeOutput processedDirectly(const EdgeConfig& config, std::uint64_t scan, std::uint64_t epoch,
                             std::int64_t sensor_time_ns) {
  Expected<EdgeOutput> output = EdgeNode(config).processFrame(sceneOf(scan), epoch, sensor_time_ns);
  EXPECT_TRUE(output.ok()) << output.error().message;
  return output ? *output : EdgeOutput{};
}

// What a node ships for a failed frame (EdgeNode::failedFrame): no objects and no points, this
// node in failed_nodes and in no contributing_nodes, sensor time unknown (0).
void expectFailedFrame(const EdgeOutput& output, Mode mode, std::uint64_t epoch, std::uint64_t dropped_uploads = 0) {
  MapHeader expected;
  expected.node = kRunnerNode;
  expected.epoch = epoch;
  expected.failed_nodes = {kRunnerNode};
  expected.dropped_uploads = dropped_uploads;
  for (const MapHeader& header : headersOf(output)) EXPECT_EQ(header, expected);
  if (mode == Mode::kBaseline) {
    EXPECT_FALSE(output.map.has_value());
    ASSERT_EQ(output.chunks.size(), 1U);
    EXPECT_TRUE(output.chunks[0].points.empty());
    EXPECT_EQ(output.chunks[0].total_points, 0U);
  } else {
    ASSERT_TRUE(output.map.has_value()) << modeName(mode);
    EXPECT_TRUE(output.map->map.objects.empty());
    EXPECT_TRUE(output.chunks.empty());
  }
}

void expectNormalFrame(const EdgeOutput& output, std::uint64_t epoch) {
  for (const MapHeader& header : headersOf(output)) {
    EXPECT_EQ(header.epoch, epoch);
    EXPECT_TRUE(header.failed_nodes.empty());
    EXPECT_EQ(header.contributing_nodes, std::vector<std::uint32_t>{kRunnerNode});
  }
  if (output.map) {
    EXPECT_EQ(output.map->map.objects.size(), 2U);
  }
}

TEST(EdgeRunner, DisplacementCentroidsAreShippedOncePerScanFromTheSecondScanOn) {
  EdgeConfig config = runnerConfig();
  config.name = "edge-5";
  config.displacement = tracking::DisplacementParams::indoor();
  Replay replay(5.0, config);  // epochs 2j and 2j + 1 show scan j
  constexpr std::size_t kSteps = 6;
  for (std::size_t i = 0; i < kSteps; ++i) ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
  ASSERT_EQ(replay.shipped.size(), kSteps);
  EXPECT_EQ(replay.observer.scans_processed, 3);
  for (std::size_t i = 0; i < kSteps; ++i) {
    SCOPED_TRACE(::testing::Message() << "step " << i);
    const Shipped& s = replay.shipped[i];
    // The first scan has nothing to be compared with; a re-used scan shows nothing new.
    const bool fresh = i % 2 == 0;
    ASSERT_EQ(s.output.centroids.has_value(), fresh && i > 0);
    EXPECT_EQ(s.output.displacement_seconds.has_value(), true) << "the detector's time stays with the scan's output";
    if (!s.output.centroids) continue;
    EXPECT_EQ(s.output.centroids->edge, "edge-5");
    EXPECT_EQ(s.output.centroids->epoch, epochOf(s.output));
    EXPECT_EQ(s.output.centroids->time_ns, s.at_ns) << "the scan's sensor time: when it was read";
    // The two boxes stand still; the noise points are single points: nothing moved.
    EXPECT_TRUE(s.output.centroids->centroids.empty());
  }
}

TEST(EdgeRunner, EpochsFollowTheClusterPeriodNotTheSensorRate) {
  const EpochSchedule epochs = schedule();
  const std::uint64_t first = firstEpoch();
  constexpr std::size_t kSteps = 8;
  std::vector<std::vector<std::pair<std::uint64_t, std::int64_t>>> timelines;  // (epoch, shipped at) per rate
  for (const double rate_hz : {10.0, 20.0, 5.0}) {
    SCOPED_TRACE(::testing::Message() << rate_hz << " Hz");
    Replay replay(rate_hz);
    EXPECT_FALSE(replay.runner.nextEpoch().has_value());
    for (std::size_t i = 0; i < kSteps; ++i) ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);

    std::vector<std::pair<std::uint64_t, std::int64_t>> timeline;
    std::vector<std::uint64_t> scans_read;
    for (std::size_t i = 0; i < kSteps; ++i) {
      const std::uint64_t epoch = first + i;
      const Shipped& s = replay.shipped.at(i);
      // Consecutive epochs of the cluster period, each shipped at its start.
      EXPECT_EQ(epochOf(s.output), epoch);
      EXPECT_EQ(s.at_ns, epochs.startNs(epoch));
      EXPECT_EQ(replay.waits.at(i), epochs.startNs(epoch));
      // It shows the sensor's most recent scan at that instant.
      const auto scan = static_cast<std::uint64_t>(epochs.startNs(epoch) / sensorPeriodNs(rate_hz));
      EXPECT_EQ(replay.runner.scanNumberAt(epoch), scan);
      EXPECT_EQ(s.output.points_in, sceneSize(scan));
      if (scans_read.empty() || scans_read.back() != scan) scans_read.push_back(scan);
      timeline.emplace_back(epoch, s.at_ns);
    }
    EXPECT_EQ(replay.scans.reads(), scans_read);
    EXPECT_EQ(replay.runner.nextEpoch(), first + kSteps);
    EXPECT_EQ(replay.runner.stats().epochs_shipped, kSteps);
    EXPECT_EQ(replay.runner.stats().skipped_epochs, 0U);
    // 20 Hz: every other scan is never shown; 5 Hz: each scan is shown for two epochs.
    const std::size_t expected_scans = rate_hz == 5.0 ? kSteps / 2 : kSteps;
    EXPECT_EQ(replay.runner.stats().scans_processed, expected_scans);
    if (rate_hz == 20.0) {
      EXPECT_EQ(scans_read.at(1) - scans_read.at(0), 2U);
    }
    timelines.push_back(timeline);
  }
  // Sensors of any rate ship the same epochs at the same instants, so the parent can merge them.
  EXPECT_EQ(timelines.at(1), timelines.at(0));
  EXPECT_EQ(timelines.at(2), timelines.at(0));
}

TEST(EdgeRunner, FreshScansAreStampedWithTheirEpochAndTheInstantTheyWereRead) {
  Replay replay(10.0);
  const EpochSchedule epochs = schedule();
  for (int i = 0; i < 3; ++i) ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
  for (const Shipped& s : replay.shipped) {
    const std::uint64_t epoch = epochOf(s.output);
    const EdgeOutput expected =
        processedDirectly(runnerConfig(), replay.runner.scanNumberAt(epoch), epoch, epochs.startNs(epoch));
    EXPECT_EQ(s.output.map, expected.map);
    EXPECT_EQ(s.output.clusters, 2U);
  }
}

TEST(EdgeRunner, ASlowerSensorsScanIsProcessedOnceAndRestampedForEachEpochItShows) {
  const EpochSchedule epochs = schedule();
  const std::uint64_t first = firstEpoch();
  for (const Mode mode : {Mode::kMadc, Mode::kBaseline, Mode::kExt}) {
    SCOPED_TRACE(modeName(mode));
    Replay replay(5.0, runnerConfig(mode));
    ASSERT_EQ(replay.runner.scanNumberAt(first), replay.runner.scanNumberAt(first + 1));
    ASSERT_NE(replay.runner.scanNumberAt(first + 1), replay.runner.scanNumberAt(first + 2));
    const std::uint64_t scan = replay.runner.scanNumberAt(first);

    ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
    ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
    EXPECT_EQ(replay.scans.reads(), std::vector<std::uint64_t>{scan});
    EXPECT_EQ(replay.runner.stats().scans_processed, 1U);
    EXPECT_EQ(replay.observer.scans_processed, 1);
    EXPECT_EQ(replay.runner.stats().epochs_shipped, 2U);
    EXPECT_EQ(replay.observer.shipped_outputs, 2);
    ASSERT_EQ(replay.shipped.size(), 2U);

    // Each epoch's output is what processing the scan for that epoch gives: header and ellipsoid
    // ids carry the epoch; the sensor time stays the instant the scan was read, the data's age.
    for (std::size_t i = 0; i < 2; ++i) {
      const EdgeOutput expected = processedDirectly(runnerConfig(mode), scan, first + i, epochs.startNs(first));
      const EdgeOutput& output = replay.shipped[i].output;
      EXPECT_EQ(output.map, expected.map) << "epoch " << first + i;
      EXPECT_EQ(output.chunks, expected.chunks) << "epoch " << first + i;
      if (mode == Mode::kBaseline) {
        EXPECT_EQ(output.chunks.size(), 3U);
        continue;
      }
      ASSERT_TRUE(output.map.has_value());
      ASSERT_EQ(output.map->map.objects.size(), 2U);
      for (const MapObject& object : output.map->map.objects) {
        for (const Ellipsoid& ellipsoid : object.ellipsoids) {
          EXPECT_EQ(ellipsoid.id.node, kRunnerNode);
          EXPECT_EQ(ellipsoid.id.frame, first + i);
        }
      }
    }

    // The next scan is read and processed afresh.
    ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
    EXPECT_EQ(replay.scans.reads().size(), 2U);
    EXPECT_EQ(replay.runner.stats().scans_processed, 2U);
    EXPECT_EQ(replay.shipped.at(2).output.points_in, sceneSize(replay.runner.scanNumberAt(first + 2)));
    expectNormalFrame(replay.shipped.at(2).output, first + 2);
  }
}

TEST(EdgeRunner, FailedFrameIsShippedEmptyAndFlagged) {
  const EpochSchedule epochs = schedule();
  const std::uint64_t first = firstEpoch();
  for (const bool unreadable : {true, false}) {
    for (const Mode mode : {Mode::kMadc, Mode::kBaseline, Mode::kExt}) {
      SCOPED_TRACE(::testing::Message() << modeName(mode) << (unreadable ? ", unreadable scan" : ", processing fails"));
      EdgeConfig config = runnerConfig(mode);
      config.preprocess.voxel_leaf_m = 0.01;  // fine for the scene; overflows with a point 1000 km out
      Replay replay(10.0, config);
      const std::uint64_t bad = replay.runner.scanNumberAt(first + 1);
      (unreadable ? replay.scans.unreadable : replay.scans.unprocessable) = [bad](std::uint64_t n) { return n == bad; };

      for (int i = 0; i < 3; ++i) ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
      ASSERT_EQ(replay.shipped.size(), 3U);
      expectNormalFrame(replay.shipped[0].output, first);
      // The failed epoch is still shipped, on time, so the parent need not wait out its deadline.
      expectFailedFrame(replay.shipped[1].output, mode, first + 1);
      EXPECT_EQ(replay.shipped[1].at_ns, epochs.startNs(first + 1));
      // The next scan ships normally.
      expectNormalFrame(replay.shipped[2].output, first + 2);
      EXPECT_EQ(replay.shipped[2].output.points_in, sceneSize(replay.runner.scanNumberAt(first + 2)));

      const EdgeRunnerStats& stats = replay.runner.stats();
      EXPECT_EQ(stats.epochs_shipped, 3U);
      EXPECT_EQ(stats.failed_frames, 1U);
      EXPECT_EQ(stats.scans_processed, 2U);
      EXPECT_EQ(replay.observer.failed_frames, 1);
      EXPECT_EQ(replay.observer.shipped_outputs, 3);
      EXPECT_EQ(replay.observer.scans_processed, 2);
      EXPECT_EQ(replay.observer.malformed_inputs, std::vector<std::string>{unreadable ? "scan" : "frame"});
      // The log names the epoch, the scan and the file.
      EXPECT_EQ(replay.logLinesContaining("failed frame (epoch " + std::to_string(first + 1) + ", scan " +
                                          std::to_string(bad) + ")"),
                1);
      EXPECT_EQ(replay.logLinesContaining("scan_" + std::to_string(bad) + ".bin"), 1);
    }
  }
}

TEST(EdgeRunner, AFailedScanShownForTwoEpochsIsReadOnceAndShippedFailedForBoth) {
  const std::uint64_t first = firstEpoch();
  Replay replay(5.0);
  const std::uint64_t bad = replay.runner.scanNumberAt(first);
  ASSERT_EQ(replay.runner.scanNumberAt(first + 1), bad);
  replay.scans.unreadable = [bad](std::uint64_t n) { return n == bad; };

  for (int i = 0; i < 3; ++i) ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
  expectFailedFrame(replay.shipped.at(0).output, Mode::kMadc, first);
  expectFailedFrame(replay.shipped.at(1).output, Mode::kMadc, first + 1);
  expectNormalFrame(replay.shipped.at(2).output, first + 2);
  EXPECT_EQ(replay.scans.reads(), (std::vector<std::uint64_t>{bad, bad + 1}));
  EXPECT_EQ(replay.runner.stats().failed_frames, 2U);
  EXPECT_EQ(replay.observer.failed_frames, 2);
  EXPECT_EQ(replay.observer.malformed_inputs, std::vector<std::string>{"scan"});
  EXPECT_EQ(replay.runner.stats().scans_processed, 1U);
}

TEST(EdgeRunner, ARepeatedErrorIsLoggedOnceAndCountedEveryTime) {
  Replay replay(10.0);
  replay.scans.file_count = 2;
  replay.scans.unreadable = [](std::uint64_t n) { return n % 2 == 1; };  // file scan_1.bin
  for (int i = 0; i < 6; ++i) ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
  EXPECT_EQ(replay.runner.stats().failed_frames, 3U);
  EXPECT_EQ(replay.observer.malformed_inputs.size(), 3U);
  EXPECT_EQ(replay.logLinesContaining("scan_1.bin: cannot read"), 1);
}

TEST(EdgeRunner, StallSkipsMissedEpochsWithoutBurst) {
  const EpochSchedule epochs = schedule();
  const std::uint64_t first = firstEpoch();
  Replay replay(10.0);
  // Shipping epoch first + 1 takes five periods and 30 ms: it ends inside epoch first + 6.
  replay.stall_in_ship[1] = 5 * kPeriodNs + 30 * kMsNs;
  for (int i = 0; i < 4; ++i) ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);

  // Epochs first + 2 .. first + 5 are skipped, not shipped late in a burst; the current epoch goes
  // at once (late), the one after it on time.
  EXPECT_EQ(replay.shippedEpochs(), (std::vector<std::uint64_t>{first, first + 1, first + 6, first + 7}));
  EXPECT_EQ(replay.shipped.at(2).at_ns, epochs.startNs(first + 6) + 30 * kMsNs);
  EXPECT_EQ(replay.shipped.at(3).at_ns, epochs.startNs(first + 7));
  EXPECT_EQ(replay.waits, (std::vector<std::int64_t>{epochs.startNs(first), epochs.startNs(first + 1),
                                                     epochs.startNs(first + 6), epochs.startNs(first + 7)}));
  // The missed epochs' scans are never read; the current epoch shows its own scan.
  std::vector<std::uint64_t> expected_reads;
  for (const std::uint64_t epoch : {first, first + 1, first + 6, first + 7}) {
    expected_reads.push_back(replay.runner.scanNumberAt(epoch));
  }
  EXPECT_EQ(replay.scans.reads(), expected_reads);
  EXPECT_EQ(replay.shipped.at(2).output.points_in, sceneSize(replay.runner.scanNumberAt(first + 6)));
  EXPECT_EQ(replay.runner.stats().skipped_epochs, 4U);
  EXPECT_EQ(replay.runner.stats().epochs_shipped, 4U);
  EXPECT_EQ(replay.logLinesContaining("stalled"), 1);

  // A second stall adds to the count (and is not logged again).
  replay.stall_in_ship[4] = 2 * kPeriodNs;
  ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
  ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
  EXPECT_EQ(epochOf(replay.shipped.at(5).output), first + 10);
  EXPECT_EQ(replay.runner.stats().skipped_epochs, 5U);
  EXPECT_EQ(replay.logLinesContaining("stalled"), 1);
}

TEST(EdgeRunner, ALateShipWithinOnePeriodSkipsNothing) {
  const EpochSchedule epochs = schedule();
  const std::uint64_t first = firstEpoch();
  Replay replay(10.0);
  replay.stall_in_ship[0] = kPeriodNs + 40 * kMsNs;  // ends 40 ms into epoch first + 1
  for (int i = 0; i < 3; ++i) ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
  EXPECT_EQ(replay.shippedEpochs(), (std::vector<std::uint64_t>{first, first + 1, first + 2}));
  EXPECT_EQ(replay.shipped.at(1).at_ns, epochs.startNs(first + 1) + 40 * kMsNs);
  EXPECT_EQ(replay.shipped.at(2).at_ns, epochs.startNs(first + 2));
  EXPECT_EQ(replay.runner.stats().skipped_epochs, 0U);
}

TEST(EdgeRunner, AStallInTheWaitShipsTheAwaitedEpochThenGoesOnWithTheCurrentOne) {
  const EpochSchedule epochs = schedule();
  const std::uint64_t first = firstEpoch();
  Replay replay(10.0);
  replay.stall_in_wait[1] = 3 * kPeriodNs + 10 * kMsNs;  // woken 3 periods late for epoch first + 1
  for (int i = 0; i < 4; ++i) ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
  EXPECT_EQ(replay.shippedEpochs(), (std::vector<std::uint64_t>{first, first + 1, first + 4, first + 5}));
  EXPECT_EQ(replay.shipped.at(2).at_ns, epochs.startNs(first + 4) + 10 * kMsNs);
  EXPECT_EQ(replay.shipped.at(3).at_ns, epochs.startNs(first + 5));
  EXPECT_EQ(replay.runner.stats().skipped_epochs, 2U);
}

TEST(EdgeRunner, StopRequestShipsNothingMore) {
  {
    Replay replay(10.0);
    replay.scans.limit = 10;  // a runner that ignored the stop would end, kDone, rather than hang
    replay.stop_from_wait = 2;
    EXPECT_EQ(replay.runner.run(), EdgeStep::kStopped);
    EXPECT_EQ(replay.shippedEpochs(), (std::vector<std::uint64_t>{firstEpoch(), firstEpoch() + 1}));
    EXPECT_EQ(replay.waits.size(), 3U);
    EXPECT_EQ(replay.scans.reads().size(), 2U);  // nothing read for the stopped epoch
    EXPECT_EQ(replay.now_ns, schedule().startNs(firstEpoch() + 1));
    EXPECT_EQ(replay.runner.stats().epochs_shipped, 2U);
    EXPECT_EQ(replay.observer.shipped_outputs, 2);
    // Asked again while the stop stands, it still ships nothing.
    EXPECT_EQ(replay.runner.step(), EdgeStep::kStopped);
    EXPECT_EQ(replay.shipped.size(), 2U);
  }
  {
    Replay replay(10.0);
    replay.stop_from_wait = 0;
    EXPECT_EQ(replay.runner.step(), EdgeStep::kStopped);
    EXPECT_TRUE(replay.shipped.empty());
    EXPECT_TRUE(replay.scans.reads().empty());
    EXPECT_EQ(replay.runner.stats().epochs_shipped, 0U);
    EXPECT_EQ(replay.now_ns, kStartNs);
  }
}

TEST(EdgeRunner, DoneWhenScansRunOut) {
  const EpochSchedule epochs = schedule();
  const std::uint64_t first = firstEpoch();
  {
    Replay replay(10.0);
    replay.scans.limit = 3;
    EXPECT_EQ(replay.runner.run(), EdgeStep::kDone);
    EXPECT_EQ(replay.shippedEpochs(), (std::vector<std::uint64_t>{first, first + 1, first + 2}));
    // A finished recording costs no further period: there was no wait for a fourth epoch.
    EXPECT_EQ(replay.waits.size(), 3U);
    EXPECT_EQ(replay.now_ns, epochs.startNs(first + 2));
    EXPECT_EQ(replay.runner.step(), EdgeStep::kDone);
    EXPECT_EQ(replay.shipped.size(), 3U);
  }
  {
    // At 5 Hz the last scan is still shown for its second epoch: only a new scan needs the provider.
    Replay replay(5.0);
    replay.scans.limit = 2;
    EXPECT_EQ(replay.runner.run(), EdgeStep::kDone);
    EXPECT_EQ(replay.shippedEpochs(), (std::vector<std::uint64_t>{first, first + 1, first + 2, first + 3}));
    EXPECT_EQ(replay.runner.stats().scans_processed, 2U);
  }
  {
    Replay replay(10.0);
    replay.scans.limit = 0;
    EXPECT_EQ(replay.runner.run(), EdgeStep::kDone);
    EXPECT_TRUE(replay.shipped.empty());
    EXPECT_TRUE(replay.waits.empty());
  }
}

TEST(EdgeRunner, DroppedUploadsAppearInHeader) {
  const std::uint64_t first = firstEpoch();
  for (const Mode mode : {Mode::kMadc, Mode::kBaseline, Mode::kExt}) {
    SCOPED_TRACE(modeName(mode));
    Replay replay(5.0, runnerConfig(mode));
    const std::uint64_t bad = replay.runner.scanNumberAt(first + 2);
    replay.scans.unreadable = [bad](std::uint64_t n) { return n == bad; };
    // A fresh scan, the same scan re-used, a failed frame: each carries the total when shipped.
    const std::vector<std::uint64_t> totals = {3, 7, 9};
    for (const std::uint64_t total : totals) {
      replay.dropped_uploads = total;
      ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
    }
    expectFailedFrame(replay.shipped.at(2).output, mode, first + 2, totals[2]);
    for (std::size_t i = 0; i < totals.size(); ++i) {
      const std::vector<MapHeader> headers = headersOf(replay.shipped.at(i).output);
      ASSERT_FALSE(headers.empty());
      for (const MapHeader& header : headers) EXPECT_EQ(header.dropped_uploads, totals[i]) << "epoch " << first + i;
    }
  }
  {
    Replay replay(10.0, runnerConfig(Mode::kExt), /*report_dropped_uploads=*/false);
    replay.dropped_uploads = 5;  // not reported without the hook
    ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
    for (const MapHeader& header : headersOf(replay.shipped.at(0).output)) EXPECT_EQ(header.dropped_uploads, 0U);
  }
}

TEST(EdgeRunner, PaddedScanIsCountedAndWarnedOncePerFile) {
  Replay replay(10.0);
  replay.scans.file_count = 2;
  replay.scans.padded = [](std::uint64_t n) { return n % 2 == 0; };  // file scan_0.bin
  for (int i = 0; i < 6; ++i) ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
  EXPECT_EQ(replay.runner.stats().padded_scans, 3U);
  EXPECT_EQ(replay.observer.padded_scans, 3);
  EXPECT_EQ(replay.logLinesContaining("scan_0.bin: 8 zero byte(s)"), 1);
  // Padding is accepted: the scans ship normally.
  EXPECT_EQ(replay.runner.stats().failed_frames, 0U);
  EXPECT_EQ(replay.runner.stats().scans_processed, 6U);
  for (const Shipped& s : replay.shipped) expectNormalFrame(s.output, epochOf(s.output));
}

TEST(EdgeRunner, DroppedNonFinitePointsAreReportedOncePerScanAndTheScanShips) {
  Replay replay(5.0);
  replay.scans.non_finite = [](std::uint64_t) { return true; };
  for (int i = 0; i < 4; ++i) ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
  EXPECT_EQ(replay.observer.malformed_inputs, (std::vector<std::string>{"non_finite_points", "non_finite_points"}));
  EXPECT_EQ(replay.runner.stats().failed_frames, 0U);
  for (const Shipped& s : replay.shipped) expectNormalFrame(s.output, epochOf(s.output));
}

TEST(EdgeRunner, StatusLinesComeEveryTenEpochsWithTheLinkStatus) {
  Replay replay(10.0);
  for (int i = 0; i < 11; ++i) ASSERT_EQ(replay.runner.step(), EdgeStep::kShipped);
  EXPECT_EQ(replay.logLinesContaining("; link up"), 2);
  EXPECT_EQ(replay.logLinesContaining("epoch " + std::to_string(firstEpoch()) + ", scan "), 1);
  EXPECT_EQ(replay.logLinesContaining("epoch " + std::to_string(firstEpoch() + 10) + ", scan "), 1);
}

// ---------------------------------------------------------------------------------------------
// Hostile values: 1 % of every scan's points have a NaN or infinite coordinate.

constexpr std::size_t kHostileScans = 50;  // distinct scans, replayed in turn

struct HostileScan {
  Cloud points;                // the non-finite points in place
  std::size_t non_finite = 0;  // how many of them
};

// Scan s: 200 to 3,000 points (a multiple of 100) in one to six blobs of 0.1 m jitter, exactly
// 1 % of them, at random positions, with NaN, +inf or -inf in one, two or three coordinates.
std::vector<HostileScan> hostileScans() {
  std::mt19937_64 rng(2024);
  std::uniform_int_distribution<std::size_t> hundreds(2, 30);
  std::uniform_int_distribution<std::size_t> blob_count(1, 6);
  std::uniform_real_distribution<float> anywhere(-30.0F, 30.0F);
  std::normal_distribution<float> jitter(0.0F, 0.1F);
  std::uniform_int_distribution<int> kind(0, 5);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<HostileScan> scans(kHostileScans);
  for (HostileScan& scan : scans) {
    const std::size_t n = 100 * hundreds(rng);
    std::vector<Point> centres(blob_count(rng));
    for (Point& c : centres) c = {anywhere(rng), anywhere(rng), 1.0F, 0.0F};
    for (std::size_t i = 0; i < n; ++i) {
      const Point& c = centres[i % centres.size()];
      scan.points.push_back({c.x + jitter(rng), c.y + jitter(rng), c.z + jitter(rng), 1.0F});
    }
    std::vector<std::size_t> order(n);
    std::iota(order.begin(), order.end(), 0);
    std::shuffle(order.begin(), order.end(), rng);
    scan.non_finite = n / 100;
    for (std::size_t k = 0; k < scan.non_finite; ++k) {
      Point& p = scan.points[order[k]];
      switch (kind(rng)) {
        case 0: p.x = nan; break;
        case 1: p.y = inf; break;
        case 2: p.z = -inf; break;
        case 3: p.x = -inf; p.y = nan; break;
        case 4: p.y = nan; p.z = inf; break;
        default: p.x = p.y = p.z = nan; break;
      }
    }
  }
  return scans;
}

// The scans from memory, non-finite points included, as a live sensor would hand them over.
class InMemoryScans : public ScanProvider {
 public:
  InMemoryScans(const std::vector<HostileScan>& scans, std::size_t limit) : scans_(scans), limit_(limit) {}
  bool done() const override { return reads_ >= limit_; }
  Expected<ScanFrame> at(std::uint64_t n) override {
    ++reads_;
    ScanFrame frame;
    frame.sequence = n;
    frame.file = "memory";
    frame.points = scans_[n % scans_.size()].points;
    return frame;
  }

 private:
  const std::vector<HostileScan>& scans_;
  std::size_t limit_;
  std::size_t reads_ = 0;
};

struct HostileReplay {
  EdgeRunnerStats stats;
  std::uint64_t injected = 0;         // non-finite points in the scans the runner read
  std::uint64_t finite_points = 0;    // the other points of those scans
  std::uint64_t points_in = 0;        // EdgeOutput::points_in summed over the scans processed
  std::uint64_t non_finite_out = 0;   // non-finite centre or shape values in what was shipped
};

// Runs an edge at 10 Hz (one fresh scan per epoch) over `scans` to the end, on a clock that jumps
// to every instant waited for.
HostileReplay replayToTheEnd(ScanProvider& scans, const std::vector<HostileScan>& recorded, EdgeObserver& observer) {
  EdgeConfig config = runnerConfig(Mode::kMadc);
  config.preprocess.crop = CropBox{};  // as the edges run: the crop box, then clustering
  HostileReplay replay;
  std::int64_t now_ns = kStartNs;
  std::vector<std::uint64_t> epochs;
  EdgeRunnerHooks hooks;
  hooks.now = [&] { return now_ns; };
  hooks.wait_until = [&](std::int64_t until_ns) {
    now_ns = std::max(now_ns, until_ns);
    return true;
  };
  hooks.ship = [&](const EdgeOutput& output) {
    epochs.push_back(epochOf(output));
    replay.points_in += output.points_in;
    if (!output.map) return;
    for (const MapObject& object : output.map->map.objects) {
      for (const Ellipsoid& e : object.ellipsoids) {
        replay.non_finite_out += static_cast<std::uint64_t>((!e.center.array().isFinite()).count() +
                                                            (!e.shape.array().isFinite()).count());
      }
    }
  };
  hooks.observer = &observer;
  EdgeRunner runner(EdgeNode(config), scans, schedule(), 10.0, std::move(hooks));
  EXPECT_EQ(runner.run(), EdgeStep::kDone);
  for (const std::uint64_t epoch : epochs) {
    const HostileScan& scan = recorded[runner.scanNumberAt(epoch) % recorded.size()];
    replay.injected += scan.non_finite;
    replay.finite_points += scan.points.size() - scan.non_finite;
  }
  replay.stats = runner.stats();
  return replay;
}

using test_support::counterValue;

TEST(EdgeMetrics, DisplacementTimeCentroidsJoinedVehiclePartsAndTheCentroidLinksFramesAreExported) {
  Metrics metrics("", "edge-cluster", "edge-5");
  MetricsObserver observer(metrics, kDefaultMaxPointsPerChunk, "edge-5");
  EdgeOutput first;  // a first scan: the detector ran, nothing to send
  first.displacement_seconds = 0.004;
  EdgeOutput second;
  second.displacement_seconds = 0.02;
  second.centroids = tracking::CentroidFrame{};
  second.centroids->centroids.resize(3);
  second.vehicle_parts_joined = 2;
  observer.scanProcessed(first);
  observer.scanProcessed(second);
  observer.scanProcessed(EdgeOutput{});  // displacement off
  observer.centroidFrameSent("tracker", 120);
  observer.centroidFrameSent("tracker", 80);
  observer.centroidFrameDropped();
  double sum = 0.0;
  std::uint64_t count = 0;
  for (const auto& f : metrics.registry().Collect()) {
    if (f.name != "fogmap_displacement_seconds") continue;
    for (const auto& m : f.metric) {
      sum += m.histogram.sample_sum;
      count += m.histogram.sample_count;
    }
  }
  EXPECT_EQ(count, 2U);
  EXPECT_DOUBLE_EQ(sum, 0.024);
  EXPECT_EQ(counterValue(metrics, "fogmap_displacement_centroids_total", "node", "edge-5"), 3.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_vehicle_parts_joined_total", "node", "edge-5"), 2.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_centroid_frames_sent_total", "node", "edge-5"), 2.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_centroid_frames_dropped_total", "node", "edge-5"), 1.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_bytes_sent_total", "kind", "centroids"), 200.0);
}

TEST(EdgeRunner, OnePercentNonFinitePointsOverTenThousandFramesAreDroppedAndCountedExactly) {
  constexpr std::size_t kFramesEach = 5000;  // read from files, then handed over from memory
  const std::vector<HostileScan> scans = hostileScans();
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("fogmap_hostile_scans_" + std::to_string(std::random_device{}()));
  std::filesystem::create_directories(dir);
  for (std::size_t s = 0; s < scans.size(); ++s) {
    char name[32];
    std::snprintf(name, sizeof name, "scan_%03zu.%s", s, s % 2 == 0 ? "bin" : "pcd");
    const Cloud& points = scans[s].points;
    const Status written = s % 2 == 0 ? writeKittiBin(dir / name, points) : writePcd(dir / name, points);
    ASSERT_TRUE(written.ok()) << written.error().message;
  }
  SensorConfig sensor;
  sensor.source = dir;
  sensor.frames = kFramesEach;
  Expected<ScanSource> files = ScanSource::open(sensor);
  ASSERT_TRUE(files.ok()) << files.error().message;
  InMemoryScans memory(scans, kFramesEach);

  Metrics metrics("", "edge-cluster", "hostile");  // the edge's one Metrics, nothing served
  MetricsObserver observer(metrics, kDefaultMaxPointsPerChunk, "hostile");
  const HostileReplay from_files = replayToTheEnd(*files, scans, observer);
  const HostileReplay from_memory = replayToTheEnd(memory, scans, observer);
  std::filesystem::remove_all(dir);

  for (const HostileReplay* replay : {&from_files, &from_memory}) {
    SCOPED_TRACE(replay == &from_files ? "from files" : "from memory");
    EXPECT_EQ(replay->stats.scans_processed, kFramesEach);
    EXPECT_EQ(replay->stats.epochs_shipped, kFramesEach);
    EXPECT_EQ(replay->stats.failed_frames, 0U) << "a non-finite point must never fail a frame";
    EXPECT_EQ(replay->stats.dropped_non_finite_points, replay->injected);
    EXPECT_EQ(replay->points_in, replay->finite_points) << "only finite points reach processing";
    EXPECT_EQ(replay->non_finite_out, 0U);
  }
  const std::uint64_t injected = from_files.injected + from_memory.injected;
  const std::uint64_t finite = from_files.finite_points + from_memory.finite_points;
  EXPECT_EQ(injected * 99, finite) << "exactly 1 % of the points were non-finite";
  const double exported = counterValue(metrics, "fogmap_dropped_points_total", "reason", "non_finite");
  EXPECT_EQ(exported, static_cast<double>(injected));
  EXPECT_EQ(counterValue(metrics, "fogmap_malformed_inputs_total", "what", "non_finite_points"),
            static_cast<double>(2 * kFramesEach));
  std::printf("%zu frames, %llu points, %llu non-finite injected, %.0f dropped and exported\n", 2 * kFramesEach,
              static_cast<unsigned long long>(injected + finite), static_cast<unsigned long long>(injected), exported);
}

}  // namespace
}  // namespace fogmap
