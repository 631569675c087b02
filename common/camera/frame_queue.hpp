#pragma once
// The hand-off between a camera reader and a slower detector: a bounded queue that keeps the newest
// frames. A detector that falls behind should work on what the camera sees now, so a full queue
// drops its oldest frame (and counts it) instead of blocking the reader or growing without bound.
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <string>

#include <opencv2/core/mat.hpp>

#include "common/base/status.hpp"

namespace fogmap::camera {

struct CameraFrame {
  // Shared, not copied (cv::Mat counts references): a reader that reuses its buffer must clone.
  cv::Mat image_bgr;
  std::string camera;
  std::int64_t capture_time_ns = 0;
};

struct FrameQueueConfig {
  std::size_t capacity = 2;  // frames waiting for the detector; beyond it the oldest is dropped
};

// capacity must be at least 1; the error names the field.
Status validate(const FrameQueueConfig& config);

// Thread-safe; any number of pushers and poppers.
class FrameQueue {
 public:
  // A capacity below 1 is taken as 1 (validate() refuses it in a config).
  explicit FrameQueue(const FrameQueueConfig& config);

  // Queues a frame; when full, first drops the oldest queued frame and counts it. Returns false,
  // queueing nothing, once closed.
  bool push(CameraFrame frame);
  // The oldest queued frame, waiting up to `timeout` for one. Nothing when the time runs out, or
  // when the queue is closed and empty.
  std::optional<CameraFrame> pop(std::chrono::milliseconds timeout);
  // Refuses further pushes and wakes every waiting pop; frames already queued can still be popped.
  void close();

  bool closed() const;
  std::size_t size() const;
  std::size_t capacity() const { return capacity_; }
  std::uint64_t dropped() const;  // frames dropped to make room, since construction

 private:
  const std::size_t capacity_;
  mutable std::mutex mutex_;
  std::condition_variable ready_;  // a frame was queued, or the queue closed
  std::deque<CameraFrame> frames_;
  std::uint64_t dropped_ = 0;
  bool closed_ = false;
};

}  // namespace fogmap::camera
