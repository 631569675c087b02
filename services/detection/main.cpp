// detection: one camera's 2D detector. Reads the camera's frames, detects objects in them and
// streams every frame's detections to the node's tracker (TrackerService.PushDetections).
// Composition root only: the loops and their policy are DetectionRunner's, the stream DetectionLink's.
//
// A detection node in a topology file (its parent is a tracker):
//
//   - name: cam-front
//     id: 20
//     role: detection
//     parent: tracker
//     host: 127.0.0.1
//     metrics_port: 9120
//     camera:
//       source: data/kitti_raw_seq_a/image_02   # images, a video file, /dev/video0, or sim
//       rate_hz: 10
//       loop: true
//       queue_frames: 2
//       max_image_pixels: 16777216                # default 4096 x 4096; larger frames are refused undecoded
//       detector: {kind: hog, hog: {upscale: 1.5}}
//       calibration: {fx: 721.5, fy: 721.5, cx: 609.6, cy: 172.9, width: 1242, height: 375,
//                     pose: {translation_m: [0, 0, 1.65], rpy_deg: [-90, 0, -90]}}
//
// A simulated camera replays the scene's truth instead of running a detector:
//       source: sim
//       scene: data/scenes/example.yaml
//       camera: camera-1
//       detector: {kind: truth, truth: {miss_rate: 0.1, box_jitter_px: 2, latency_ms: 40}}
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <utility>

#include "common/camera/detector.hpp"
#include "common/camera/frame_queue.hpp"
#include "common/certs.hpp"
#include "common/clock.hpp"
#include "common/topology.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/metrics.hpp"
#include "services/common/proto_convert.hpp"
#include "services/common/service_process.hpp"
#include "services/common/tracker_link.hpp"
#include "services/detection/detection_metrics.hpp"
#include "services/detection/detection_runner.hpp"
#include "services/detection/frame_source.hpp"
#include "services/detection/truth_camera.hpp"

namespace {

using namespace std::chrono_literals;

constexpr int kExitRuntimeError = 1;
constexpr int kExitBadConfig = 2;
// Shutdown on SIGTERM or SIGINT, within 2 s: the loops see the request between frames (within
// kStopPollNs while waiting for one), a read or detection in progress gets kStopGraceNs to end and
// is otherwise left behind (the process exits without it), the detections already made get
// kStopFlush to be written, and the stream is half-closed (unless a detection was left behind).
// At the end of a replay the last frames get kDoneFlush.
constexpr std::int64_t kStopPollNs = 50'000'000;
constexpr std::int64_t kStopGraceNs = 500'000'000;
constexpr auto kStopFlush = 1s;
constexpr auto kDoneFlush = 5s;

using fogmap::stopRequested;

bool waitUntil(std::int64_t until_ns) { return fogmap::sleepUntilUnlessStopped(until_ns, kStopPollNs); }

void usage() { std::cerr << "usage: detection --topology FILE --node NAME\n"; }

struct Flags {
  std::filesystem::path topology;
  std::string node;
};

int badConfig(const std::string& message) {
  std::cerr << "detection: " << message << "\n";
  return kExitBadConfig;
}

int run(const Flags& flags) {
  fogmap::Expected<fogmap::TopologyConfig> topology = fogmap::loadTopology(flags.topology);
  if (!topology) return badConfig(topology.error().message);
  const fogmap::NodeConfig* node = topology->find(flags.node);
  if (node == nullptr) return badConfig("no node '" + flags.node + "' in " + flags.topology.string());
  if (node->role != fogmap::Role::kDetection || !node->camera) {
    return badConfig("node '" + flags.node + "' is not a detection node with a camera in " + flags.topology.string());
  }
  const fogmap::NodeConfig* parent = node->parent.empty() ? nullptr : topology->find(node->parent);
  if (parent == nullptr || parent->role != fogmap::Role::kTracker) {
    return badConfig("detection node '" + flags.node + "' has no parent tracker to send to");
  }
  const fogmap::CameraNodeConfig& camera = *node->camera;
  const std::string where = "node '" + node->name + "': camera.";
  if (const fogmap::Status s = fogmap::camera::validate(fogmap::camera::FrameQueueConfig{camera.queue_frames}); !s) {
    return badConfig(where + "queue_frames: must be at least 1");
  }

  // Exactly one of: the scene's truth, or a source of images and a detector.
  std::optional<fogmap::TruthCamera> truth;
  std::unique_ptr<fogmap::FrameSource> source;
  std::unique_ptr<fogmap::camera::Detector> detector;
  if (camera.truth) {
    fogmap::Expected<fogmap::TruthCamera> opened = fogmap::TruthCamera::open(camera, node->name);
    if (!opened) return badConfig(where + "detector." + opened.error().message);
    truth.emplace(std::move(*opened));
  } else {
    if (const fogmap::Status s = fogmap::camera::validate(camera.detector); !s) {
      return badConfig(where + "detector." + s.error().message);
    }
    fogmap::Expected<std::unique_ptr<fogmap::camera::Detector>> made = fogmap::camera::makeDetector(camera.detector);
    if (!made) return badConfig(where + "detector." + made.error().message);
    detector = std::move(*made);
    fogmap::Expected<std::unique_ptr<fogmap::FrameSource>> opened =
        fogmap::openFrameSource(camera, fogmap::systemNowNs);
    if (!opened) return badConfig(where + "source: " + opened.error().message);
    source = std::move(*opened);
  }

  // Read and checked before anything starts: a missing or wrong file is a configuration error.
  const auto tls = fogmap::loadTls(*topology, node->name, std::chrono::system_clock::now());
  if (!tls) return badConfig("tls: " + tls.error().message);

  const std::string host = node->host.empty() ? "127.0.0.1" : node->host;
  fogmap::Metrics metrics(host + ":" + std::to_string(node->metrics_port),
                          fogmap::serviceName(fogmap::Role::kDetection), node->name);
  fogmap::DetectionMetrics detection_metrics(metrics, node->name);
  const std::string prefix = "detection " + node->name + ": ";

  fogmap::TrackerLinkConfig link_config;
  link_config.target = parent->host + ":" + std::to_string(parent->port);
  link_config.credentials = fogmap::channelCredentials(*tls);
  link_config.max_message_bytes = topology->max_message_bytes;
  fogmap::TrackerLinkHooks link_hooks;
  const std::string peer = parent->name;
  link_hooks.on_sent = [&detection_metrics, peer](std::size_t bytes) { detection_metrics.frameSent(peer, bytes); };
  link_hooks.on_reconnect = [&detection_metrics] { detection_metrics.reconnected(); };
  link_hooks.on_dropped = [&detection_metrics, prefix](std::uint64_t total, bool first_of_burst) {
    detection_metrics.linkDropped();
    if (first_of_burst) {
      std::cerr << prefix << "the tracker is not taking detections; dropping the oldest frames (" << total
                << " dropped so far)\n";
    }
  };
  link_hooks.on_stream_ended = [prefix](const std::string& why) { std::cerr << prefix << why << "\n"; };
  // Declared after the metrics, so destroyed (and its thread stopped) before the hooks' targets go.
  fogmap::DetectionLink link(link_config, std::move(link_hooks));

  fogmap::DetectionRunnerHooks hooks;
  hooks.now = fogmap::systemNowNs;
  hooks.wait_until = waitUntil;
  hooks.stop_requested = stopRequested;
  hooks.deliver = [&link](fogmap::tracking::DetectionFrame frame) { link.send(frame); };
  hooks.log = [&prefix](const std::string& line) { std::cerr << prefix << line << "\n"; };
  hooks.observer = &detection_metrics;
  hooks.stop_grace_ns = kStopGraceNs;
  hooks.max_detections = fogmap::kMaxDetectionsPerFrame;  // what the tracker takes in one frame
  std::optional<fogmap::DetectionRunner> runner;
  if (truth) {
    runner.emplace(*truth, fogmap::ReplayConfig{camera.rate_hz, camera.loop, camera.frames}, std::move(hooks));
  } else {
    runner.emplace(node->name, *source, *detector, camera.queue_frames, std::move(hooks));
  }

  std::cerr << prefix << (truth ? truth->describe() : source->describe())
            << (truth ? "" : ", frames above " + std::to_string(camera.max_image_pixels) + " pixels refused")
            << ", sending to " << parent->name << " (" << link_config.target << (*tls ? ", mutual TLS" : "") << ")\n";

  const bool ended = runner->run();
  const fogmap::DetectionRunnerStats stats = runner->stats();
  const std::string frames = std::to_string(stats.frames_detected) + " frame(s) detected of " +
                             std::to_string(stats.frames_read) + " read (" + std::to_string(stats.frames_dropped) +
                             " dropped, " + std::to_string(stats.frames_unreadable) + " unreadable), " +
                             std::to_string(stats.detections) + " detection(s)";
  if (stopRequested()) {
    const bool flushed = link.flush(kStopFlush);
    std::cerr << prefix << "stopping after " << frames
              << (flushed ? "" : "; " + std::to_string(link.queued()) + " frame(s) not sent")
              << (ended ? "" : "; a read or detection still running was left unfinished") << "\n";
    // The loops' threads would be joined by the runner's destructor: a detection at work would hold
    // the exit for as long as it takes. Nothing it could still produce would be sent.
    if (!ended) std::_Exit(0);
    return 0;
  }
  if (stats.frames_read == 0) {
    std::cerr << prefix << "no readable frame (" << (truth ? truth->describe() : source->describe()) << ")\n";
    return kExitRuntimeError;
  }
  const bool flushed = link.flush(kDoneFlush);
  std::cerr << prefix << "done after " << frames
            << (flushed ? ", all sent" : "; " + std::to_string(link.queued()) + " frame(s) not sent") << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (fogmap::wantsHelp(argc, argv)) {
    usage();
    return 0;
  }
  const auto args = fogmap::parseServiceArgs(argc, argv);
  if (!args) {
    usage();
    return kExitBadConfig;
  }
  Flags flags;
  flags.topology = args->topology;
  flags.node = args->node;
  fogmap::installStopFlag();
  try {
    return run(flags);
  } catch (const std::exception& e) {
    // Only the outside world throws here (e.g. the metrics port is taken).
    std::cerr << "detection: " << e.what() << "\n";
    return kExitRuntimeError;
  }
}
