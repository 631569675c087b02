#include "services/common/stream_follow.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <thread>

namespace fogmap {

namespace {

using Clock = std::chrono::steady_clock;

Clock::duration seconds(double s) { return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s)); }

bool stopped(const std::function<bool()>& stop) { return stop && stop(); }

}  // namespace

std::string waitForChannel(grpc::Channel& channel, double window_s, const std::function<bool()>& stop) {
  const auto deadline = Clock::now() + seconds(window_s);
  std::string last_problem = "no connection";
  auto state = channel.GetState(true);
  while (state != GRPC_CHANNEL_READY) {
    if (state == GRPC_CHANNEL_SHUTDOWN) return "the channel was shut down";
    if (state == GRPC_CHANNEL_TRANSIENT_FAILURE) last_problem = "the connection failed";
    if (stopped(stop)) return "interrupted";
    const auto now = Clock::now();
    if (now >= deadline) {
      char within[48];
      std::snprintf(within, sizeof within, " within %g s", window_s);
      return last_problem + within;
    }
    // In slices, so that a stop is seen.
    const auto slice = std::min<Clock::duration>(deadline - now, std::chrono::milliseconds(100));
    channel.WaitForStateChange(state, std::chrono::system_clock::now() + slice);
    state = channel.GetState(true);
  }
  return {};
}

FollowResult followStream(grpc::ClientContext& context, const std::function<bool()>& read_next,
                          const std::function<grpc::Status()>& finish, const FollowOptions& options) {
  std::atomic<long> received{0};
  std::atomic<bool> gave_up{false};
  std::atomic<bool> stop_seen{false};
  std::mutex mutex;
  std::condition_variable finished_cv;
  bool finished = false;
  std::thread watchdog([&] {
    long seen = 0;
    long idle_periods = 0;
    auto quiet_since = Clock::now();
    std::unique_lock<std::mutex> lock(mutex);
    while (!finished_cv.wait_for(lock, std::chrono::milliseconds(50), [&] { return finished; })) {
      if (stopped(options.stop)) {
        stop_seen = true;
        context.TryCancel();
        return;
      }
      const auto now = Clock::now();
      if (received.load() != seen) {
        seen = received.load();
        idle_periods = 0;
        quiet_since = now;
        continue;
      }
      if (options.timeout_s > 0.0 && now - quiet_since >= seconds(options.timeout_s)) {
        gave_up = true;
        context.TryCancel();
        return;
      }
      if (now - quiet_since >= seconds(options.idle_s * static_cast<double>(idle_periods + 1))) {
        ++idle_periods;
        if (options.on_idle) options.on_idle(options.idle_s * static_cast<double>(idle_periods));
      }
    }
  });

  bool counted_out = false;
  while (read_next()) {
    ++received;
    if (options.count > 0 && received.load() >= options.count) {
      counted_out = true;
      break;
    }
  }
  {
    std::lock_guard<std::mutex> lock(mutex);
    finished = true;
  }
  finished_cv.notify_all();
  watchdog.join();
  // Reading stopped early: the stream is cancelled so that its status comes at once. A stream the
  // server ended keeps the status it ended with.
  if (counted_out) context.TryCancel();
  const grpc::Status status = finish();
  FollowResult result;
  result.messages = received.load();
  if (counted_out) {
    result.end = FollowEnd::kCounted;
  } else if (stop_seen || stopped(options.stop)) {
    result.end = FollowEnd::kStopped;
  } else if (gave_up) {
    result.end = FollowEnd::kGaveUp;
  } else {
    result.end = FollowEnd::kLost;
    result.why = status.ok() ? "it ended the stream" : status.error_message();
    if (result.why.empty()) result.why = "the stream failed";
  }
  return result;
}

}  // namespace fogmap
