#pragma once
// The child's side of the upload stream: one long-lived MapIngest.Push stream to the parent,
// with acknowledgements, keepalive, reconnect with capped backoff, and re-send of everything not
// yet acknowledged (MERGE is idempotent, so a duplicate is harmless).
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "fogmap/v1/fogmap.grpc.pb.h"

namespace fogmap {

struct ParentLinkConfig {
  std::string target;                      // host:port of the parent
  std::size_t max_message_bytes = 64U << 20;
  std::size_t max_unacked = 256;           // oldest unacknowledged uploads are dropped beyond this
  std::chrono::milliseconds backoff_initial{50};
  std::chrono::milliseconds backoff_max{2000};
  std::chrono::milliseconds keepalive{10000};
};

// Observers for metrics (may be empty). `kind` is "map" or "points".
struct ParentLinkHooks {
  std::function<void(const std::string& kind, std::size_t bytes)> on_sent;
  std::function<void()> on_reconnect;
  std::function<void()> on_dropped;  // an unacknowledged upload was dropped (queue full)
};

class ParentLink {
 public:
  ParentLink(ParentLinkConfig config, ParentLinkHooks hooks);
  ~ParentLink();  // stops the stream thread; unacknowledged uploads are abandoned
  ParentLink(const ParentLink&) = delete;
  ParentLink& operator=(const ParentLink&) = delete;

  // Queues an upload (the sequence number is assigned here) and returns at once.
  void send(fogmap::v1::Upload upload);
  // Blocks until every queued upload is acknowledged or the timeout passes; true when all are.
  bool flush(std::chrono::milliseconds timeout);
  std::size_t unacknowledged() const;
  bool connected() const;

 private:
  void run();
  struct State;
  std::unique_ptr<State> state_;
  std::thread thread_;
};

}  // namespace fogmap
