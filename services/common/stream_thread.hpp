#pragma once
// What the client-stream links (ParentLink, TrackerStreamLink) share: the channel to their peer,
// the lock and condition their stream thread waits on, the stop flag, the link's clock, and the
// waits that end as soon as a stop is requested.
#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>

#include <grpcpp/grpcpp.h>

#include "common/base/clock.hpp"
#include "services/common/grpc_options.hpp"

namespace fogmap {

// A link configuration's channel: its target, message limit and keepalive, with its credentials
// (TLS) or plaintext when it has none.
template <class Config>
std::shared_ptr<grpc::Channel> channelFor(const Config& config) {
  return config.credentials ? makeChannel(config.target, config.credentials, config.max_message_bytes, config.keepalive)
                            : makeChannel(config.target, config.max_message_bytes, config.keepalive);
}

struct StreamThreadState {
  // Upper bound of every blocking wait, so that a stop request is seen within this long even when
  // a notification is missed.
  static constexpr std::chrono::milliseconds kPollSlice{100};

  // `steady_now`: the link's clock for its timed decisions, a steady clock in ns (empty:
  // std::chrono::steady_clock). Tests inject one to drive the link's time by hand.
  explicit StreamThreadState(std::shared_ptr<grpc::Channel> c, NowNs steady_now = {})
      : channel(std::move(c)), now(steady_now ? std::move(steady_now) : NowNs(steadyNowNs)) {}

  std::shared_ptr<grpc::Channel> channel;
  NowNs now;  // the link's clock (see the constructor); read under mu, so it must not call into the link
  mutable std::mutex mu;
  std::condition_variable cv;  // any change of the link's state under mu, a stop included
  bool stopping = false;       // under mu

  bool stopRequested() const {
    std::lock_guard lock(mu);
    return stopping;
  }

  // Waits until `d` has passed on the link's clock or a stop is requested; true when stopping.
  // The clock decides: it is read again at least every kPollSlice, so an injected clock that a
  // test moves on ends the wait within a slice, and one it holds still never does.
  bool sleepFor(std::chrono::milliseconds d) {
    const std::int64_t until = now() + std::chrono::nanoseconds(d).count();
    std::unique_lock lock(mu);
    while (!stopping) {
      const std::chrono::nanoseconds left{until - now()};
      if (left.count() <= 0) return false;
      // At least a millisecond: a clock held still just short of `until` must not make this spin.
      cv.wait_for(lock, std::clamp<std::chrono::nanoseconds>(left, std::chrono::milliseconds(1), kPollSlice));
    }
    return true;
  }

  // Waits in short slices so that a destructor never waits on a peer that is down (gRPC converts
  // only system_clock deadlines; a clock step merely lengthens or shortens one slice). True once
  // connected, false when a stop was requested first.
  bool waitConnected() {
    while (!stopRequested()) {
      if (channel->WaitForConnected(std::chrono::system_clock::now() + kPollSlice)) return true;
    }
    return false;
  }
};

}  // namespace fogmap
