#pragma once
// What every service process does the same way before it knows its topology: read its command
// line (--topology FILE --node NAME, and the few flags a service adds), and stop on SIGINT or
// SIGTERM through one StopRequest that its loops wait on.
//
// The one stop mechanism: both signals are blocked before any thread starts (every thread inherits
// the mask), and one waiter thread takes them with sigwait and requests the stop. No signal handler
// runs, so a stop is an ordinary mutex and condition variable: a wait on it ends at once.
#include <pthread.h>
#include <signal.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>

namespace fogmap {

struct ServiceArgs {
  std::string topology;
  std::string node;
  std::map<std::string, std::string> extra;  // the service's own flags, without "--"
};

// "--flag value" pairs: --topology and --node are required, `extra_flags` (names without "--")
// allowed; nothing when anything else is given or a value is missing.
std::optional<ServiceArgs> parseServiceArgs(int argc, char** argv, const std::set<std::string>& extra_flags = {});
// True when the only argument is --help or -h.
bool wantsHelp(int argc, char** argv);

// A process's request to stop: made once (by StopSignals, or by a test), seen by every loop.
class StopRequest {
 public:
  // Requests the stop (from any thread; again is harmless) and wakes every wait.
  void request();
  bool requested() const;
  // Blocks until the stop is requested.
  void wait() const;
  // When the stop was first requested, on the steady clock; nullopt before.
  std::optional<std::chrono::steady_clock::time_point> requestedAt() const;
  // Waits until the system clock reaches `until_ns`, reading it again at least every `poll` (so a
  // stepped clock is followed); false as soon as the stop is requested.
  bool sleepUntil(std::int64_t until_ns, std::chrono::nanoseconds poll = std::chrono::milliseconds(50)) const;

 private:
  mutable std::mutex mutex_;
  mutable std::condition_variable requested_cv_;
  std::optional<std::chrono::steady_clock::time_point> requested_at_;
};

// SIGINT and SIGTERM request `stop`. Construct it first in main, before any thread starts: it
// blocks both signals in the calling thread, so every thread started afterwards inherits the mask
// and its own waiter thread (sigwait) is the only one that sees them. The destructor ends the
// waiter and leaves the signals blocked: one that comes while the process ends changes nothing.
class StopSignals {
 public:
  explicit StopSignals(StopRequest& stop);
  ~StopSignals();
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

 private:
  StopRequest& stop_;
  sigset_t signals_{};
  std::atomic<bool> closing_{false};
  std::thread waiter_;
};

}  // namespace fogmap
