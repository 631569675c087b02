#include "services/common/tracker_link.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "tests/support/eventually.hpp"
#include "tests/support/recording_tracker.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
using test_support::RecordingTracker;
using test_support::TestTracker;
using test_support::eventually;
using Clock = std::chrono::steady_clock;

// A port that was free a moment ago and now has no listener.
int closedTrackerPort() {
  RecordingTracker service;
  TestTracker tracker(service);
  return tracker.port();
}

tracking::DetectionFrame frameAt(std::int64_t capture_time_ns, int detections = 1) {
  tracking::DetectionFrame frame;
  frame.camera = "cam-front";
  frame.capture_time_ns = capture_time_ns;
  for (int i = 0; i < detections; ++i) {
    camera::Detection d;
    d.box = {10.0 + i, 20.0, 50.0 + i, 120.0};
    d.label = i % 2 == 0 ? "person" : "car";
    d.score = 0.5 + 0.1 * i;
    d.camera = frame.camera;
    d.capture_time_ns = capture_time_ns;
    frame.detections.push_back(d);
  }
  return frame;
}

// Counts what the hooks report.
struct LinkCounts {
  std::atomic<std::uint64_t> sent{0}, bytes{0}, reconnects{0}, drops{0}, bursts{0};
  TrackerLinkHooks hooks() {
    TrackerLinkHooks h;
    h.on_sent = [this](std::size_t b) {
      ++sent;
      bytes += b;
    };
    h.on_reconnect = [this] { ++reconnects; };
    h.on_dropped = [this](std::uint64_t /*total*/, bool first) {
      ++drops;
      if (first) ++bursts;
    };
    return h;
  }
};

TrackerLinkConfig trackerLinkConfig(const std::string& target, std::size_t queue_frames = 4) {
  TrackerLinkConfig config;
  config.target = target;
  config.queue_frames = queue_frames;
  return config;
}

TEST(DetectionLink, DeliversEveryFrameWithItsCameraAndDetections) {
  RecordingTracker service;
  TestTracker tracker(service);
  ASSERT_TRUE(tracker.started());
  LinkCounts counts;
  DetectionLink link(trackerLinkConfig(tracker.target(), 8), counts.hooks());
  for (int i = 0; i < 3; ++i) link.send(frameAt(1'000 + i, i + 1));
  ASSERT_TRUE(service.waitFrames(3));

  const std::vector<tracking::DetectionFrame> got = service.frames();
  ASSERT_EQ(got.size(), 3u);
  EXPECT_TRUE(service.errors().empty());
  for (int i = 0; i < 3; ++i) {
    const tracking::DetectionFrame sent = frameAt(1'000 + i, i + 1);
    EXPECT_EQ(got[i].camera, "cam-front");
    EXPECT_EQ(got[i].capture_time_ns, 1'000 + i);
    ASSERT_EQ(got[i].detections.size(), sent.detections.size());
    for (std::size_t k = 0; k < sent.detections.size(); ++k) {
      EXPECT_EQ(got[i].detections[k].label, sent.detections[k].label);
      EXPECT_FLOAT_EQ(got[i].detections[k].box.left, sent.detections[k].box.left);
      EXPECT_FLOAT_EQ(got[i].detections[k].box.bottom, sent.detections[k].box.bottom);
      EXPECT_FLOAT_EQ(got[i].detections[k].score, sent.detections[k].score);
      EXPECT_EQ(got[i].detections[k].camera, "cam-front");
    }
  }
  ASSERT_TRUE(link.flush(5s));
  EXPECT_EQ(link.sent(), 3u);
  EXPECT_EQ(link.dropped(), 0u);
  EXPECT_EQ(counts.sent.load(), 3u);
  EXPECT_GT(counts.bytes.load(), 0u);
}

TEST(DetectionLink, WhileTheTrackerIsDownTheOldestFramesAreDroppedThenItReconnectsAndDelivers) {
  const int port = closedTrackerPort();
  ASSERT_GT(port, 0);
  LinkCounts counts;
  DetectionLink link(trackerLinkConfig("127.0.0.1:" + std::to_string(port), 3), counts.hooks());
  for (int i = 1; i <= 8; ++i) link.send(frameAt(i));
  EXPECT_FALSE(link.connected());
  EXPECT_EQ(link.dropped(), 5u);
  EXPECT_EQ(link.queued(), 3u);
  EXPECT_EQ(counts.drops.load(), 5u);
  EXPECT_EQ(counts.bursts.load(), 1u) << "one burst of drops, logged once";

  RecordingTracker service;
  TestTracker tracker(service, port);
  ASSERT_TRUE(tracker.started()) << "port " << port << " could not be bound again";
  ASSERT_TRUE(service.waitFrames(3));
  std::vector<std::int64_t> captures;
  for (const auto& f : service.frames()) captures.push_back(f.capture_time_ns);
  EXPECT_EQ(captures, (std::vector<std::int64_t>{6, 7, 8})) << "the newest frames, in order";

  link.send(frameAt(9));
  ASSERT_TRUE(service.waitFrames(4));
  EXPECT_EQ(service.frames().back().capture_time_ns, 9);
  EXPECT_TRUE(link.connected());
  EXPECT_EQ(link.dropped(), 5u);
}

TEST(DetectionLink, ReconnectsToARestartedTracker) {
  RecordingTracker first_service;
  auto first = std::make_unique<TestTracker>(first_service);
  ASSERT_TRUE(first->started());
  const int port = first->port();
  LinkCounts counts;
  DetectionLink link(trackerLinkConfig(first->target()), counts.hooks());
  link.send(frameAt(1));
  ASSERT_TRUE(first_service.waitFrames(1));
  first->stop();

  RecordingTracker second_service;
  TestTracker second(second_service, port);
  ASSERT_TRUE(second.started()) << "port " << port << " could not be bound again";
  // Frames written into the dead stream are lost (and counted); keep sending until one arrives.
  std::int64_t capture = 2;
  ASSERT_TRUE(eventually([&] {
    link.send(frameAt(capture++));
    return second_service.waitFrames(1, 20ms);
  }));
  EXPECT_GE(counts.reconnects.load(), 1u);
  ASSERT_TRUE(link.flush(5s));
  EXPECT_EQ(link.sent() + link.dropped() + link.queued(), static_cast<std::uint64_t>(capture - 1));
}

TEST(DetectionLink, DestroyingTheLinkEndsTheStreamCleanly) {
  RecordingTracker service;
  TestTracker tracker(service);
  ASSERT_TRUE(tracker.started());
  {
    DetectionLink link(trackerLinkConfig(tracker.target()), {});
    link.send(frameAt(1));
    ASSERT_TRUE(service.waitFrames(1));
  }
  EXPECT_TRUE(service.waitStreamsEnded(1, 2s)) << "the tracker should see the stream half-closed";
}

TEST(DetectionLink, DestructorReturnsPromptlyWhenTheTrackerIsGone) {
  const int port = closedTrackerPort();
  const auto started = Clock::now();
  {
    DetectionLink link(trackerLinkConfig("127.0.0.1:" + std::to_string(port)), {});
    link.send(frameAt(1));
  }
  EXPECT_LT(Clock::now() - started, 2s);
}

TEST(CentroidLink, DeliversEveryCentroidFrameOnItsOwnStream) {
  RecordingTracker service;
  TestTracker tracker(service);
  ASSERT_TRUE(tracker.started());
  LinkCounts counts;
  CentroidLink link(trackerLinkConfig(tracker.target(), 8), counts.hooks());
  for (int i = 0; i < 3; ++i) {
    tracking::CentroidFrame frame;
    frame.edge = "edge-3";
    frame.epoch = 100 + static_cast<std::uint64_t>(i);
    frame.time_ns = 5'000 + i;
    frame.sensor_position = {1.0, 2.0, 1.5};
    for (int k = 0; k < i; ++k) {
      frame.centroids.push_back({Eigen::Vector3d(k, 0.5, 1.0), Eigen::Matrix3d::Identity() * 0.25, static_cast<std::size_t>(7 + k)});
    }
    link.send(frame);
  }
  ASSERT_TRUE(service.waitCentroidFrames(3));
  const auto got = service.centroidFrames();
  EXPECT_TRUE(service.frames().empty()) << "centroids are not detections";
  EXPECT_TRUE(service.errors().empty());
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(got[i].edge, "edge-3");
    EXPECT_EQ(got[i].epoch, 100U + i);
    EXPECT_EQ(got[i].time_ns, 5'000 + i);
    EXPECT_EQ(got[i].sensor_position, Eigen::Vector3d(1.0, 2.0, 1.5));
    ASSERT_EQ(got[i].centroids.size(), static_cast<std::size_t>(i));
    for (int k = 0; k < i; ++k) {
      EXPECT_EQ(got[i].centroids[k].position, Eigen::Vector3d(k, 0.5, 1.0));
      EXPECT_EQ(got[i].centroids[k].covariance, Eigen::Matrix3d::Identity() * 0.25);
      EXPECT_EQ(got[i].centroids[k].point_count, static_cast<std::size_t>(7 + k));
    }
  }
  ASSERT_TRUE(link.flush(5s));
  EXPECT_EQ(link.sent(), 3u);
  EXPECT_EQ(counts.sent.load(), 3u);
}

}  // namespace
}  // namespace fogmap
