#pragma once
// A detection node's loops (docs/design.md "Cameras"). With images: a reader puts the source's
// frames into a bounded FrameQueue when they are due (the oldest dropped when the detector falls
// behind: detections of stale images are worth less than fresh ones), and a detector pops, detects
// and hands every frame's detections to a sink (the tracker link), empty frames included, so the
// tracker knows the camera looked. With truth (source sim): frame n is due at n / rate_hz of unix
// time, shows the scene at sim::sceneTime(scene, n, rate_hz) like the simulated LiDARs' scan n, and
// its detections reach the sink latency_ms after. Time comes in through a clock and a wait
// function, so tests drive it by hand. No gRPC, no printing.
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "common/camera/detector.hpp"
#include "common/camera/frame_queue.hpp"
#include "common/clock.hpp"
#include "common/tracking/track.hpp"
#include "services/detection/frame_source.hpp"
#include "services/detection/truth_camera.hpp"

namespace fogmap {

// What the runner reports for metrics; every method does nothing unless overridden. Called from
// the reader and the detector threads.
class DetectionObserver {
 public:
  virtual ~DetectionObserver() = default;
  virtual void frameRead() {}
  virtual void frameUnreadable() {}
  // Frames the queue dropped to make room for newer ones.
  virtual void framesDropped(std::uint64_t /*frames*/) {}
  // One frame detected (truth frames included), with how long the detector took.
  virtual void frameDetected(std::size_t /*detections*/, double /*seconds*/) {}
};

// Blocks until the clock reaches `until_ns` (at once when it has); false when a stop was requested.
using WaitUntilNs = std::function<bool(std::int64_t until_ns)>;

struct DetectionRunnerHooks {
  NowNs now;                 // unix ns (systemNowNs in the service)
  WaitUntilNs wait_until;
  // Polled between frames and while waiting for one (a signal flag in the service); may be empty.
  std::function<bool()> stop_requested;
  std::function<void(tracking::DetectionFrame)> deliver;  // every frame's detections, in capture order
  std::function<void(const std::string&)> log;           // one line, no prefix; empty: silent
  DetectionObserver* observer = nullptr;                  // may be null
};

struct DetectionRunnerStats {
  std::uint64_t frames_read = 0;        // images the reader queued
  std::uint64_t frames_dropped = 0;     // queued images dropped for newer ones
  std::uint64_t frames_unreadable = 0;  // images skipped because they could not be read
  std::uint64_t frames_detected = 0;    // frames whose detections went to the sink
  std::uint64_t detections = 0;         // detections in them
  std::uint64_t detect_failures = 0;    // frames the detector refused (nothing delivered)
  double detect_seconds = 0.0;          // time spent detecting, by the injected clock
};

class DetectionRunner {
 public:
  // Images from `source` through `detector` (both must outlive the runner), queued up to
  // `queue_frames`; detections stamped with `camera` (the node's name).
  DetectionRunner(std::string camera, FrameSource& source, camera::Detector& detector, std::size_t queue_frames,
                  DetectionRunnerHooks hooks);
  // Truth replay of `truth` (must outlive the runner): `replay.frames` frames, or one pass of the
  // scene without `replay.loop`, endless otherwise.
  DetectionRunner(TruthCamera& truth, const ReplayConfig& replay, DetectionRunnerHooks hooks);

  // Runs until the source is done or stop(): with images the reader on its own thread and the
  // detector on this one, with truth the replay on this one.
  void run();

  // The reader loop alone: queues every frame when due, until the source is done or a stop; then
  // closes the queue.
  void readFrames();
  // The detector loop alone: pops and detects until the queue is closed and empty, or a stop.
  void detectFrames();
  // The truth loop alone.
  void replayTruth();

  // Ends the loops soon: no frame is queued or delivered after the current one. Thread-safe.
  void stop();
  bool stopped() const { return stopping(); }

  // Frames waiting for the detector.
  std::size_t queued() const { return queue_.size(); }
  // A snapshot; thread-safe.
  DetectionRunnerStats stats() const;

 private:
  bool stopping() const;
  void log(const std::string& line) const;
  void deliver(tracking::DetectionFrame frame, double seconds);

  std::string camera_;
  FrameSource* source_ = nullptr;
  camera::Detector* detector_ = nullptr;
  TruthCamera* truth_ = nullptr;
  ReplayConfig replay_;
  DetectionRunnerHooks hooks_;
  camera::FrameQueue queue_;
  std::atomic<bool> stop_{false};

  std::atomic<std::uint64_t> frames_read_{0};
  std::atomic<std::uint64_t> frames_dropped_{0};
  std::atomic<std::uint64_t> frames_unreadable_{0};
  std::atomic<std::uint64_t> frames_detected_{0};
  std::atomic<std::uint64_t> detections_{0};
  std::atomic<std::uint64_t> detect_failures_{0};
  std::atomic<std::int64_t> detect_ns_{0};
};

}  // namespace fogmap
