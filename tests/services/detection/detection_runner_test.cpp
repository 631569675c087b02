#include "services/detection/detection_runner.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "common/camera/kitti.hpp"
#include "common/config/camera_node.hpp"
#include "common/sim/camera_truth.hpp"
#include "common/sim/generators.hpp"
#include "common/sim/raycaster.hpp"
#include "common/sim/sensor_frames.hpp"
#include "services/common/metrics.hpp"
#include "services/detection/detection_metrics.hpp"
#include "tests/support/metric_values.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;

using test_support::kSourceDir;
// About 2023-11-14 in unix ns: frame numbers since the epoch are as large as in service.
constexpr std::int64_t kStartNs = 1'700'000'000'000'000'000;

// A clock the test drives: a wait moves it to the awaited instant at once, and every wait is
// recorded.
class ManualClock {
 public:
  std::int64_t now() const { return now_.load(); }
  bool waitUntil(std::int64_t until_ns) {
    std::lock_guard lock(mu_);
    waits_.push_back(until_ns);
    if (until_ns > now_.load()) now_.store(until_ns);
    return true;
  }
  void set(std::int64_t ns) { now_.store(ns); }
  std::vector<std::int64_t> waits() const {
    std::lock_guard lock(mu_);
    return waits_;
  }

 private:
  std::atomic<std::int64_t> now_{kStartNs};
  mutable std::mutex mu_;
  std::vector<std::int64_t> waits_;
};

// A one-shot event a test waits on, bounded.
class Signal {
 public:
  void set() {
    {
      std::lock_guard lock(mu_);
      set_ = true;
    }
    cv_.notify_all();
  }
  bool wait(std::chrono::milliseconds timeout = 10s) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, timeout, [&] { return set_; });
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  bool set_ = false;
};

// Frames from memory, due every 100 ms; hooks let a test hold the reader at a frame.
class ListSource final : public FrameSource {
 public:
  explicit ListSource(std::size_t frames, std::function<void(std::size_t)> before_frame = {})
      : frames_(frames), before_frame_(std::move(before_frame)) {}
  SourceFrame next() override {
    if (next_ == frames_) {
      done_.set();
      return {};
    }
    if (before_frame_) before_frame_(next_);
    SourceFrame f;
    f.outcome = FrameOutcome::kFrame;
    // The frame's number in the pixel values, so the detector can tell which frame it saw.
    f.image_bgr = cv::Mat(48, 64, CV_8UC3, cv::Scalar(static_cast<double>(next_), 0, 0));
    f.due_ns = static_cast<std::int64_t>(next_) * 100'000'000;
    f.origin = "frame " + std::to_string(next_);
    ++next_;
    return f;
  }
  std::string describe() const override { return "list"; }
  Signal& done() { return done_; }

 private:
  std::size_t frames_;
  std::function<void(std::size_t)> before_frame_;
  std::size_t next_ = 0;
  Signal done_;
};

// Reports one "frame-N" detection per image, N read back from the pixels; a hook may hold it.
class NumberingDetector final : public camera::Detector {
 public:
  explicit NumberingDetector(std::function<void(int)> on_detect = {}) : on_detect_(std::move(on_detect)) {}
  camera::DetectResult detectFrame(const cv::Mat& image_bgr, const std::string& camera,
                                   std::int64_t capture_time_ns) override {
    const int number = image_bgr.at<cv::Vec3b>(0, 0)[0];
    if (on_detect_) on_detect_(number);
    camera::Detection d;
    d.box = {1, 2, 30, 40};
    d.label = "frame-" + std::to_string(number);
    d.score = 1.0;
    d.camera = camera;
    d.capture_time_ns = capture_time_ns;
    camera::DetectResult result;
    result.detections = {d};
    return result;
  }

 private:
  std::function<void(int)> on_detect_;
};

class CountingObserver final : public DetectionObserver {
 public:
  void frameRead() override { ++read; }
  void frameUnreadable(FrameFailure failure) override {
    ++unreadable;
    std::lock_guard lock(mu);
    ++frame_failures[frameFailureName(failure)];
  }
  void detectFailed(const std::string& reason) override {
    std::lock_guard lock(mu);
    ++detector_failures[reason];
  }
  std::map<std::string, int> frameFailures() {
    std::lock_guard lock(mu);
    return frame_failures;
  }
  std::map<std::string, int> detectorFailures() {
    std::lock_guard lock(mu);
    return detector_failures;
  }
  void framesDropped(std::uint64_t frames) override { dropped += frames; }
  void frameDetected(std::size_t n, double /*seconds*/) override {
    ++detected;
    detections += n;
  }
  std::atomic<std::uint64_t> read{0}, unreadable{0}, dropped{0}, detected{0}, detections{0};

 private:
  std::mutex mu;
  std::map<std::string, int> frame_failures, detector_failures;
};

// What reached the sink, thread-safe.
struct Delivered {
  std::mutex mu;
  std::vector<tracking::DetectionFrame> frames;
  std::vector<std::int64_t> clock_at_delivery;
  std::vector<std::string> log;
};

DetectionRunnerHooks hooksFor(ManualClock& clock, Delivered& out, DetectionObserver* observer = nullptr) {
  DetectionRunnerHooks hooks;
  hooks.now = [&clock] { return clock.now(); };
  hooks.wait_until = [&clock](std::int64_t t) { return clock.waitUntil(t); };
  hooks.deliver = [&clock, &out](tracking::DetectionFrame frame) {
    std::lock_guard lock(out.mu);
    out.frames.push_back(std::move(frame));
    out.clock_at_delivery.push_back(clock.now());
  };
  hooks.log = [&out](const std::string& line) {
    std::lock_guard lock(out.mu);
    out.log.push_back(line);
  };
  hooks.observer = observer;
  return hooks;
}

TEST(DetectionRunner, StampsEveryFrameWithTheCameraAndItsScheduledTime) {
  ManualClock clock;
  Delivered out;
  auto source = openImageDirectory(kSourceDir / "data/kitti_raw_seq_a/image_02", ReplayConfig{10.0, false, std::nullopt});
  ASSERT_TRUE(source.ok()) << source.error().message;
  NumberingDetector detector;
  CountingObserver observer;
  DetectionRunner runner("cam-front", **source, detector, 8, hooksFor(clock, out, &observer));
  runner.run();

  ASSERT_EQ(out.frames.size(), 3u);
  for (std::size_t i = 0; i < out.frames.size(); ++i) {
    const std::int64_t scheduled = kStartNs + static_cast<std::int64_t>(i) * 100'000'000;
    EXPECT_EQ(out.frames[i].camera, "cam-front");
    EXPECT_EQ(out.frames[i].capture_time_ns, scheduled) << "frame " << i;
    ASSERT_EQ(out.frames[i].detections.size(), 1u);
    EXPECT_EQ(out.frames[i].detections[0].camera, "cam-front");
    EXPECT_EQ(out.frames[i].detections[0].capture_time_ns, scheduled);
  }
  EXPECT_EQ(clock.waits(), (std::vector<std::int64_t>{kStartNs, kStartNs + 100'000'000, kStartNs + 200'000'000}));
  const DetectionRunnerStats stats = runner.stats();
  EXPECT_EQ(stats.frames_read, 3u);
  EXPECT_EQ(stats.frames_detected, 3u);
  EXPECT_EQ(stats.detections, 3u);
  EXPECT_EQ(stats.frames_dropped, 0u);
  EXPECT_EQ(observer.read.load(), 3u);
  EXPECT_EQ(observer.detected.load(), 3u);
}

TEST(DetectionRunner, AnUnreadableImageIsSkippedCountedAndLoggedWithItsPath) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "fogmap_runner_unreadable";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(kSourceDir / "data/kitti_raw_seq_a/image_02/0000000000.png", dir / "a.png");
  std::ofstream(dir / "b.png") << "not an image";
  auto source = openImageDirectory(dir, ReplayConfig{10.0, false, std::nullopt});
  ASSERT_TRUE(source.ok()) << source.error().message;
  ManualClock clock;
  Delivered out;
  NumberingDetector detector;
  CountingObserver observer;
  DetectionRunner runner("cam", **source, detector, 4, hooksFor(clock, out, &observer));
  runner.run();
  std::filesystem::remove_all(dir);

  EXPECT_EQ(out.frames.size(), 1u);
  EXPECT_EQ(runner.stats().frames_unreadable, 1u);
  EXPECT_EQ(runner.stats().frames_read, 1u);
  EXPECT_EQ(observer.unreadable.load(), 1u);
  ASSERT_EQ(out.log.size(), 1u);
  EXPECT_NE(out.log[0].find((dir / "b.png").string()), std::string::npos) << out.log[0];
}

TEST(DetectionRunner, HogFindsTheKittiPedestrianAndStampsItWithCameraAndCaptureTime) {
  const cv::Mat image = cv::imread((kSourceDir / "data/kitti_object/image_2/000000.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  std::ifstream label_file(kSourceDir / "data/kitti_object/label_2/000000.txt");
  std::stringstream label_text;
  label_text << label_file.rdbuf();
  const auto labels = camera::parseKittiLabels(label_text.str());
  ASSERT_TRUE(labels.ok() && labels->size() == 1u);

  // One frame: the KITTI image, due at once.
  class OneImage final : public FrameSource {
   public:
    explicit OneImage(cv::Mat image) : image_(std::move(image)) {}
    SourceFrame next() override {
      if (given_) return {};
      given_ = true;
      SourceFrame f;
      f.outcome = FrameOutcome::kFrame;
      f.image_bgr = image_;
      f.due_ns = 0;
      return f;
    }
    std::string describe() const override { return "one image"; }

   private:
    cv::Mat image_;
    bool given_ = false;
  } source(image);

  camera::DetectorConfig config;
  config.kind = camera::DetectorKind::kHog;
  config.hog.upscale = 1.5;
  auto detector = camera::makeDetector(config);
  ASSERT_TRUE(detector.ok()) << detector.error().message;
  ManualClock clock;
  Delivered out;
  DetectionRunner runner("cam-kitti", source, **detector, 2, hooksFor(clock, out));
  runner.run();

  ASSERT_EQ(out.frames.size(), 1u);
  const tracking::DetectionFrame& frame = out.frames[0];
  EXPECT_EQ(frame.camera, "cam-kitti");
  EXPECT_EQ(frame.capture_time_ns, kStartNs);
  double best = 0.0;
  for (const camera::Detection& d : frame.detections) {
    EXPECT_EQ(d.label, "person");
    EXPECT_EQ(d.camera, "cam-kitti");
    EXPECT_EQ(d.capture_time_ns, kStartNs);
    best = std::max(best, camera::iou(d.box, labels->front().box));
  }
  EXPECT_GE(best, 0.5) << frame.detections.size() << " detection(s), none on the labelled pedestrian";
  EXPECT_GT(runner.stats().detect_seconds, -1.0);
}

TEST(DetectionRunner, AQueueFullBehindASlowDetectorDropsTheOldestFramesAndCountsThem) {
  ManualClock clock;
  Delivered out;
  Signal detecting_first;
  // The reader waits for the detector to be busy with frame 0 before it reads frame 1, and the
  // detector stays busy until the reader has read all five: frames 1..4 meet a queue of 2.
  ListSource source(5, [&](std::size_t frame) {
    if (frame == 1) {
      ASSERT_TRUE(detecting_first.wait());
    }
  });
  NumberingDetector detector([&](int number) {
    if (number == 0) {
      detecting_first.set();
      ASSERT_TRUE(source.done().wait());
    }
  });
  CountingObserver observer;
  DetectionRunner runner("cam", source, detector, 2, hooksFor(clock, out, &observer));
  runner.run();

  std::vector<std::string> seen;
  for (const auto& f : out.frames) seen.push_back(f.detections.at(0).label);
  EXPECT_EQ(seen, (std::vector<std::string>{"frame-0", "frame-3", "frame-4"}));
  EXPECT_EQ(out.frames.at(1).capture_time_ns, kStartNs + 300'000'000);
  const DetectionRunnerStats stats = runner.stats();
  EXPECT_EQ(stats.frames_read, 5u);
  EXPECT_EQ(stats.frames_dropped, 2u);
  EXPECT_EQ(stats.frames_detected, 3u);
  EXPECT_EQ(observer.dropped.load(), 2u);
}

TEST(DetectionRunner, StopEndsBothLoopsWithoutDeliveringMore) {
  ManualClock clock;
  Delivered out;
  DetectionRunner* running = nullptr;
  ListSource source(1000, [&](std::size_t frame) {
    if (frame == 3) running->stop();
  });
  NumberingDetector detector;
  DetectionRunner runner("cam", source, detector, 2, hooksFor(clock, out));
  running = &runner;
  runner.run();
  EXPECT_TRUE(runner.stopped());
  EXPECT_LE(runner.stats().frames_read, 3u);
  EXPECT_LE(out.frames.size(), 3u);
}

// Frames that all fail: the first `unreadable` of them too large for the source, the rest refused
// by the detector (RefusingDetector), due every 100 ms.
class FailingSource final : public FrameSource {
 public:
  FailingSource(std::size_t unreadable, std::size_t refused) : unreadable_(unreadable), refused_(refused) {}
  SourceFrame next() override {
    if (next_ == unreadable_ + refused_) return {};
    SourceFrame f;
    f.due_ns = static_cast<std::int64_t>(next_) * 100'000'000;
    f.origin = "/images/" + std::to_string(next_) + ".png";
    if (next_++ < unreadable_) {
      f.outcome = FrameOutcome::kUnreadable;
      f.failure = FrameFailure::kTooLarge;
      f.problem = f.origin + ": 20000 x 20000 (400000000 pixels) PNG, above the camera's max_image_pixels";
      return f;
    }
    f.outcome = FrameOutcome::kFrame;
    f.image_bgr = cv::Mat(8, 8, CV_8UC3, cv::Scalar(0, 0, 0));
    return f;
  }
  std::string describe() const override { return "failing"; }

 private:
  std::size_t unreadable_, refused_;
  std::size_t next_ = 0;
};

// Refuses every frame as a network whose outputs do not fit the config would.
class RefusingDetector final : public camera::Detector {
 public:
  camera::DetectResult detectFrame(const cv::Mat&, const std::string&, std::int64_t) override {
    camera::DetectResult result;
    result.refusal = camera::DetectRefusal{camera::DetectFailure::kModelOutputMismatch,
                                           invalidArgument("dnn: output 'out' has shape [1, 1, 1, 7]; output "
                                                           "yolo-export expects [N, 5 + classes]")};
    return result;
  }
};

TEST(DetectionRunner, FailuresAreCountedByReasonAndLoggedOncePerBurstNotPerFrame) {
  ManualClock clock;
  Delivered out;
  FailingSource source(50, 50);
  RefusingDetector detector;
  CountingObserver observer;
  Metrics metrics("", "detection", "cam");
  DetectionMetrics detection_metrics(metrics, "cam");
  // Both the test's observer and the service's metrics see every event.
  class Both final : public DetectionObserver {
   public:
    Both(DetectionObserver& a, DetectionObserver& b) : a_(a), b_(b) {}
    void frameUnreadable(FrameFailure f) override {
      a_.frameUnreadable(f);
      b_.frameUnreadable(f);
    }
    void detectFailed(const std::string& reason) override {
      a_.detectFailed(reason);
      b_.detectFailed(reason);
    }

   private:
    DetectionObserver& a_;
    DetectionObserver& b_;
  } both(observer, detection_metrics);
  DetectionRunner runner("cam", source, detector, 100, hooksFor(clock, out, &both));
  EXPECT_TRUE(runner.run());

  EXPECT_EQ(observer.frameFailures(), (std::map<std::string, int>{{"too_large", 50}}));
  EXPECT_EQ(observer.detectorFailures(), (std::map<std::string, int>{{"model_output_mismatch", 50}}));
  EXPECT_EQ(runner.stats().frames_unreadable, 50u);
  EXPECT_EQ(runner.stats().detect_failures, 50u);
  EXPECT_TRUE(out.frames.empty());
  using test_support::counterValue;
  EXPECT_EQ(counterValue(metrics, "fogmap_detection_failures_total", "reason", "too_large"), 50.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_detection_failures_total", "reason", "model_output_mismatch"), 50.0);
  EXPECT_EQ(counterValue(metrics, "fogmap_detection_failures_total", "reason", "decode_failed"), 0.0);

  // 100 failures over 10 s of the clock: a line opening each reason's burst (naming the file and
  // the sizes, or the output's shape) and a summary with the count, not 100 lines.
  EXPECT_LE(out.log.size(), 6u);
  const auto logged = [&](const std::string& text) {
    return std::any_of(out.log.begin(), out.log.end(), [&](const std::string& l) { return l.find(text) != std::string::npos; });
  };
  EXPECT_TRUE(logged("/images/0.png: 20000 x 20000")) << ::testing::PrintToString(out.log);
  EXPECT_TRUE(logged("model_output_mismatch")) << ::testing::PrintToString(out.log);
  EXPECT_TRUE(logged("[1, 1, 1, 7]")) << ::testing::PrintToString(out.log);
  EXPECT_TRUE(logged("49 more")) << ::testing::PrintToString(out.log);
}

// Reports `count` detections per image, scores 0, 1, ..., count - 1 in a shuffled order.
class CrowdDetector final : public camera::Detector {
 public:
  explicit CrowdDetector(int count) : count_(count) {}
  camera::DetectResult detectFrame(const cv::Mat& /*image_bgr*/, const std::string& camera,
                                   std::int64_t capture_time_ns) override {
    camera::DetectResult result;
    for (int i = 0; i < count_; ++i) {
      camera::Detection d;
      d.box = {1, 2, 30, 40};
      d.label = "person";
      d.score = static_cast<double>((i * 7919) % count_);  // a permutation of 0 .. count - 1 (7919 is prime)
      d.camera = camera;
      d.capture_time_ns = capture_time_ns;
      result.detections.push_back(d);
    }
    return result;
  }

 private:
  int count_;
};

TEST(DetectionRunner, AFrameWithMoreDetectionsThanTheTrackerTakesKeepsTheMostConfidentAndCountsTheRest) {
  ManualClock clock;
  Delivered out;
  ListSource source(3);
  CrowdDetector detector(1500);
  Metrics metrics("", "detection", "cam");
  DetectionMetrics detection_metrics(metrics, "cam");
  DetectionRunnerHooks hooks = hooksFor(clock, out, &detection_metrics);
  hooks.max_detections = 1000;
  DetectionRunner runner("cam", source, detector, 100, std::move(hooks));
  EXPECT_TRUE(runner.run());
  ASSERT_EQ(out.frames.size(), 3u);
  for (const auto& frame : out.frames) {
    ASSERT_EQ(frame.detections.size(), 1000u);
    double lowest = 1e9;
    for (const auto& d : frame.detections) lowest = std::min(lowest, d.score);
    EXPECT_EQ(lowest, 500.0) << "the 500 least confident (scores 0 to 499) are the ones left out";
  }
  EXPECT_EQ(test_support::counterValue(metrics, "fogmap_detections_capped_total", "node", "cam"), 3.0 * 500.0);
  EXPECT_LE(out.log.size(), 2u) << "one line per burst, not one per frame";
}

TEST(DetectionRunner, AStopDoesNotWaitForADetectionInProgressBeyondItsGrace) {
  ManualClock clock;
  Delivered out;
  std::atomic<bool> stop_requested{false};
  Signal detecting;
  Signal release;
  ListSource source(1000);
  NumberingDetector detector([&](int) {
    detecting.set();
    // A detection that takes as long as the test says (HOG at a large upscale takes seconds).
    ASSERT_TRUE(release.wait(60s));
  });
  DetectionRunnerHooks hooks = hooksFor(clock, out);
  hooks.stop_requested = [&] { return stop_requested.load(); };
  // Once the stop is requested, every look at the clock finds it 100 ms later: the grace passes
  // on the clock the test drives, however long the machine takes.
  hooks.now = [&] {
    if (stop_requested.load()) clock.set(clock.now() + 100'000'000);
    return clock.now();
  };
  hooks.stop_grace_ns = 500'000'000;
  auto runner = std::make_unique<DetectionRunner>("cam", source, detector, 2, std::move(hooks));
  Signal returned;
  std::atomic<bool> ended{true};
  std::thread running([&] {
    ended = runner->run();
    returned.set();
  });
  ASSERT_TRUE(detecting.wait());
  const std::int64_t stop_at = clock.now();
  stop_requested = true;
  ASSERT_TRUE(returned.wait(60s)) << "run() waited for the detection in progress";
  EXPECT_FALSE(ended.load()) << "run() must say a loop was left running";
  EXPECT_GE(clock.now() - stop_at, 500'000'000) << "run() returned before the grace had passed";
  EXPECT_TRUE(out.frames.empty());
  // The detection ends later; the runner's destructor waits for it, and nothing more is delivered.
  release.set();
  running.join();
  runner.reset();
  EXPECT_TRUE(out.frames.empty());
}

TEST(DetectionRunner, AStopRequestedBetweenFramesEndsBothLoopsAtOnce) {
  ManualClock clock;
  Delivered out;
  std::atomic<bool> stop_requested{false};
  ListSource source(1000, [&](std::size_t frame) {
    if (frame == 3) stop_requested = true;
  });
  NumberingDetector detector;
  DetectionRunnerHooks hooks = hooksFor(clock, out);
  hooks.stop_requested = [&] { return stop_requested.load(); };
  DetectionRunner runner("cam", source, detector, 2, std::move(hooks));
  EXPECT_TRUE(runner.run()) << "nothing was running when the stop came: both loops end";
  EXPECT_LE(runner.stats().frames_read, 3u);
  EXPECT_LE(out.frames.size(), 3u);
}

// ---- Truth replay ----------------------------------------------------------------------------

// One person walking to and fro across the view of one camera.
sim::Scene walkingPersonScene() {
  sim::Scene scene;
  scene.name = "walk";
  scene.duration_s = 60.0;
  sim::SceneObject person;
  person.id = 1;
  person.name = "walker";
  person.label = "person";
  person.parts.push_back({sim::Shape::kBox, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.5, 0.5, 1.8), 0.0});
  person.motion.waypoints = {Eigen::Vector2d(8.0, -2.0), Eigen::Vector2d(8.0, 2.0)};
  person.motion.speed_mps = 0.5;
  person.motion.loop = true;
  scene.objects.push_back(person);
  sim::CameraConfig camera;
  camera.name = "cam0";
  camera.pose = sim::lookAt(Eigen::Vector3d(0.0, 0.0, 1.5), Eigen::Vector3d(8.0, 0.0, 0.9));
  scene.cameras.push_back(camera);
  return scene;
}

TEST(DetectionRunner, TruthReplayShowsTheLidarsInstantAndDeliversAfterTheLatency) {
  const sim::Scene scene = walkingPersonScene();
  CameraNodeConfig config;
  config.source = kSimSource;
  config.scene = "walk.yaml";
  config.camera = "cam0";
  config.rate_hz = 10.0;
  config.loop = false;
  config.frames = 3;
  config.truth = true;
  config.truth_replay.latency_ms = 40.0;
  auto truth = TruthCamera::create(scene, config, "cam-sim");
  ASSERT_TRUE(truth.ok()) << truth.error().message;

  ManualClock clock;
  clock.set(kStartNs + 30'000'000);  // between frames: the first is the next one
  Delivered out;
  DetectionRunner runner(*truth, ReplayConfig{10.0, false, 3}, hooksFor(clock, out));
  runner.run();

  const std::uint64_t first = static_cast<std::uint64_t>(kStartNs / 100'000'000) + 1;
  ASSERT_EQ(out.frames.size(), 3u);
  const sim::CameraConfig& cam = scene.cameras[0];
  const camera::PinholeCamera pinhole = sim::pinholeOf(cam);
  for (std::size_t i = 0; i < out.frames.size(); ++i) {
    const std::uint64_t n = first + i;
    const std::int64_t capture = static_cast<std::int64_t>(n) * 100'000'000;
    const tracking::DetectionFrame& frame = out.frames[i];
    EXPECT_EQ(frame.camera, "cam-sim");
    EXPECT_EQ(frame.capture_time_ns, capture);
    EXPECT_EQ(out.clock_at_delivery[i], capture + 40'000'000) << "frame " << i << " not delivered after the latency";
    ASSERT_EQ(frame.detections.size(), 1u) << "frame " << i;
    const camera::Detection& d = frame.detections[0];
    EXPECT_EQ(d.label, "person");
    EXPECT_EQ(d.camera, "cam-sim");
    EXPECT_EQ(d.capture_time_ns, capture);

    // The scene instant of the simulated LiDARs' scan n: the same truth, box for box.
    const double time_s = sim::sceneTime(scene, n, 10.0);
    auto raycaster = sim::SceneRaycaster::build(scene, time_s);
    ASSERT_TRUE(raycaster.ok());
    auto expected = sim::truthDetections(scene, *raycaster, cam, sim::cycleFrame(scene, n, 10.0),
                                         sim::TruthReplayConfig{0.0, 0.0, 40.0, scene.seed});
    ASSERT_TRUE(expected.ok());
    ASSERT_EQ(expected->detections.size(), 1u);
    EXPECT_EQ(d.box.left, expected->detections[0].box.left);
    EXPECT_EQ(d.box.right, expected->detections[0].box.right);

    // The box holds the projection of the person's true centre at that instant.
    const sim::ObjectPose pose = sim::poseAt(scene.objects[0], time_s);
    const auto pixel = pinhole.project(Eigen::Vector3d(pose.xy.x(), pose.xy.y(), 0.9));
    ASSERT_TRUE(pixel.has_value());
    EXPECT_GE(pixel->x(), d.box.left);
    EXPECT_LE(pixel->x(), d.box.right);
    EXPECT_GE(pixel->y(), d.box.top);
    EXPECT_LE(pixel->y(), d.box.bottom);
  }
  // The person moves: the frames are of different instants.
  EXPECT_NE(out.frames[0].detections[0].box.left, out.frames[2].detections[0].box.left);
  EXPECT_EQ(runner.stats().frames_detected, 3u);
}

TEST(TruthCamera, NamesTheSceneCamerasWhenTheCameraIsMissing) {
  CameraNodeConfig config;
  config.source = kSimSource;
  config.scene = "walk.yaml";
  config.camera = "cam9";
  config.truth = true;
  auto truth = TruthCamera::create(walkingPersonScene(), config, "cam-sim");
  ASSERT_FALSE(truth.ok());
  EXPECT_NE(truth.error().message.find("'cam0'"), std::string::npos) << truth.error().message;
}

}  // namespace
}  // namespace fogmap
