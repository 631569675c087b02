// The detection service as a real process running a user's network through OpenCV's dnn module:
// `detection` is started from a topology (as fogctl up starts it) on the bundled KITTI camera
// frames, with a tiny ONNX network whose answer the test knows (tests/data/make_tiny_detector.py).
// Its parent tracker is a stand-in on 127.0.0.1 that records every detection frame it receives.
#include <poll.h>
#include <signal.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <iostream>
#include <iterator>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "common/config/camera_node.hpp"
#include "common/config/topology.hpp"
#include "common/config/topology_yaml.hpp"
#include "common/config/tracker_node.hpp"
#include "tests/support/eventually.hpp"
#include "tests/support/free_ports.hpp"
#include "tests/support/process_cluster.hpp"
#include "tests/support/recording_tracker.hpp"
#include "tests/support/scratch_dir.hpp"
#include "tests/support/tiny_detector.hpp"
#include "tests/support/topology_builders.hpp"
#include "harness/launcher.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using test_support::makeTinyDetector;
using test_support::node;
using test_support::pythonWithOnnx;
using test_support::RecordingTracker;
using test_support::TestTracker;

const fs::path kImages = fs::path(FOGMAP_SOURCE_DIR) / "data" / "kitti_raw_seq_a" / "image_02";

// A topology of a root, a tracker and the camera node `camera_name` (id 20) with `camera`, on free
// ports, the tracker where the stand-in listens (`tracker_port`); written to `file` and read back.
Expected<TopologyConfig> cameraTopology(const std::string& name, const std::string& camera_name,
                                        const CameraNodeConfig& camera, int tracker_port, const fs::path& file) {
  TopologyConfig topology;
  topology.name = name;
  NodeConfig tracker_node = node(50, "tracker", Role::kTracker, "");
  tracker_node.tracker = TrackerNodeConfig{};
  NodeConfig cam = node(20, camera_name, Role::kDetection, "tracker");
  cam.camera = camera;
  topology.nodes = {node(100, "root", Role::kAggregator, ""), tracker_node, cam};
  test_support::useFreePorts(topology);
  for (NodeConfig& n : topology.nodes) {
    if (n.role == Role::kTracker) n.port = static_cast<std::uint16_t>(tracker_port);
  }
  return test_support::writeTopology(file, topology);
}

TEST(DetectionProcess, RunsTheUsersOnnxNetworkOnCameraFramesAndStreamsItsDetectionsToTheTracker) {
  SKIP_WITHOUT_ONNX(python);
  test_support::ScratchDir dir("detection-dnn");
  // SSD rows: image, class, score, x1, y1, x2, y2 (normalised). Classes index the names file.
  const fs::path model = makeTinyDetector(*python, dir.path(), "ssd", 32, 32,
                                          {"0,0,0.9,0.10,0.20,0.40,0.60", "0,2,0.8,0.50,0.30,0.90,0.80", "0,1,0.2,0,0,1,1"});
  ASSERT_FALSE(model.empty());
  {
    std::ofstream names(dir.path() / "names.txt");
    names << "person\nbicycle\ncar\n";
  }
  const cv::Mat first = cv::imread((kImages / "0000000000.png").string());
  ASSERT_FALSE(first.empty());

  RecordingTracker recorder;
  TestTracker tracker(recorder);
  ASSERT_TRUE(tracker.started());

  const fs::path topology_file = dir.path() / "topology.yaml";
  CameraNodeConfig camera;
  camera.source = kImages;
  camera.rate_hz = 20.0;
  camera.loop = true;
  camera.detector.kind = camera::DetectorKind::kDnn;
  camera.detector.dnn.model_path = model.string();
  camera.detector.dnn.names_path = (dir.path() / "names.txt").string();
  camera.detector.dnn.output = camera::DnnOutput::kSsd;
  camera.detector.dnn.input_width = 32;
  camera.detector.dnn.input_height = 32;
  camera.detector.dnn.confidence_threshold = 0.5;
  camera.calibration.fx = camera.calibration.fy = 721.5;
  camera.calibration.cx = 609.6;
  camera.calibration.cy = 172.9;
  camera.calibration.width = first.cols;
  camera.calibration.height = first.rows;
  const auto reloaded = cameraTopology("dnn", "cam-front", camera, tracker.port(), topology_file);
  ASSERT_TRUE(reloaded.ok()) << reloaded.error().message;

  harness::StartOptions options;
  options.only = {"cam-front"};
  auto cluster = harness::startCluster(topology_file, *reloaded, dir.path() / "state", 30s, options);
  ASSERT_TRUE(cluster.ok()) << cluster.error().message;
  const test_support::StopOnExit stop(*cluster);
  ASSERT_EQ(cluster->nodes.size(), 1U);

  // Every bundled frame once, and the loop's first again.
  constexpr std::size_t kFrames = 4;
  ASSERT_TRUE(recorder.waitFrames(kFrames, 30s)) << "only " << recorder.frames().size() << " frames arrived; see "
                                                   << cluster->nodes.front().log;
  EXPECT_TRUE(recorder.errors().empty());
  const std::vector<tracking::DetectionFrame> frames = recorder.frames();
  const double w = first.cols;
  const double h = first.rows;
  std::int64_t previous_capture = 0;
  for (const tracking::DetectionFrame& frame : frames) {
    EXPECT_EQ(frame.camera, "cam-front");
    EXPECT_GT(frame.capture_time_ns, previous_capture) << "capture times must increase";
    previous_capture = frame.capture_time_ns;
    // The network's rows at or above the threshold, scaled to the image, the 0.2 row left out.
    ASSERT_EQ(frame.detections.size(), 2U);
    std::vector<camera::Detection> detections = frame.detections;
    std::sort(detections.begin(), detections.end(), [](const auto& a, const auto& b) { return a.score > b.score; });
    EXPECT_EQ(detections[0].label, "person");
    EXPECT_NEAR(detections[0].score, 0.9, 1e-6);
    EXPECT_NEAR(detections[0].box.left, 0.10 * w, 0.01);
    EXPECT_NEAR(detections[0].box.top, 0.20 * h, 0.01);
    EXPECT_NEAR(detections[0].box.right, 0.40 * w, 0.01);
    EXPECT_NEAR(detections[0].box.bottom, 0.60 * h, 0.01);
    EXPECT_EQ(detections[1].label, "car");
    EXPECT_NEAR(detections[1].score, 0.8, 1e-6);
    EXPECT_NEAR(detections[1].box.left, 0.50 * w, 0.01);
    EXPECT_NEAR(detections[1].box.bottom, 0.80 * h, 0.01);
  }

  // The service counts what it did in its own metrics.
  const NodeConfig* cam_node = reloaded->find("cam-front");
  const auto metrics = harness::httpGet(cam_node->host, cam_node->metrics_port, "/metrics", 2s);
  ASSERT_TRUE(metrics.ok()) << metrics.error().message;
  EXPECT_NE(metrics->find("fogmap_detection_frames_sent_total"), std::string::npos);
}

TEST(DetectionProcess, RefusesANetworkFileThatIsNotAModelAndNamesIt) {
  test_support::ScratchDir dir("detection-bad-model");
  {
    std::ofstream(dir.path() / "model.onnx") << "this is not a protobuf";
    std::ofstream(dir.path() / "names.txt") << "person\n";
  }
  TopologyConfig topology;
  topology.name = "bad-model";
  NodeConfig tracker_node = node(50, "tracker", Role::kTracker, "");
  tracker_node.tracker = TrackerNodeConfig{};
  NodeConfig cam = node(20, "cam", Role::kDetection, "tracker");
  CameraNodeConfig camera;
  camera.source = kImages;
  camera.detector.kind = camera::DetectorKind::kDnn;
  camera.detector.dnn.model_path = (dir.path() / "model.onnx").string();
  camera.detector.dnn.names_path = (dir.path() / "names.txt").string();
  cam.camera = camera;
  topology.nodes = {node(100, "root", Role::kAggregator, ""), tracker_node, cam};
  test_support::useFreePorts(topology);
  const fs::path topology_file = dir.path() / "topology.yaml";
  {
    std::ofstream out(topology_file);
    out << toYaml(topology);
  }
  harness::StartOptions options;
  options.only = {"cam"};
  auto cluster = harness::startCluster(topology_file, topology, dir.path() / "state", 10s, options);
  ASSERT_FALSE(cluster.ok()) << "a detection service with a broken model must not start";
  std::ifstream log(dir.path() / "state" / "logs" / "cam.log");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("model.onnx"), std::string::npos) << text;
}

// The value of the unlabelled-by-test gauge `name` in a /metrics text; nullopt when absent.
std::optional<double> gaugeValue(const std::string& metrics, const std::string& name) {
  std::istringstream lines(metrics);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind(name + "{", 0) != 0 && line.rfind(name + " ", 0) != 0) continue;
    return std::stod(line.substr(line.rfind(' ') + 1));
  }
  return std::nullopt;
}

std::string readAll(const fs::path& file) {
  std::ifstream in(file);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(DetectionProcess, SigtermEndsItWhileADetectionIsRunningWithoutWaitingForTheDetection) {
  test_support::ScratchDir dir("detection-sigterm");
  RecordingTracker recorder;
  TestTracker tracker(recorder);
  ASSERT_TRUE(tracker.started());

  const fs::path topology_file = dir.path() / "topology.yaml";
  CameraNodeConfig camera;
  camera.source = kImages;
  camera.rate_hz = 20.0;
  camera.loop = true;
  // A detection that takes many seconds on a KITTI frame: HOG on the frame upscaled 4 times (7.5 MP)
  // over 64 nearly full-size pyramid levels.
  camera.detector.kind = camera::DetectorKind::kHog;
  camera.detector.hog.upscale = 4.0;
  camera.detector.hog.scale = 1.001;
  camera.calibration.fx = camera.calibration.fy = 721.5;
  camera.calibration.cx = 609.6;
  camera.calibration.cy = 172.9;
  camera.calibration.width = 1242;
  camera.calibration.height = 375;
  const auto reloaded = cameraTopology("sigterm", "cam", camera, tracker.port(), topology_file);
  ASSERT_TRUE(reloaded.ok()) << reloaded.error().message;

  harness::StartOptions options;
  options.only = {"cam"};
  auto cluster = harness::startCluster(topology_file, *reloaded, dir.path() / "state", 30s, options);
  ASSERT_TRUE(cluster.ok()) << cluster.error().message;
  const test_support::StopOnExit stop(*cluster);
  ASSERT_EQ(cluster->nodes.size(), 1U);
  const harness::RunningNode& process = cluster->nodes.front();

  // Busy: the service says a detection is running (the gauge is set just before the detector is
  // called, and the detection takes far longer than the polls).
  const NodeConfig* cam_node = reloaded->find("cam");
  ASSERT_TRUE(test_support::eventually(
      [&] {
        const auto metrics = harness::httpGet(cam_node->host, cam_node->metrics_port, "/metrics", 2s);
        return metrics.ok() && gaugeValue(*metrics, "fogmap_detection_in_progress") == 1.0;
      },
      30s))
      << "no detection started; see " << process.log;

  const int pidfd = static_cast<int>(::syscall(SYS_pidfd_open, process.pid, 0));
  ASSERT_GE(pidfd, 0);
  const auto signalled = std::chrono::steady_clock::now();
  ASSERT_EQ(::kill(process.pid, SIGTERM), 0);
  // Bounded so that a service that waits for its detection fails here instead of hanging; the
  // service's own deadline (2 s) is what the log line below shows it kept.
  pollfd p{pidfd, POLLIN, 0};
  const int ready = ::poll(&p, 1, 120'000);
  const auto exited_after = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - signalled);
  ::close(pidfd);
  ASSERT_EQ(ready, 1) << "still running 120 s after SIGTERM; see " << process.log;
  int status = 0;
  ASSERT_EQ(::waitpid(process.pid, &status, 0), process.pid);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "wait status " << status;
  RecordProperty("sigterm_to_exit_ms", static_cast<int>(exited_after.count()));
  std::cout << "SIGTERM to exit while detecting: " << exited_after.count() << " ms\n";

  // It stopped without the detection: the frame was never delivered, and the service says so.
  const std::string log = readAll(process.log);
  EXPECT_NE(log.find("stopping after 0 frame(s) detected"), std::string::npos) << log;
  EXPECT_NE(log.find("left unfinished"), std::string::npos) << log;
  EXPECT_TRUE(recorder.frames().empty());
}

TEST(DetectionProcess, StartingANodeTheTopologyDoesNotHaveIsAnError) {
  test_support::ScratchDir dir("detection-only");
  TopologyConfig topology;
  topology.name = "only";
  NodeConfig tracker_node = node(50, "tracker", Role::kTracker, "");
  tracker_node.tracker = TrackerNodeConfig{};
  topology.nodes = {node(100, "root", Role::kAggregator, ""), tracker_node};
  test_support::useFreePorts(topology);
  harness::StartOptions options;
  options.only = {"camera-that-is-not-there"};
  auto cluster = harness::startCluster(dir.path() / "topology.yaml", topology, dir.path() / "state", 5s, options);
  ASSERT_FALSE(cluster.ok());
  EXPECT_NE(cluster.error().message.find("camera-that-is-not-there"), std::string::npos) << cluster.error().message;
}

}  // namespace
}  // namespace fogmap
