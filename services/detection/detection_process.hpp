#pragma once
// One detection process as its topology node says: its camera (the scene's truth, or a source of
// images and a detector), the link to its tracker, the metrics, and the loops (DetectionRunner)
// that read, detect and deliver.
//
// How it ends (within 2 s of the stop request): the loops see the request between frames (at once
// while waiting for one), a read or detection in progress gets kStopGraceNs to end and is
// otherwise left behind (unfinished(): the process exits without joining it), the detections
// already made get kStopFlush to be written. At the end of a replay the last frames get kDoneFlush;
// exit kExitRuntimeError when not one frame was readable.
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>

#include "common/base/status.hpp"
#include "common/camera/detector.hpp"
#include "services/common/service_main.hpp"
#include "services/common/tracker_link.hpp"
#include "services/detection/detection_metrics.hpp"
#include "services/detection/detection_runner.hpp"
#include "services/detection/frame_source.hpp"
#include "services/detection/truth_camera.hpp"

namespace fogmap {

class DetectionProcess {
 public:
  static constexpr std::chrono::nanoseconds kStopPoll = std::chrono::milliseconds(50);  // clock steps
  static constexpr std::int64_t kStopGraceNs = 500'000'000;
  static constexpr std::chrono::milliseconds kStopFlush{1000};
  static constexpr std::chrono::milliseconds kDoneFlush{5000};

  // Checks the node (a camera under a tracker; its queue, detector and source) and opens its camera;
  // an error says what is wrong (a configuration error). `context` must outlive the process.
  static Expected<std::unique_ptr<DetectionProcess>> create(const ServiceContext& context);
  DetectionProcess(const DetectionProcess&) = delete;
  DetectionProcess& operator=(const DetectionProcess&) = delete;

  // Runs until the replay ends or the stop request, then ends as above; the exit code.
  int run();
  // After run(): a read or detection was still at work when the loops stopped. Destroying the
  // process would wait for it, for as long as it takes; nothing it could produce would be sent.
  bool unfinished() const { return unfinished_; }

 private:
  DetectionProcess(const ServiceContext& context, const NodeConfig& parent, std::optional<TruthCamera> truth,
                   std::unique_ptr<FrameSource> source, std::unique_ptr<camera::Detector> detector);
  DetectionRunnerHooks runnerHooks();
  TrackerLinkHooks linkHooks();
  std::string describe() const { return truth_ ? truth_->describe() : source_->describe(); }

  const ServiceContext& context_;
  const NodeConfig& parent_;
  std::optional<TruthCamera> truth_;  // exactly one of: the scene's truth,
  std::unique_ptr<FrameSource> source_;          // or a source of images
  std::unique_ptr<camera::Detector> detector_;   // and a detector
  DetectionMetrics detection_metrics_;
  DetectionLink link_;  // after the metrics its hooks count with
  std::optional<DetectionRunner> runner_;
  bool unfinished_ = false;
};

}  // namespace fogmap
