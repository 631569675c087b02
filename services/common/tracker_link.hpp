#pragma once
// A node's side of a client stream to TrackerService: detection nodes push their camera's
// DetectionFrames (PushDetections), edges their displacement CentroidFrames (PushCentroids). One
// long-lived stream to the tracker, with keepalive and reconnect with the capped backoff of the
// upload link (ParentLinkConfig's). Both are perishable: a tracker fuses a frame only near its time,
// so nothing is re-sent, and a small queue keeps only the newest frames while the tracker is slow
// or down; every frame that does not reach a stream is dropped and counted.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>

#include <grpcpp/security/credentials.h>

#include "common/tracking/track.hpp"
#include "services/common/parent_link.hpp"

namespace fogmap {

struct TrackerLinkConfig {
  std::string target;  // host:port of the tracker
  // Transport credentials (grpc_options channelCredentials: this node's certificate with TLS);
  // null means plaintext.
  std::shared_ptr<grpc::ChannelCredentials> credentials{};
  std::size_t max_message_bytes = 64U << 20;
  std::size_t queue_frames = 4;  // frames waiting for the stream; beyond, the oldest is dropped (>= 1)
  // The same pacing as every link of the cluster.
  std::chrono::milliseconds backoff_initial = ParentLinkConfig{}.backoff_initial;
  std::chrono::milliseconds backoff_max = ParentLinkConfig{}.backoff_max;
  std::chrono::milliseconds keepalive = ParentLinkConfig{}.keepalive;
};

// Observers for metrics and logs (each may be empty); called from the link's thread or from
// send(), never under the link's lock.
struct TrackerLinkHooks {
  std::function<void(std::size_t bytes)> on_sent;  // one frame written to a stream, its serialised size
  std::function<void()> on_reconnect;              // a stream was opened after a previous one ended
  // One call per frame dropped (queue full, or its write failed), `dropped_total` counting it.
  // `first_of_burst` is true for the first drop since the start or since a frame was last written:
  // log only then.
  std::function<void(std::uint64_t dropped_total, bool first_of_burst)> on_dropped;
  // A stream ended; `why` is the tracker's summary or the failure, for a log line.
  std::function<void(const std::string& why)> on_stream_ended;
};

// `Frame` is tracking::DetectionFrame or tracking::CentroidFrame (the two streams of
// TrackerService; the aliases below).
template <class Frame>
class TrackerStreamLink {
 public:
  // Starts the stream thread at once; the tracker need not be up yet.
  TrackerStreamLink(TrackerLinkConfig config, TrackerLinkHooks hooks);
  // Ends the stream (half-closes it, giving the tracker a moment to answer) and joins the thread;
  // frames still queued are abandoned, not counted as dropped.
  ~TrackerStreamLink();
  TrackerStreamLink(const TrackerStreamLink&) = delete;
  TrackerStreamLink& operator=(const TrackerStreamLink&) = delete;

  // Converts the frame and queues it, dropping the oldest queued frame when full; returns at once.
  void send(const Frame& frame);
  // Blocks until every queued frame was written (or dropped), or the timeout passes; true when
  // none is left.
  bool flush(std::chrono::milliseconds timeout);
  std::uint64_t sent() const;     // frames written to a stream since construction
  std::uint64_t dropped() const;  // frames dropped since construction
  std::size_t queued() const;     // frames waiting for the stream
  bool connected() const;         // true while a stream to the tracker is open

 private:
  struct State;
  std::unique_ptr<State> state_;
  std::thread thread_;
};

// A detection node's link (PushDetections).
using DetectionLink = TrackerStreamLink<tracking::DetectionFrame>;
// An edge's link for its displacement centroids (PushCentroids).
using CentroidLink = TrackerStreamLink<tracking::CentroidFrame>;

}  // namespace fogmap
