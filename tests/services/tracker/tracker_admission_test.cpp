// The tracker's door against a hostile client, over real gRPC on 127.0.0.1 with the process's own
// hooks (metrics and burst log) and a clock the test drives: frames dated outside the admission
// window are refused and counted and never move the tracker's time or its cameras' staleness; a
// flood of refusals writes one log line per reason per burst; subscribers beyond the bound are
// refused; a flood of clutter is shed by the fusion budget while the people keep their tracks.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/base/burst_log.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/metrics.hpp"
#include "services/common/proto_convert.hpp"
#include "services/tracker/tracker_hooks.hpp"
#include "services/tracker/tracker_metrics.hpp"
#include "services/tracker/tracker_node.hpp"
#include "services/tracker/tracker_service.hpp"
#include "tests/support/front_camera.hpp"
#include "tests/support/eventually.hpp"
#include "tests/support/metric_values.hpp"
#include "tests/support/test_server.hpp"
#include "tests/support/epoch_times.hpp"
#include "tests/support/global_maps.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
using test_support::counterValue;

using test_support::globalMapWith;
using test_support::kE0;
using test_support::kMs;
using test_support::kT0;
using test_support::startOf;

constexpr std::int64_t kDayNs = 86'400'000'000'000;
constexpr std::int64_t kYearNs = 365 * kDayNs;

double gaugeValue(Metrics& metrics, const std::string& family, const std::string& label, const std::string& value) {
  for (const auto& f : metrics.registry().Collect()) {
    if (f.name != family) continue;
    for (const auto& m : f.metric) {
      for (const auto& l : m.label) {
        if (l.name == label && l.value == value) return m.gauge.value;
      }
    }
  }
  return std::nan("");
}

using test_support::frontCamera;

// A person 8 m ahead of frontCamera: (8, 0, 0.5) is pixel (320, 271.25).
tracking::DetectionFrame personSeenAt(std::int64_t capture_ns) {
  tracking::DetectionFrame frame{"cam-1", capture_ns, {}};
  camera::Detection person;
  person.box = {300, 250, 340, 290};
  person.label = "person";
  person.score = 0.9;
  frame.detections.push_back(person);
  return frame;
}

tracking::CentroidFrame centroidFrame(const std::string& edge, std::uint64_t epoch, std::int64_t time_ns,
                                      const std::vector<Eigen::Vector2d>& people, std::size_t points = 30) {
  tracking::CentroidFrame f;
  f.edge = edge;
  f.epoch = epoch;
  f.time_ns = time_ns;
  for (const auto& p : people) {
    f.centroids.push_back({Eigen::Vector3d(p.x(), p.y(), 0.9), Eigen::Matrix3d::Identity() * 0.02, points});
  }
  return f;
}

// The tracker as its composition root wires it (node, adapter, metrics, hooks, burst log), on a
// loopback server, with the clock in `now_ns`; with `edges`, its input is their centroids.
class TrackerUnderTest {
 public:
  struct Options {
    std::vector<camera::PinholeCamera> cameras = {};
    std::vector<std::string> edges = {};
    std::size_t max_subscribers = 32;
    NowNs stopwatch = {};  // empty: the steady clock
  };
  explicit TrackerUnderTest(Options options)
      : metrics_("", "tracker", "tracker"),
        tracker_metrics_(metrics_, "tracker", names(options.cameras), options.edges),
        log_("tracker tracker: ",
             [this](const std::string& line) {
               std::lock_guard lock(mutex_);
               lines_.push_back(line);
             },
             [this] { return now_ns.load(); }) {
    auto tracker = tracking::Tracker::create({}, options.cameras);
    EXPECT_TRUE(tracker.ok());
    std::optional<CentroidCollector> collector;
    auto schedule = EpochSchedule::create(100.0, 80.0);
    EXPECT_TRUE(schedule.ok());
    if (!options.edges.empty()) collector.emplace(CentroidCollectorConfig{options.edges, 1.0, 3.0}, *schedule);
    TrackerNodeLimits limits;  // window 300 ms (3 periods of 100 ms), half a period for a step
    limits.stopwatch = options.stopwatch;
    node_ = std::make_unique<TrackerNode>(
        std::move(*tracker), 1.5, [this] { return now_ns.load(); },
        [this](const TrackSnapshot& s, const FusionReport& report) {
          tracker_metrics_.fused(report);
          service_->publish(s);
          std::lock_guard lock(mutex_);
          snapshots_.push_back(s);
          reports_.push_back(report);
        },
        std::move(collector), limits);
    service_ = std::make_unique<TrackerService>(*node_, names(options.cameras), false,
                                                trackerServiceHooks(metrics_, tracker_metrics_, log_), 16, 20ms,
                                                options.max_subscribers);
    server_ = std::make_unique<test_support::TestServer>(*service_);
    stub_ = v1::TrackerService::NewStub(makeChannel(server_->target(), 64U << 20));
  }
  ~TrackerUnderTest() {
    service_->shutdown(200ms);
    server_->stop();
  }

  // Pushes `frames` on one stream; returns when the tracker has taken every one (the summary
  // comes after the last).
  v1::DetectionSummary pushDetections(const std::vector<tracking::DetectionFrame>& frames) {
    grpc::ClientContext context;
    context.set_wait_for_ready(true);  // a loaded machine may be slow to connect: wait, do not fail
    v1::DetectionSummary summary;
    auto writer = stub_->PushDetections(&context, &summary);
    for (const auto& f : frames) EXPECT_TRUE(writer->Write(toProto(f)));
    EXPECT_TRUE(writer->WritesDone());
    const grpc::Status status = writer->Finish();
    EXPECT_TRUE(status.ok()) << status.error_code() << ": " << status.error_message();
    return summary;
  }
  v1::CentroidSummary pushCentroids(const std::vector<v1::CentroidFrame>& frames) {
    grpc::ClientContext context;
    context.set_wait_for_ready(true);
    v1::CentroidSummary summary;
    auto writer = stub_->PushCentroids(&context, &summary);
    for (const auto& f : frames) EXPECT_TRUE(writer->Write(f));
    EXPECT_TRUE(writer->WritesDone());
    const grpc::Status status = writer->Finish();
    EXPECT_TRUE(status.ok()) << status.error_code() << ": " << status.error_message();
    return summary;
  }

  double counter(const std::string& family, const std::string& reason) {
    return counterValue(metrics_, family, "reason", reason);
  }
  std::vector<TrackSnapshot> snapshots() {
    std::lock_guard lock(mutex_);
    return snapshots_;
  }
  std::vector<FusionReport> reports() {
    std::lock_guard lock(mutex_);
    return reports_;
  }
  std::vector<std::string> lines() {
    std::lock_guard lock(mutex_);
    return lines_;
  }

  std::atomic<std::int64_t> now_ns{kT0};
  Metrics& metrics() { return metrics_; }
  TrackerMetrics& trackerMetrics() { return tracker_metrics_; }
  BurstLog& log() { return log_; }
  TrackerNode& node() { return *node_; }
  TrackerService& service() { return *service_; }
  v1::TrackerService::Stub& stub() { return *stub_; }

 private:
  static std::vector<std::string> names(const std::vector<camera::PinholeCamera>& cameras) {
    std::vector<std::string> out;
    for (const auto& c : cameras) out.push_back(c.name);
    return out;
  }

  Metrics metrics_;
  TrackerMetrics tracker_metrics_;
  std::mutex mutex_;
  std::vector<std::string> lines_;
  std::vector<TrackSnapshot> snapshots_;
  std::vector<FusionReport> reports_;
  BurstLog log_;
  std::unique_ptr<TrackerNode> node_;
  std::unique_ptr<TrackerService> service_;
  std::unique_ptr<test_support::TestServer> server_;
  std::unique_ptr<v1::TrackerService::Stub> stub_;
};

TEST(TrackerAdmission, CentroidFramesOutsideTheWindowAreRefusedAndTheTracksKeepComing) {
  TrackerUnderTest t({.edges = {"edge-a"}});
  const auto person = [](std::uint64_t k) { return Eigen::Vector2d(4.0, 0.1 * static_cast<double>(k)); };
  const auto honest = [&](std::uint64_t k) {
    t.now_ns = startOf(kE0 + k) + 10 * kMs;
    return t.pushCentroids({toProto(centroidFrame("edge-a", kE0 + k, startOf(kE0 + k) + 2 * kMs, {person(k)}))});
  };
  for (std::uint64_t k = 0; k < 10; ++k) EXPECT_EQ(honest(k).refused(), 0U);
  ASSERT_EQ(t.snapshots().size(), 10U);
  // The next epoch dated a year ahead, an epoch a year ahead, and the next epoch dated a day back.
  t.now_ns = startOf(kE0 + 10) + 10 * kMs;
  const std::uint64_t year_of_epochs = static_cast<std::uint64_t>(kYearNs / (100 * kMs));
  const auto hostile = t.pushCentroids({
      toProto(centroidFrame("edge-a", kE0 + 10, startOf(kE0 + 10) + kYearNs, {person(10)})),
      toProto(centroidFrame("edge-a", kE0 + year_of_epochs, startOf(kE0 + year_of_epochs), {person(10)})),
      toProto(centroidFrame("edge-a", kE0 + 10, startOf(kE0 + 10) - kDayNs, {person(10)})),
  });
  EXPECT_EQ(hostile.refused(), 3U);
  EXPECT_NE(hostile.last_refusal().find("clock_skew"), std::string::npos) << hostile.last_refusal();
  EXPECT_EQ(t.counter("fogmap_centroid_frames_rejected_total", "clock_skew"), 3.0);
  EXPECT_EQ(t.snapshots().size(), 10U) << "nothing refused is fused";
  // The honest epochs go on being fused, at their own times, into the same track.
  for (std::uint64_t k = 10; k < 20; ++k) EXPECT_EQ(honest(k).refused(), 0U) << "epoch " << k;
  const auto snapshots = t.snapshots();
  ASSERT_EQ(snapshots.size(), 20U);
  EXPECT_EQ(snapshots.back().lidar_time_ns, startOf(kE0 + 19) + 2 * kMs);
  ASSERT_EQ(snapshots.back().tracks.size(), 1U);
  EXPECT_EQ(snapshots.back().tracks[0].id, snapshots[9].tracks.at(0).id);
  EXPECT_EQ(t.node().counters().cloud_frames_out_of_order, 0U);
  EXPECT_EQ(t.counter("fogmap_centroid_frames_rejected_total", "late"), 0.0);
}

TEST(TrackerAdmission, DetectionFramesOutsideTheWindowAreRefusedAndTheCameraStaysFreshAndNamesItsPerson) {
  TrackerUnderTest t({.cameras = {frontCamera()}});
  const auto step = [&](int k) {
    t.now_ns = kT0 + k * 100 * kMs;
    const auto summary = t.pushDetections({personSeenAt(t.now_ns.load())});
    t.node().addGlobalMap(globalMapWith(t.now_ns.load(), {{8, 0, 0.5}}));
    return summary;
  };
  for (int k = 0; k < 10; ++k) EXPECT_EQ(step(k).refused(), 0U);
  // 64 frames dated a day ahead (the camera's whole buffer), then 64 dated a day back.
  std::vector<tracking::DetectionFrame> ahead, behind;
  for (int i = 0; i < 64; ++i) {
    ahead.push_back(personSeenAt(t.now_ns.load() + kDayNs + i * kMs));
    behind.push_back(personSeenAt(t.now_ns.load() - kDayNs + i * kMs));
  }
  EXPECT_EQ(t.pushDetections(ahead).refused(), 64U);
  // Frames from the past are no clock fault (a slow detector's frames are late): taken in, and
  // counted stale (exported with the next fusion step), as no LiDAR frame to come can use them.
  EXPECT_EQ(t.pushDetections(behind).refused(), 0U);
  EXPECT_EQ(t.counter("fogmap_detection_frames_dropped_total", "clock_skew"), 64.0);
  const auto staleness = t.node().tick();
  ASSERT_EQ(staleness.count("cam-1"), 1U);
  EXPECT_GE(staleness.at("cam-1"), 0.0);
  EXPECT_LT(staleness.at("cam-1"), 0.2) << "the camera's newest honest frame is the newest it has";
  // The honest frames that follow are all fused, none dropped, and the person keeps its name.
  for (int k = 10; k < 20; ++k) EXPECT_EQ(step(k).refused(), 0U);
  EXPECT_EQ(t.counter("fogmap_detection_frames_dropped_total", "overflow"), 0.0);
  EXPECT_EQ(t.counter("fogmap_detection_frames_dropped_total", "stale"), 64.0);
  EXPECT_EQ(t.node().counters().detections_fused, 20U) << "every step fused the camera's detection";
  const auto tracks = t.node().tracks();
  ASSERT_EQ(tracks.size(), 1U);
  EXPECT_EQ(tracks[0].label, "person");
  const double gauge = gaugeValue(t.metrics(), "fogmap_camera_staleness_seconds", "camera", "cam-1");
  EXPECT_GE(gauge, 0.0);
  EXPECT_LT(gauge, 0.2);
}

// A detector slower than the fusion waits (HOG on a loaded machine: every frame delivered 1.5 s
// after its capture) is late, not skewed: its frames are taken in and counted stale, and the camera
// is heard, its staleness the detector's delay, far below the 5 s of FogmapCameraStale.
TEST(TrackerAdmission, ASlowCameraIsHeardItsLateFramesCountedStaleNotRefused) {
  TrackerUnderTest t({.cameras = {frontCamera()}});
  constexpr std::int64_t kDelay = 1500 * kMs;
  for (int k = 0; k < 40; ++k) {
    t.now_ns = kT0 + k * 100 * kMs;
    t.node().addGlobalMap(globalMapWith(t.now_ns.load(), {{8, 0, 0.5}}));
    if (k % 5 == 0 && t.now_ns.load() - kDelay >= kT0) {
      EXPECT_EQ(t.pushDetections({personSeenAt(t.now_ns.load() - kDelay)}).refused(), 0U) << "step " << k;
    }
  }
  EXPECT_EQ(t.counter("fogmap_detection_frames_dropped_total", "clock_skew"), 0.0);
  EXPECT_EQ(t.counter("fogmap_detection_frames_dropped_total", "stale"), 5.0) << "captured at 0, 0.5, ... 2.0 s, each delivered 1.5 s later";
  const auto staleness = t.node().tick();
  ASSERT_EQ(staleness.count("cam-1"), 1U);
  EXPECT_NEAR(staleness.at("cam-1"), 1.9, 1e-9) << "now 3.9 s, newest capture at 2.0 s";
}

TEST(TrackerAdmission, AGlobalMapFromTheFutureIsRefusedAndTheTracksKeepComing) {
  TrackerUnderTest t({});
  const GlobalMapFeedHooks feed = globalMapFeedHooks(t.metrics(), t.trackerMetrics(), t.node(), t.log(), "root");
  for (int k = 0; k < 5; ++k) {
    t.now_ns = kT0 + k * 100 * kMs;
    feed.on_map(globalMapWith(t.now_ns.load(), {{8, 0.1 * k, 0.5}}), 100);
  }
  feed.on_map(globalMapWith(t.now_ns.load() + kYearNs, {{8, 0.5, 0.5}}), 100);
  EXPECT_EQ(counterValue(t.metrics(), "fogmap_global_maps_refused_total", "reason", "clock_skew"), 1.0);
  ASSERT_EQ(t.lines().size(), 1U);
  EXPECT_NE(t.lines()[0].find("refused global maps (clock_skew)"), std::string::npos) << t.lines()[0];
  for (int k = 5; k < 10; ++k) {
    t.now_ns = kT0 + k * 100 * kMs;
    feed.on_map(globalMapWith(t.now_ns.load(), {{8, 0.1 * k, 0.5}}), 100);
  }
  const auto snapshots = t.snapshots();
  ASSERT_EQ(snapshots.size(), 10U);
  EXPECT_EQ(snapshots.back().lidar_time_ns, kT0 + 900 * kMs);
  EXPECT_EQ(t.node().counters().cloud_frames_out_of_order, 0U);
}

TEST(TrackerAdmission, TheStalenessOfACameraThatStoppedGrowsOnEveryTickWithoutAnythingFused) {
  TrackerUnderTest t({.cameras = {frontCamera()}});
  EXPECT_EQ(t.pushDetections({personSeenAt(kT0)}).refused(), 0U);
  for (int s = 1; s <= 3; ++s) {
    t.now_ns = kT0 + s * 1'000'000'000LL;
    t.trackerMetrics().cameraStaleness(t.node().tick());
    EXPECT_DOUBLE_EQ(gaugeValue(t.metrics(), "fogmap_camera_staleness_seconds", "camera", "cam-1"), s);
  }
  EXPECT_TRUE(t.snapshots().empty()) << "no LiDAR frame: nothing fused, the gauge moved anyway";
}

TEST(TrackerAdmission, AFloodOfRefusedFramesWritesOneLinePerReasonPerBurstWithItsCount) {
  TrackerUnderTest t({.cameras = {frontCamera()}, .edges = {"edge-a"}});
  constexpr int kFlood = 5000;
  std::vector<tracking::DetectionFrame> ahead(kFlood, personSeenAt(kT0 + kDayNs));
  std::vector<v1::CentroidFrame> strangers(kFlood, toProto(centroidFrame("edge-z", kE0, kT0, {{1, 1}})));
  v1::CentroidFrame malformed = toProto(centroidFrame("edge-a", kE0, kT0, {{1, 1}}));
  malformed.mutable_centroids(0)->set_position(0, std::nanf(""));
  std::vector<v1::CentroidFrame> broken(kFlood, malformed);
  EXPECT_EQ(t.pushDetections(ahead).refused(), static_cast<unsigned>(kFlood));
  EXPECT_EQ(t.pushCentroids(strangers).refused(), static_cast<unsigned>(kFlood));
  EXPECT_EQ(t.pushCentroids(broken).refused(), static_cast<unsigned>(kFlood));
  // Every refusal counted, one line per reason while the clock stood still.
  EXPECT_EQ(t.counter("fogmap_detection_frames_dropped_total", "clock_skew"), kFlood);
  EXPECT_EQ(t.counter("fogmap_centroid_frames_rejected_total", "unknown_edge"), kFlood);
  EXPECT_EQ(t.counter("fogmap_centroid_frames_rejected_total", "malformed"), kFlood);
  auto lines = t.lines();
  ASSERT_EQ(lines.size(), 3U);
  EXPECT_NE(lines[0].find("refused detection frames (clock_skew): camera 'cam-1': captured 86400000 ms ahead"),
            std::string::npos)
      << lines[0];
  EXPECT_NE(lines[1].find("refused centroid frames (unknown_edge): edge 'edge-z'"), std::string::npos) << lines[1];
  EXPECT_NE(lines[2].find("refused centroid frames (malformed)"), std::string::npos) << lines[2];
  // Once the bursts went quiet, each is summarised with its count.
  t.now_ns = kT0 + 6'000'000'000LL;
  t.log().flush();
  lines = t.lines();
  ASSERT_EQ(lines.size(), 6U);
  for (std::size_t i = 3; i < 6; ++i) EXPECT_NE(lines[i].find(": 4999 more in the last"), std::string::npos) << lines[i];
}

TEST(TrackerAdmission, SubscribersBeyondTheBoundAreRefusedAsResourceExhaustedAndCounted) {
  TrackerUnderTest t({.max_subscribers = 2});
  v1::TrackSubscribeRequest request;
  grpc::ClientContext first_context, second_context;
  first_context.set_wait_for_ready(true);
  second_context.set_wait_for_ready(true);
  auto first = t.stub().Subscribe(&first_context, request);
  auto second = t.stub().Subscribe(&second_context, request);
  ASSERT_TRUE(test_support::eventually([&] { return t.service().subscriberCount() == 2; }));
  grpc::ClientContext third_context;
  // A deadline only so that a tracker which serves it fails this test instead of hanging it.
  third_context.set_deadline(std::chrono::system_clock::now() + 30s);
  third_context.set_wait_for_ready(true);
  auto third = t.stub().Subscribe(&third_context, request);
  v1::TrackList list;
  EXPECT_FALSE(third->Read(&list));
  const grpc::Status status = third->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(status.error_message().find("max_subscribers"), std::string::npos) << status.error_message();
  EXPECT_EQ(counterValue(t.metrics(), "fogmap_subscribers_refused_total", "node", "tracker"), 1.0);
  EXPECT_EQ(t.service().subscriberCount(), 2U);
  // One leaves: the next one is served.
  first_context.TryCancel();
  ASSERT_TRUE(test_support::eventually([&] { return t.service().subscriberCount() == 1; }));
  grpc::ClientContext fourth_context;
  fourth_context.set_wait_for_ready(true);
  auto fourth = t.stub().Subscribe(&fourth_context, request);
  ASSERT_TRUE(test_support::eventually([&] { return t.service().subscriberCount() == 2; }));
  EXPECT_EQ(counterValue(t.metrics(), "fogmap_subscribers_refused_total", "node", "tracker"), 1.0);
  second_context.TryCancel();
  fourth_context.TryCancel();
}

TEST(TrackerAdmission, AFloodOfClutterIsShedByTheFusionBudgetAndThePeopleKeepTheirTrackIds) {
  // Every fusion call is measured to take 125 ms (the cost of 1,000 centroids the flood once had):
  // the budget is what fits half a period at that cost, never below 64.
  std::atomic<std::int64_t> stopwatch{0};
  TrackerUnderTest t({.edges = {"edge-a"}, .stopwatch = [&] { return stopwatch += 125 * kMs; }});
  const auto people = [](std::uint64_t k) {
    std::vector<Eigen::Vector2d> out;
    for (int i = 0; i < 6; ++i) {
      out.emplace_back(3.0 * i, -5.0 + 0.1 * static_cast<double>(k) * (i % 2 == 0 ? 1 : -1) + 0.5 * i);
    }
    return out;
  };
  // Clutter on a 2 m lattice, jittered anew every epoch by up to 0.4 m: never within the 1 m merge
  // radius of another, so every centroid is an observation of its own.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> jitter(-0.4, 0.4);
  std::map<int, std::uint64_t> ids;
  for (std::uint64_t k = 0; k < 40; ++k) {
    t.now_ns = startOf(kE0 + k) + 10 * kMs;
    auto frame = centroidFrame("edge-a", kE0 + k, startOf(kE0 + k) + 2 * kMs, people(k), 30);
    if (k >= 10) {
      for (int j = 0; j < 1000; ++j) {
        const Eigen::Vector3d at(30.0 + 2.0 * (j % 50) + jitter(rng), -20.0 + 2.0 * (j / 50) + jitter(rng), 0.9);
        frame.centroids.push_back({at, Eigen::Matrix3d::Identity() * 0.02, 600});
      }
    }
    ASSERT_EQ(t.pushCentroids({toProto(frame)}).refused(), 0U) << "epoch " << k;
    const auto snapshots = t.snapshots();
    ASSERT_EQ(snapshots.size(), k + 1);
    if (k < 5) continue;  // confirmed after 3 hits
    for (int i = 0; i < 6; ++i) {
      const tracking::Track* best = nullptr;
      for (const auto& track : snapshots.back().tracks) {
        if ((track.position - people(k)[static_cast<std::size_t>(i)]).norm() < 0.5) best = &track;
      }
      ASSERT_NE(best, nullptr) << "person " << i << ", epoch " << k;
      EXPECT_EQ(best->state, tracking::TrackState::kConfirmed);
      if (k == 5) ids[i] = best->id;
      EXPECT_EQ(best->id, ids[i]) << "person " << i << " changed track at epoch " << k;
    }
  }
  // 30 flood epochs of 1,006 observations, 64 taken each.
  EXPECT_EQ(t.node().measurementBudget(), 64U);
  EXPECT_EQ(t.counter("fogmap_measurements_shed_total", "over_budget"), 30.0 * (1006 - 64));
  EXPECT_EQ(gaugeValue(t.metrics(), "fogmap_fusion_budget_measurements", "node", "tracker"), 64.0);
  for (const auto& report : t.reports()) {
    for (const auto& step : report.steps) EXPECT_LE(step.measurements, 64U);
  }
}

}  // namespace
}  // namespace fogmap
