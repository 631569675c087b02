#pragma once
// Time a test moves by hand: a clock (NowNs) and a Pacer whose waits end only when the test moves
// the clock past them (or the waiting thread is interrupted). The test synchronises with the
// waiting thread explicitly: awaitWaits(n) returns once the thread has begun its n-th wait, i.e.
// has finished whatever it did before.
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <vector>

#include "common/base/clock.hpp"
#include "services/common/periodic.hpp"

namespace fogmap::test_support {

class ManualTime final : public Pacer {
 public:
  explicit ManualTime(std::int64_t start_ns = 0) : now_ns_(start_ns) {}

  std::int64_t now() const {
    std::lock_guard lock(mutex_);
    return now_ns_;
  }
  NowNs clock() {
    return [this] { return now(); };
  }
  // Moves the clock on; a wait whose end it reaches ends.
  void advance(std::chrono::nanoseconds d) {
    {
      std::lock_guard lock(mutex_);
      now_ns_ += d.count();
    }
    changed_.notify_all();
  }
  // True once a thread has begun its n-th wait (counting from 1); false if that takes longer than
  // `limit` (a safety net for a broken unit, never reached by a working one).
  bool awaitWaits(std::size_t n, std::chrono::seconds limit = std::chrono::seconds(30)) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, limit, [&] { return waits_.size() >= n; });
  }
  // The period of every wait begun so far.
  std::vector<std::chrono::nanoseconds> waits() const {
    std::lock_guard lock(mutex_);
    return waits_;
  }

  bool waitFor(std::chrono::nanoseconds period) override {
    std::unique_lock lock(mutex_);
    const std::int64_t until_ns = now_ns_ + period.count();
    waits_.push_back(period);
    changed_.notify_all();
    changed_.wait(lock, [&] { return interrupted_ || now_ns_ >= until_ns; });
    const bool interrupted = interrupted_;
    interrupted_ = false;
    return interrupted;
  }
  void interrupt() override {
    {
      std::lock_guard lock(mutex_);
      interrupted_ = true;
    }
    changed_.notify_all();
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable changed_;  // the clock moved, a wait began, or an interrupt came
  std::int64_t now_ns_;
  std::vector<std::chrono::nanoseconds> waits_;
  bool interrupted_ = false;
};

}  // namespace fogmap::test_support
