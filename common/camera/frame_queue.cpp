#include "common/camera/frame_queue.hpp"

#include <algorithm>
#include <utility>

namespace fogmap::camera {

Status validate(const FrameQueueConfig& config) {
  if (config.capacity < 1) return invalidArgument("frame_queue.capacity: must be at least 1");
  return {};
}

FrameQueue::FrameQueue(const FrameQueueConfig& config) : capacity_(std::max<std::size_t>(config.capacity, 1)) {}

bool FrameQueue::push(CameraFrame frame) {
  {
    std::lock_guard lock(mutex_);
    if (closed_) return false;
    if (frames_.size() >= capacity_) {
      frames_.pop_front();
      ++dropped_;
    }
    frames_.push_back(std::move(frame));
  }
  ready_.notify_one();
  return true;
}

std::optional<CameraFrame> FrameQueue::pop(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  ready_.wait_for(lock, timeout, [this] { return !frames_.empty() || closed_; });
  if (frames_.empty()) return std::nullopt;
  CameraFrame frame = std::move(frames_.front());
  frames_.pop_front();
  return frame;
}

void FrameQueue::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  ready_.notify_all();
}

bool FrameQueue::closed() const {
  std::lock_guard lock(mutex_);
  return closed_;
}

std::size_t FrameQueue::size() const {
  std::lock_guard lock(mutex_);
  return frames_.size();
}

std::uint64_t FrameQueue::dropped() const {
  std::lock_guard lock(mutex_);
  return dropped_;
}

}  // namespace fogmap::camera
