#include "services/common/service_process.hpp"

#include <algorithm>
#include <string_view>

#include "common/base/clock.hpp"

namespace fogmap {

std::optional<ServiceArgs> parseServiceArgs(int argc, char** argv, const std::set<std::string>& extra_flags) {
  ServiceArgs args;
  for (int i = 1; i < argc; ++i) {
    const std::string_view flag = argv[i];
    if (i + 1 >= argc || flag.substr(0, 2) != "--") return std::nullopt;
    const std::string name(flag.substr(2));
    const std::string value = argv[++i];
    if (name == "topology") {
      args.topology = value;
    } else if (name == "node") {
      args.node = value;
    } else if (extra_flags.count(name) > 0) {
      args.extra[name] = value;
    } else {
      return std::nullopt;
    }
  }
  if (args.topology.empty() || args.node.empty()) return std::nullopt;
  return args;
}

bool wantsHelp(int argc, char** argv) {
  return argc == 2 && (std::string_view(argv[1]) == "--help" || std::string_view(argv[1]) == "-h");
}

void StopRequest::request() {
  {
    std::lock_guard lock(mutex_);
    if (!requested_at_) requested_at_ = std::chrono::steady_clock::now();
  }
  requested_cv_.notify_all();
}

bool StopRequest::requested() const {
  std::lock_guard lock(mutex_);
  return requested_at_.has_value();
}

void StopRequest::wait() const {
  std::unique_lock lock(mutex_);
  requested_cv_.wait(lock, [this] { return requested_at_.has_value(); });
}

std::optional<std::chrono::steady_clock::time_point> StopRequest::requestedAt() const {
  std::lock_guard lock(mutex_);
  return requested_at_;
}

bool StopRequest::sleepUntil(std::int64_t until_ns, std::chrono::nanoseconds poll) const {
  std::unique_lock lock(mutex_);
  while (!requested_at_) {
    const std::int64_t now_ns = systemNowNs();
    if (now_ns >= until_ns) return true;
    requested_cv_.wait_for(lock, std::min(std::chrono::nanoseconds(until_ns - now_ns), poll));
  }
  return false;
}

StopSignals::StopSignals(StopRequest& stop) : stop_(stop) {
  sigemptyset(&signals_);
  sigaddset(&signals_, SIGINT);
  sigaddset(&signals_, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals_, nullptr);
  waiter_ = std::thread([this] {
    for (;;) {
      int signal = 0;
      if (sigwait(&signals_, &signal) != 0) continue;
      if (closing_.load()) return;
      stop_.request();
    }
  });
}

StopSignals::~StopSignals() {
  closing_.store(true);
  // Directed at the waiter alone (blocked there, so it is taken by its sigwait, never delivered).
  pthread_kill(waiter_.native_handle(), SIGTERM);
  waiter_.join();
}

}  // namespace fogmap
