#pragma once
// The child's side of the upload stream: one long-lived MapIngest.Push stream to the parent,
// with keepalive, reconnect with capped backoff, and re-send of everything not yet answered
// (MERGE is idempotent, so a duplicate is harmless).
//
// Delivery contract:
// - Every upload gets a sequence number that never repeats across restarts of the sender: the
//   first is the wall clock in microseconds at construction (or `first_sequence`), then one more
//   per upload. (A sender that averaged more than one upload a microsecond, or a wall clock set
//   back between runs, could still repeat one.)
// - The parent answers every upload with an Ack carrying its status (applied, late or refused).
//   Any answer settles the upload: it leaves the queue and is never re-sent. Refused and late
//   answers are counted and reported through hooks.
// - Unanswered uploads stay queued, and are re-sent on every new stream, up to
//   `max_unacked_bytes` (the sum of their serialised sizes). Beyond it the oldest are dropped;
//   the upload just queued is dropped only when it alone exceeds the bound. Every drop is counted.
// - Each upload is settled exactly once: answered (the parent's Ack: status, reason and code),
//   dropped by the bound, or abandoned when the link is destroyed (both std::nullopt).
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include <grpcpp/security/credentials.h>

#include "common/base/clock.hpp"
#include "fogmap/v1/fogmap.pb.h"

namespace fogmap {

struct ParentLinkConfig {
  std::string target;                      // host:port of the parent
  // Transport credentials (grpc_options channelCredentials: this node's certificate with TLS);
  // null means plaintext.
  std::shared_ptr<grpc::ChannelCredentials> credentials{};
  std::size_t max_message_bytes = 64U << 20;
  std::size_t max_unacked_bytes = 64U << 20;  // serialised bytes of unanswered uploads kept for re-send
  std::optional<std::uint64_t> first_sequence{};  // default: wall clock in microseconds at construction
  std::chrono::milliseconds backoff_initial{50};  // wait before re-opening a failed stream, doubled
  std::chrono::milliseconds backoff_max{2000};    // per failure up to this
  std::chrono::milliseconds keepalive{10000};     // transport ping interval (>= 5 s, see grpc_options)
  // The application heartbeat: a stream on which an upload has waited this long for an answer,
  // with no answer at all meanwhile, is taken for stalled (a parent stopped or cut off without a
  // FIN, which keepalive notices only after keepalive + 5 s): it is cancelled and re-opened, and
  // the unanswered uploads are re-sent. Parents answer every upload; 0 disables the check.
  std::chrono::milliseconds answer_timeout{2000};
};

// Observers for metrics and logs (each may be empty); called from the link's threads or from
// send(), never under the link's lock.
struct ParentLinkHooks {
  // One call per upload written to a stream (re-sends included); `kind` is "map" or "points"
  // ("empty" for an upload without payload), `bytes` its serialised size.
  std::function<void(const std::string& kind, std::size_t bytes)> on_sent;
  std::function<void()> on_reconnect;  // a stream was re-opened after a previous one failed
  // A stream was given up as stalled (no answer within answer_timeout); `waited` is how long the
  // oldest unanswered upload had waited.
  std::function<void(std::chrono::milliseconds waited)> on_stalled;
  // One call per upload dropped by the byte bound, `dropped_total` counting it. `first_of_burst`
  // is true for the first drop since the start, since the parent's last answer, or since the queue
  // was last left empty: log only then.
  std::function<void(std::uint64_t dropped_total, bool first_of_burst)> on_dropped;
  // The parent refused a queued upload (it is not re-sent); `reason` is the parent's.
  std::function<void(std::uint64_t sequence, const std::string& reason)> on_refused;
  // The parent merged a queued upload into an epoch already emitted.
  std::function<void(std::uint64_t sequence)> on_late;
};

class ParentLink {
 public:
  // How one upload ended: the parent's answer (its sequence is the link's), or std::nullopt when
  // it was dropped by the byte bound or abandoned by the destructor.
  using Settled = std::function<void(const std::optional<fogmap::v1::Ack>& answer)>;

  // Starts the stream thread at once; the parent need not be up yet. `steady_now` is the clock of
  // the answer timeout and the backoff, a steady clock in ns (empty: std::chrono::steady_clock);
  // the link reads it at least every 100 ms while it waits, so a test can drive it by hand.
  ParentLink(ParentLinkConfig config, ParentLinkHooks hooks, NowNs steady_now = {});
  // Cancels the stream and joins its threads promptly; uploads still queued are abandoned (their
  // Settled called with std::nullopt on this thread; not counted as dropped).
  ~ParentLink();
  ParentLink(const ParentLink&) = delete;
  ParentLink& operator=(const ParentLink&) = delete;

  // Assigns the upload its sequence number, queues it (dropping the oldest beyond the byte bound)
  // and returns at once. `on_settled` is called exactly once, outside the link's lock: from the
  // link's reader thread when answered (keep it short: later answers wait for it), or from this
  // call or the destructor with std::nullopt. It may call back into the link, except flush().
  void send(fogmap::v1::Upload upload, Settled on_settled = {});
  // Blocks until every queued upload is answered or dropped and its Settled callback has returned,
  // or the timeout passes; true when none is left.
  bool flush(std::chrono::milliseconds timeout);
  std::size_t unacknowledged() const;       // uploads queued and not yet answered
  std::size_t unacknowledgedBytes() const;  // their serialised size, the quantity the bound limits
  std::uint64_t dropped() const;   // uploads dropped by the byte bound since construction
  std::uint64_t refused() const;   // queued uploads the parent refused since construction
  std::uint64_t late() const;      // queued uploads the parent answered late since construction
  std::uint64_t stalls() const;    // streams given up as stalled since construction
  // True while a stream to the parent is open.
  bool connected() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
  std::thread thread_;  // opens streams and watches them for stalls
};

}  // namespace fogmap
