#pragma once
// A detection node's loops (docs/design.md "Cameras"). With images: a reader puts the source's
// frames into a bounded FrameQueue when they are due (the oldest dropped when the detector falls
// behind: detections of stale images are worth less than fresh ones), and a detector pops, detects
// and hands every frame's detections to a sink (the tracker link), empty frames included, so the
// tracker knows the camera looked. With truth (source sim): frame n is due at n / rate_hz of unix
// time, shows the scene at sim::sceneTime(scene, n, rate_hz) like the simulated LiDARs' scan n, and
// its detections reach the sink latency_ms after. Time comes in through a clock and a wait
// function, so tests drive it by hand. Every frame the source could not give and every frame the
// detector refused is counted by reason and logged through a BurstLog (one line per reason per
// burst, never one per frame). A stop is seen between frames; a read or a detection still running
// after the stop's grace is left behind, so a stop never waits for one. No gRPC, no printing.
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "common/base/burst_log.hpp"
#include "common/camera/detector.hpp"
#include "common/camera/frame_queue.hpp"
#include "common/base/clock.hpp"
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
  // A frame the source could not give, and why.
  virtual void frameUnreadable(FrameFailure /*failure*/) {}
  // A frame the detector refused (a camera::detectFailureName, or "truth_replay_failed").
  virtual void detectFailed(const std::string& /*reason*/) {}
  // True while the detector works on a frame, false when it is done with it.
  virtual void detecting(bool /*busy*/) {}
  // Frames the queue dropped to make room for newer ones.
  virtual void framesDropped(std::uint64_t /*frames*/) {}
  // One frame detected (truth frames included), with how long the detector took.
  virtual void frameDetected(std::size_t /*detections*/, double /*seconds*/) {}
  // A frame had more detections than the tracker takes; the `left_out` least confident were not sent.
  virtual void detectionsCapped(std::size_t /*left_out*/) {}
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
  // After a stop, how long (by `now`) run() waits for a read or detection in progress to end.
  std::int64_t stop_grace_ns = 500'000'000;
  // The most detections a frame carries (the tracker refuses more: kMaxDetectionsPerFrame); beyond,
  // the most confident are kept and the rest counted (observer->detectionsCapped). 0: no bound.
  std::size_t max_detections = 0;
};

struct DetectionRunnerStats {
  std::uint64_t frames_read = 0;        // images the reader queued
  std::uint64_t frames_dropped = 0;     // queued images dropped for newer ones
  std::uint64_t frames_unreadable = 0;  // images skipped because they could not be read (or were too large)
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
  // Stops, and waits for the loops' threads (those run() left behind included).
  ~DetectionRunner();
  DetectionRunner(const DetectionRunner&) = delete;
  DetectionRunner& operator=(const DetectionRunner&) = delete;

  // Runs until the source is done or a stop: with images the reader and the detector on threads
  // of their own, with truth the replay on this one. True when every loop ended; false when, a
  // stop's grace after it was seen, a read or detection was still running: its thread is left to
  // the destructor (a process that is stopping may exit without waiting for it).
  bool run();

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
  void deliver(tracking::DetectionFrame frame, double seconds);
  void frameUnreadable(const SourceFrame& frame);
  void detectFailed(const std::string& reason, const std::string& message);
  void loopEnded();

  std::string camera_;
  FrameSource* source_ = nullptr;
  camera::Detector* detector_ = nullptr;
  TruthCamera* truth_ = nullptr;
  ReplayConfig replay_;
  DetectionRunnerHooks hooks_;
  camera::FrameQueue queue_;
  std::atomic<bool> stop_{false};
  BurstLog burst_log_;

  std::mutex loops_mutex_;
  std::condition_variable loops_cv_;
  int loops_running_ = 0;  // guarded by loops_mutex_
  std::thread reader_;
  std::thread detector_thread_;

  std::atomic<std::uint64_t> frames_read_{0};
  std::atomic<std::uint64_t> frames_dropped_{0};
  std::atomic<std::uint64_t> frames_unreadable_{0};
  std::atomic<std::uint64_t> frames_detected_{0};
  std::atomic<std::uint64_t> detections_{0};
  std::atomic<std::uint64_t> detect_failures_{0};
  std::atomic<std::int64_t> detect_ns_{0};
};

}  // namespace fogmap
