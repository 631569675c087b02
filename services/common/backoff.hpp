#pragma once
// The one reconnect backoff of the services' client streams (parent link, tracker link, global-map
// feed): after a failed stream wait `initial`, doubled after each further failure up to `max`;
// a stream that worked starts the waits again from `initial`.
#include <algorithm>
#include <chrono>

namespace fogmap {

class Backoff {
 public:
  Backoff(std::chrono::milliseconds initial, std::chrono::milliseconds max) : initial_(initial), max_(max), next_(initial) {}

  // The wait before the next attempt; the one after it is twice as long (at most `max`).
  std::chrono::milliseconds next() {
    const auto wait = next_;
    next_ = std::min(next_ * 2, max_);
    return wait;
  }
  // The stream worked: the next failure waits `initial` again.
  void reset() { next_ = initial_; }

 private:
  std::chrono::milliseconds initial_;
  std::chrono::milliseconds max_;
  std::chrono::milliseconds next_;
};

}  // namespace fogmap
