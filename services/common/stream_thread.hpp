#pragma once
// What the client-stream links (ParentLink, TrackerStreamLink) share: the channel to their peer,
// the lock and condition their stream thread waits on, the stop flag, and the waits that end as
// soon as a stop is requested.
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>

#include <grpcpp/grpcpp.h>

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

  explicit StreamThreadState(std::shared_ptr<grpc::Channel> c) : channel(std::move(c)) {}

  std::shared_ptr<grpc::Channel> channel;
  mutable std::mutex mu;
  std::condition_variable cv;  // any change of the link's state under mu, a stop included
  bool stopping = false;       // under mu

  bool stopRequested() const {
    std::lock_guard lock(mu);
    return stopping;
  }

  // Waits until `d` has passed or a stop is requested; true when stopping.
  bool sleepFor(std::chrono::milliseconds d) {
    std::unique_lock lock(mu);
    return cv.wait_for(lock, d, [&] { return stopping; });
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
