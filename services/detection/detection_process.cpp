#include "services/detection/detection_process.hpp"

#include <utility>

#include "common/base/clock.hpp"
#include "common/camera/frame_queue.hpp"
#include "common/config/camera_node.hpp"
#include "services/common/proto_convert.hpp"

namespace fogmap {

Expected<std::unique_ptr<DetectionProcess>> DetectionProcess::create(const ServiceContext& context) {
  const NodeConfig& node = context.node;
  if (!node.camera) {
    return invalidArgument("node '" + node.name + "' is not a detection node with a camera in " +
                           context.topology_file.string());
  }
  const NodeConfig* parent = node.parent.empty() ? nullptr : context.topology.find(node.parent);
  if (parent == nullptr || parent->role != Role::kTracker) {
    return invalidArgument("detection node '" + node.name + "' has no parent tracker to send to");
  }
  const CameraNodeConfig& settings = *node.camera;
  const std::string where = "node '" + node.name + "': camera.";
  if (const Status s = camera::validate(camera::FrameQueueConfig{settings.queue_frames}); !s) {
    return invalidArgument(where + "queue_frames: must be at least 1");
  }
  // Exactly one of: the scene's truth, or a source of images and a detector.
  std::optional<TruthCamera> truth;
  std::unique_ptr<FrameSource> source;
  std::unique_ptr<camera::Detector> detector;
  if (settings.truth) {
    Expected<TruthCamera> opened = TruthCamera::open(settings, node.name);
    if (!opened) return invalidArgument(where + "detector." + opened.error().message);
    truth.emplace(std::move(*opened));
  } else {
    if (const Status s = camera::validate(settings.detector); !s) {
      return invalidArgument(where + "detector." + s.error().message);
    }
    Expected<std::unique_ptr<camera::Detector>> made = camera::makeDetector(settings.detector);
    if (!made) return invalidArgument(where + "detector." + made.error().message);
    detector = std::move(*made);
    Expected<std::unique_ptr<FrameSource>> opened = openFrameSource(settings, systemNowNs);
    if (!opened) return invalidArgument(where + "source: " + opened.error().message);
    source = std::move(*opened);
  }
  return std::unique_ptr<DetectionProcess>(
      new DetectionProcess(context, *parent, std::move(truth), std::move(source), std::move(detector)));
}

DetectionProcess::DetectionProcess(const ServiceContext& context, const NodeConfig& parent,
                                   std::optional<TruthCamera> truth, std::unique_ptr<FrameSource> source,
                                   std::unique_ptr<camera::Detector> detector)
    : context_(context),
      parent_(parent),
      truth_(std::move(truth)),
      source_(std::move(source)),
      detector_(std::move(detector)),
      detection_metrics_(context.metrics, context.node.name),
      link_(context.linkTo<TrackerLinkConfig>(parent), linkHooks()) {
  const CameraNodeConfig& camera = *context.node.camera;
  if (truth_) {
    runner_.emplace(*truth_, ReplayConfig{camera.rate_hz, camera.loop, camera.frames}, runnerHooks());
  } else {
    runner_.emplace(context.node.name, *source_, *detector_, camera.queue_frames, runnerHooks());
  }
}

TrackerLinkHooks DetectionProcess::linkHooks() {
  TrackerLinkHooks hooks;
  hooks.on_sent = [this, peer = parent_.name](std::size_t bytes) { detection_metrics_.frameSent(peer, bytes); };
  hooks.on_reconnect = [this] { detection_metrics_.reconnected(); };
  hooks.on_dropped = [this](std::uint64_t total, bool first_of_burst) {
    detection_metrics_.linkDropped();
    if (first_of_burst) {
      context_.log("the tracker is not taking detections; dropping the oldest frames (" + std::to_string(total) +
                   " dropped so far)");
    }
  };
  hooks.on_stream_ended = [this](const std::string& why) { context_.log(why); };
  return hooks;
}

DetectionRunnerHooks DetectionProcess::runnerHooks() {
  DetectionRunnerHooks hooks;
  hooks.now = systemNowNs;
  hooks.wait_until = [this](std::int64_t until_ns) { return context_.stop.sleepUntil(until_ns, kStopPoll); };
  hooks.stop_requested = [this] { return context_.stop.requested(); };
  hooks.deliver = [this](tracking::DetectionFrame frame) { link_.send(frame); };
  hooks.log = [this](const std::string& line) { context_.log(line); };
  hooks.observer = &detection_metrics_;
  hooks.stop_grace_ns = kStopGraceNs;
  hooks.max_detections = kMaxDetectionsPerFrame;  // what the tracker takes in one frame
  return hooks;
}

int DetectionProcess::run() {
  const CameraNodeConfig& camera = *context_.node.camera;
  context_.log(describe() +
               (truth_ ? "" : ", frames above " + std::to_string(camera.max_image_pixels) + " pixels refused") +
               ", sending to " + parent_.name + " (" + endpoint(parent_.host, parent_.port) +
               (context_.tls ? ", mutual TLS" : "") + ")");
  const bool ended = runner_->run();
  const DetectionRunnerStats stats = runner_->stats();
  const std::string frames = std::to_string(stats.frames_detected) + " frame(s) detected of " +
                             std::to_string(stats.frames_read) + " read (" + std::to_string(stats.frames_dropped) +
                             " dropped, " + std::to_string(stats.frames_unreadable) + " unreadable), " +
                             std::to_string(stats.detections) + " detection(s)";
  if (context_.stop.requested()) {
    const bool flushed = link_.flush(kStopFlush);
    context_.log("stopping after " + frames +
                 (flushed ? "" : "; " + std::to_string(link_.queued()) + " frame(s) not sent") +
                 (ended ? "" : "; a read or detection still running was left unfinished"));
    unfinished_ = !ended;
    return 0;
  }
  if (stats.frames_read == 0) {
    context_.log("no readable frame (" + describe() + ")");
    return kExitRuntimeError;
  }
  const bool flushed = link_.flush(kDoneFlush);
  context_.log("done after " + frames +
               (flushed ? ", all sent" : "; " + std::to_string(link_.queued()) + " frame(s) not sent"));
  return 0;
}

}  // namespace fogmap
