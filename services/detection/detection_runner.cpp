#include "services/detection/detection_runner.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <thread>
#include <utility>

namespace fogmap {
namespace {

// Upper bound of one wait for a queued frame, so a stop is seen this soon even without a frame.
constexpr std::chrono::milliseconds kPopSlice{100};

// The unix time frame `n` of a camera at `rate_hz` is due: n / rate_hz, in long double so that
// frame numbers since the epoch (about 1.7e10 at 10 Hz) keep their nanoseconds.
std::int64_t frameTimeNs(std::uint64_t n, double rate_hz) {
  return static_cast<std::int64_t>(std::llround(static_cast<long double>(n) * 1e9L / rate_hz));
}

// The frame current at `now_ns`: the last one due at or before it.
std::uint64_t frameAt(std::int64_t now_ns, double rate_hz) {
  if (now_ns <= 0) return 0;
  const auto n = static_cast<std::uint64_t>(std::floor(static_cast<long double>(now_ns) * rate_hz / 1e9L));
  // Rounding of the product can put n one past the frame whose time is <= now.
  return frameTimeNs(n, rate_hz) > now_ns && n > 0 ? n - 1 : n;
}

}  // namespace

DetectionRunner::DetectionRunner(std::string camera, FrameSource& source, camera::Detector& detector,
                                 std::size_t queue_frames, DetectionRunnerHooks hooks)
    : camera_(std::move(camera)),
      source_(&source),
      detector_(&detector),
      hooks_(std::move(hooks)),
      queue_(camera::FrameQueueConfig{queue_frames}),
      burst_log_("", hooks_.log, hooks_.now) {}

DetectionRunner::DetectionRunner(TruthCamera& truth, const ReplayConfig& replay, DetectionRunnerHooks hooks)
    : truth_(&truth),
      replay_(replay),
      hooks_(std::move(hooks)),
      queue_(camera::FrameQueueConfig{1}),
      burst_log_("", hooks_.log, hooks_.now) {}

DetectionRunner::~DetectionRunner() {
  stop();
  if (reader_.joinable()) reader_.join();
  if (detector_thread_.joinable()) detector_thread_.join();
}

bool DetectionRunner::stopping() const {
  return stop_.load() || (hooks_.stop_requested && hooks_.stop_requested());
}

void DetectionRunner::stop() {
  stop_.store(true);
  queue_.close();
}

void DetectionRunner::loopEnded() {
  {
    std::lock_guard lock(loops_mutex_);
    --loops_running_;
  }
  loops_cv_.notify_all();
}

bool DetectionRunner::run() {
  if (truth_ != nullptr) {
    replayTruth();
    burst_log_.flush(true);
    return true;
  }
  {
    std::lock_guard lock(loops_mutex_);
    loops_running_ = 2;
  }
  reader_ = std::thread([this] {
    readFrames();
    loopEnded();
  });
  detector_thread_ = std::thread([this] {
    detectFrames();
    loopEnded();
  });
  // The detector ends when the reader closed the queue, or on a stop the reader sees too. A stop
  // waits for neither beyond its grace: a decode or a detection can take long (HOG at a large
  // upscale takes seconds), and a process asked to stop must stop.
  std::optional<std::int64_t> stop_seen_ns;
  std::unique_lock lock(loops_mutex_);
  while (loops_running_ > 0) {
    if (stopping()) {
      const std::int64_t now = hooks_.now();
      if (!stop_seen_ns) stop_seen_ns = now;
      if (now - *stop_seen_ns >= hooks_.stop_grace_ns) {
        lock.unlock();
        burst_log_.flush(true);
        return false;
      }
    }
    loops_cv_.wait_for(lock, kPopSlice);
  }
  lock.unlock();
  reader_.join();
  detector_thread_.join();
  burst_log_.flush(true);
  return true;
}

void DetectionRunner::frameUnreadable(const SourceFrame& frame) {
  frames_unreadable_.fetch_add(1);
  if (hooks_.observer != nullptr) hooks_.observer->frameUnreadable(frame.failure);
  burst_log_.note(std::string("skipping frames: ") + frameFailureName(frame.failure), frame.problem);
}

void DetectionRunner::detectFailed(const std::string& reason, const std::string& message) {
  detect_failures_.fetch_add(1);
  if (hooks_.observer != nullptr) hooks_.observer->detectFailed(reason);
  burst_log_.note("the detector refused frames: " + reason, message);
}

void DetectionRunner::readFrames() {
  const std::int64_t start_ns = hooks_.now();
  while (!stopping()) {
    SourceFrame frame = source_->next();
    if (frame.outcome == FrameOutcome::kDone) break;
    if (frame.outcome == FrameOutcome::kUnreadable) {
      frameUnreadable(frame);
      continue;
    }
    std::int64_t capture_ns = 0;
    if (frame.due_ns) {
      capture_ns = start_ns + *frame.due_ns;
      if (!hooks_.wait_until(capture_ns)) break;
    } else {
      capture_ns = frame.capture_time_ns ? *frame.capture_time_ns : hooks_.now();
    }
    if (stopping()) break;
    // The reader is the only pusher, so the change of the total is this push's drop.
    const std::uint64_t dropped_before = queue_.dropped();
    if (!queue_.push({std::move(frame.image_bgr), camera_, capture_ns})) break;
    const std::uint64_t dropped = queue_.dropped() - dropped_before;
    frames_read_.fetch_add(1);
    if (hooks_.observer != nullptr) hooks_.observer->frameRead();
    if (dropped > 0) {
      frames_dropped_.fetch_add(dropped);
      if (hooks_.observer != nullptr) hooks_.observer->framesDropped(dropped);
    }
  }
  queue_.close();
}

void DetectionRunner::detectFrames() {
  while (!stopping()) {
    std::optional<camera::CameraFrame> frame = queue_.pop(kPopSlice);
    // Summaries of failure bursts that went quiet get written even when no frame comes.
    burst_log_.flush();
    if (!frame) {
      if (queue_.closed() && queue_.size() == 0) break;
      continue;
    }
    if (hooks_.observer != nullptr) hooks_.observer->detecting(true);
    const std::int64_t started = hooks_.now();
    camera::DetectResult result = detector_->detectFrame(frame->image_bgr, camera_, frame->capture_time_ns);
    const std::int64_t took_ns = hooks_.now() - started;
    if (hooks_.observer != nullptr) hooks_.observer->detecting(false);
    const double seconds = static_cast<double>(took_ns) * 1e-9;
    detect_ns_.fetch_add(took_ns);
    if (result.refusal) {
      detectFailed(camera::detectFailureName(result.refusal->reason), result.refusal->error.message);
      continue;
    }
    if (stopping()) break;
    deliver({camera_, frame->capture_time_ns, std::move(result.detections)}, seconds);
  }
}

void DetectionRunner::deliver(tracking::DetectionFrame frame, double seconds) {
  auto& detections = frame.detections;
  if (hooks_.max_detections > 0 && detections.size() > hooks_.max_detections) {
    const std::size_t left_out = detections.size() - hooks_.max_detections;
    std::stable_sort(detections.begin(), detections.end(),
                     [](const camera::Detection& a, const camera::Detection& b) { return a.score > b.score; });
    detections.resize(hooks_.max_detections);
    if (hooks_.observer != nullptr) hooks_.observer->detectionsCapped(left_out);
    burst_log_.note("frames with more detections than the tracker takes",
                    std::to_string(left_out + hooks_.max_detections) + " detections; the " + std::to_string(left_out) +
                        " least confident were left out");
  }
  frames_detected_.fetch_add(1);
  detections_.fetch_add(frame.detections.size());
  if (hooks_.observer != nullptr) hooks_.observer->frameDetected(frame.detections.size(), seconds);
  if (hooks_.deliver) hooks_.deliver(std::move(frame));
}

void DetectionRunner::replayTruth() {
  struct Pending {
    std::int64_t arrival_ns = 0;
    tracking::DetectionFrame frame;
    double seconds = 0.0;
  };
  const double rate_hz = truth_->rateHz();
  const std::int64_t latency_ns = truth_->latencyNs();
  std::optional<std::uint64_t> limit = replay_.frames;
  if (!limit && !replay_.loop) limit = truth_->framesPerPass();

  std::deque<Pending> pending;  // in arrival order: the latency is the same for every frame
  std::uint64_t n = frameAt(hooks_.now(), rate_hz) + 1;
  std::uint64_t produced = 0;
  for (;;) {
    const bool more = !stopping() && (!limit || produced < *limit);
    if (!more && pending.empty()) break;
    const std::int64_t capture_ns = frameTimeNs(n, rate_hz);
    if (!pending.empty() && (!more || pending.front().arrival_ns <= capture_ns)) {
      if (!hooks_.wait_until(pending.front().arrival_ns) || stopping()) break;
      deliver(std::move(pending.front().frame), pending.front().seconds);
      pending.pop_front();
      continue;
    }
    if (!hooks_.wait_until(capture_ns) || stopping()) break;
    const std::int64_t started = hooks_.now();
    Expected<tracking::DetectionFrame> frame = truth_->frame(n, capture_ns);
    const std::int64_t finished = hooks_.now();
    detect_ns_.fetch_add(finished - started);
    ++produced;
    // After a stall, go on with the frame current now instead of a burst of stale ones.
    const std::uint64_t current = frameAt(finished, rate_hz);
    const std::uint64_t next = std::max(n + 1, current);
    if (next > n + 1) {
      frames_dropped_.fetch_add(next - n - 1);
      if (hooks_.observer != nullptr) hooks_.observer->framesDropped(next - n - 1);
    }
    n = next;
    if (!frame) {
      detectFailed("truth_replay_failed", frame.error().message);
      continue;
    }
    frames_read_.fetch_add(1);
    if (hooks_.observer != nullptr) hooks_.observer->frameRead();
    pending.push_back({capture_ns + latency_ns, std::move(*frame), static_cast<double>(finished - started) * 1e-9});
  }
}

DetectionRunnerStats DetectionRunner::stats() const {
  DetectionRunnerStats s;
  s.frames_read = frames_read_.load();
  s.frames_dropped = frames_dropped_.load();
  s.frames_unreadable = frames_unreadable_.load();
  s.frames_detected = frames_detected_.load();
  s.detections = detections_.load();
  s.detect_failures = detect_failures_.load();
  s.detect_seconds = static_cast<double>(detect_ns_.load()) * 1e-9;
  return s;
}

}  // namespace fogmap
