#pragma once
// The child's side of the upload stream: one long-lived MapIngest.Push stream to the parent,
// with acknowledgements, keepalive, reconnect with capped backoff, and re-send of everything not
// yet acknowledged (MERGE is idempotent, so a duplicate is harmless).
#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include "fogmap/v1/fogmap.pb.h"

namespace fogmap {

struct ParentLinkConfig {
  std::string target;                      // host:port of the parent
  std::size_t max_message_bytes = 64U << 20;
  std::size_t max_unacked = 256;           // oldest unacknowledged uploads are dropped beyond this
  std::chrono::milliseconds backoff_initial{50};  // wait before re-opening a failed stream, doubled
  std::chrono::milliseconds backoff_max{2000};    // per failure up to this
  std::chrono::milliseconds keepalive{10000};     // transport ping interval (>= 5 s, see grpc_options)
};

// Observers for metrics (may be empty); called from the link's threads, never under its lock.
struct ParentLinkHooks {
  // One call per upload written to a stream (re-sends included); `kind` is "map" or "points"
  // ("empty" for an upload without payload), `bytes` its serialised size.
  std::function<void(const std::string& kind, std::size_t bytes)> on_sent;
  std::function<void()> on_reconnect;  // a stream was re-opened after a previous one failed
  std::function<void()> on_dropped;    // an unacknowledged upload was dropped (queue full)
};

class ParentLink {
 public:
  // Starts the stream thread at once; the parent need not be up yet.
  ParentLink(ParentLinkConfig config, ParentLinkHooks hooks);
  ~ParentLink();  // cancels the stream and joins its threads promptly; unacknowledged uploads are abandoned
  ParentLink(const ParentLink&) = delete;
  ParentLink& operator=(const ParentLink&) = delete;

  // Queues an upload (its sequence number, from 1 upwards, is assigned here) and returns at once.
  void send(fogmap::v1::Upload upload);
  // Blocks until every queued upload is acknowledged (or dropped) or the timeout passes; true
  // when none is left unacknowledged.
  bool flush(std::chrono::milliseconds timeout);
  std::size_t unacknowledged() const;
  // True while a stream to the parent is open.
  bool connected() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
  std::thread thread_;
};

}  // namespace fogmap
