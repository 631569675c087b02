#pragma once
// Work done on its own thread every period, and at once when woken (the aggregator's emitter, the
// tracker's tick). The waiting goes through a Pacer, so a test lets each period pass by hand.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>

namespace fogmap {

// How a periodic thread waits between two runs of its work.
class Pacer {
 public:
  virtual ~Pacer() = default;
  // Blocks until `period` has passed or interrupt() is called; an interrupt() that came while
  // nobody waited ends the next wait at once. True when interrupted.
  virtual bool waitFor(std::chrono::nanoseconds period) = 0;
  // Ends the current wait (or the next one); callable from any thread.
  virtual void interrupt() = 0;
};

// The real one: the steady clock.
class SteadyPacer final : public Pacer {
 public:
  bool waitFor(std::chrono::nanoseconds period) override;
  void interrupt() override;

 private:
  std::mutex mutex_;
  std::condition_variable interrupted_cv_;
  bool interrupted_ = false;
};

class Periodic {
 public:
  // `work` runs on the thread once at start(), then again `period` after each run ends, and at once
  // after wake(). `pacer` empty: a SteadyPacer.
  Periodic(std::function<void()> work, std::chrono::nanoseconds period, std::shared_ptr<Pacer> pacer = nullptr);
  ~Periodic();  // stop()
  Periodic(const Periodic&) = delete;
  Periodic& operator=(const Periodic&) = delete;

  // Starts the thread (again after stop()); nothing when it runs.
  void start();
  // Ends the thread after the run in progress, if any; returns once it has ended.
  void stop();
  // Runs the work again as soon as the run in progress (if any) ends.
  void wake();

 private:
  void run();

  std::function<void()> work_;
  std::chrono::nanoseconds period_;
  std::shared_ptr<Pacer> pacer_;
  std::mutex mutex_;  // start and stop
  std::atomic<bool> stopping_{false};
  std::thread thread_;
};

}  // namespace fogmap
