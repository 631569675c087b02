#include "services/common/periodic.hpp"

#include <utility>

namespace fogmap {

bool SteadyPacer::waitFor(std::chrono::nanoseconds period) {
  std::unique_lock lock(mutex_);
  const bool interrupted = interrupted_cv_.wait_for(lock, period, [this] { return interrupted_; });
  interrupted_ = false;
  return interrupted;
}

void SteadyPacer::interrupt() {
  {
    std::lock_guard lock(mutex_);
    interrupted_ = true;
  }
  interrupted_cv_.notify_all();
}

Periodic::Periodic(std::function<void()> work, std::chrono::nanoseconds period, std::shared_ptr<Pacer> pacer)
    : work_(std::move(work)), period_(period), pacer_(pacer ? std::move(pacer) : std::make_shared<SteadyPacer>()) {}

Periodic::~Periodic() { stop(); }

void Periodic::start() {
  std::lock_guard lock(mutex_);
  if (thread_.joinable()) return;
  stopping_ = false;
  thread_ = std::thread([this] { run(); });
}

void Periodic::stop() {
  std::lock_guard lock(mutex_);
  stopping_ = true;
  if (!thread_.joinable()) return;
  pacer_->interrupt();
  thread_.join();
}

void Periodic::wake() { pacer_->interrupt(); }

void Periodic::run() {
  while (!stopping_) {
    work_();
    if (stopping_) break;
    pacer_->waitFor(period_);
  }
}

}  // namespace fogmap
