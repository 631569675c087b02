#include "services/common/tracker_link.hpp"

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "services/common/backoff.hpp"
#include "services/common/stream_thread.hpp"

namespace fogmap {
namespace {


// What differs between the two streams: the messages and the method.
template <class Frame>
struct StreamKind;

template <>
struct StreamKind<tracking::DetectionFrame> {
  using Message = v1::DetectionFrame;
  using Summary = v1::DetectionSummary;
  static constexpr const char* kMethod = "PushDetections";
  static std::unique_ptr<grpc::ClientWriter<Message>> open(v1::TrackerService::Stub& stub, grpc::ClientContext* context,
                                                           Summary* summary) {
    return stub.PushDetections(context, summary);
  }
};

template <>
struct StreamKind<tracking::CentroidFrame> {
  using Message = v1::CentroidFrame;
  using Summary = v1::CentroidSummary;
  static constexpr const char* kMethod = "PushCentroids";
  static std::unique_ptr<grpc::ClientWriter<Message>> open(v1::TrackerService::Stub& stub, grpc::ClientContext* context,
                                                           Summary* summary) {
    return stub.PushCentroids(context, summary);
  }
};

// How long the destructor lets the tracker answer a half-closed stream before cancelling it.
constexpr std::chrono::milliseconds kCloseGrace{500};

template <class Summary>
std::string describeEnd(const grpc::Status& status, const Summary& summary, const char* method) {
  if (!status.ok()) {
    return "the stream to the tracker ended: " + fromGrpcStatus(status, method).message;
  }
  std::string why = "the tracker received " + std::to_string(summary.received()) + " frame(s), refused " +
                    std::to_string(summary.refused());
  if (!summary.last_refusal().empty()) why += " (last: " + summary.last_refusal() + ")";
  return why;
}

}  // namespace

template <class Frame>
struct TrackerStreamLink<Frame>::State : StreamThreadState {
  using Kind = StreamKind<Frame>;
  using Message = typename Kind::Message;
  using Writer = grpc::ClientWriter<Message>;

  struct Drop {
    std::uint64_t total = 0;
    bool first_of_burst = false;
  };

  TrackerLinkConfig config;
  TrackerLinkHooks hooks;
  std::unique_ptr<v1::TrackerService::Stub> stub;

  // Under mu (cv: any change: a new frame, a write, a broken stream, a stop, the end).
  std::deque<std::shared_ptr<const Message>> queue;
  std::uint64_t sent = 0;
  std::uint64_t dropped = 0;
  bool drop_burst = false;
  bool writing = false;
  bool connected = false;
  bool finished = false;  // the stream thread has returned
  std::shared_ptr<grpc::ClientContext> context;  // the current stream's, for TryCancel

  State(TrackerLinkConfig c, TrackerLinkHooks h)
      : StreamThreadState(channelFor(c)),
        config(std::move(c)),
        hooks(std::move(h)),
        stub(v1::TrackerService::NewStub(channel)) {
    config.queue_frames = std::max<std::size_t>(1, config.queue_frames);
  }

  // Counts a drop; under the lock.
  Drop noteDrop() {
    const Drop drop{++dropped, !drop_burst};
    drop_burst = true;
    return drop;
  }

  void reportDrops(const std::vector<Drop>& drops) const {
    if (!hooks.on_dropped) return;
    for (const Drop& d : drops) hooks.on_dropped(d.total, d.first_of_burst);
  }

  // Writes queued frames, oldest first, until a write fails or a stop is requested; true when it
  // wrote at least one.
  bool writeFrames(Writer& writer) {
    bool wrote = false;
    for (;;) {
      std::shared_ptr<const Message> next;
      {
        std::unique_lock lock(mu);
        cv.wait_for(lock, kPollSlice, [&] { return stopping || !queue.empty(); });
        if (stopping) return wrote;
        if (queue.empty()) continue;
        // Taken out of the queue: a frame is written once or dropped, never both.
        next = std::move(queue.front());
        queue.pop_front();
        writing = true;
      }
      const std::size_t bytes = next->ByteSizeLong();
      // Blocks under flow control; TryCancel (destructor) unblocks it.
      const bool written = writer.Write(*next);
      std::vector<Drop> drops;
      {
        std::lock_guard lock(mu);
        if (written) {
          ++sent;
          drop_burst = false;
        } else {
          drops.push_back(noteDrop());
        }
      }
      // The hooks run before the frame stops counting as in progress, so a flush() that returned
      // has seen them.
      if (written && hooks.on_sent) hooks.on_sent(bytes);
      reportDrops(drops);
      {
        std::lock_guard lock(mu);
        writing = false;
      }
      cv.notify_all();
      if (!written) return wrote;
      wrote = true;
    }
  }

  void run() {
    Backoff backoff(config.backoff_initial, config.backoff_max);
    bool had_stream = false;
    while (waitConnected()) {
      auto context = std::make_shared<grpc::ClientContext>();
      {
        std::lock_guard lock(mu);
        if (stopping) break;
        this->context = context;
      }
      typename Kind::Summary summary;
      // No deadline: the stream lives as long as the link; keepalive detects a dead tracker.
      std::unique_ptr<Writer> writer = Kind::open(*stub, context.get(), &summary);
      const std::int64_t opened_ns = now();
      {
        std::lock_guard lock(mu);
        connected = true;
      }
      if (had_stream && hooks.on_reconnect) hooks.on_reconnect();
      had_stream = true;

      const bool wrote = writeFrames(*writer);
      // A stop half-closes the stream so the tracker ends it cleanly and answers; a failed write
      // means the call is over already.
      if (stopRequested()) writer->WritesDone();
      const grpc::Status status = writer->Finish();
      {
        std::lock_guard lock(mu);
        connected = false;
        this->context.reset();
      }
      if (hooks.on_stream_ended) hooks.on_stream_ended(describeEnd(status, summary, Kind::kMethod));

      // A tracker that accepts streams and fails them at once must not be hammered; one that
      // took frames a while gets a quick reconnect.
      if (wrote || std::chrono::nanoseconds(now() - opened_ns) >= config.backoff_max) backoff.reset();
      if (sleepFor(backoff.next())) break;
    }
    {
      std::lock_guard lock(mu);
      finished = true;
    }
    cv.notify_all();
  }
};

template <class Frame>
TrackerStreamLink<Frame>::TrackerStreamLink(TrackerLinkConfig config, TrackerLinkHooks hooks)
    : state_(std::make_unique<State>(std::move(config), std::move(hooks))) {
  thread_ = std::thread([state = state_.get()] { state->run(); });
}

template <class Frame>
TrackerStreamLink<Frame>::~TrackerStreamLink() {
  {
    std::unique_lock lock(state_->mu);
    state_->stopping = true;
    state_->cv.notify_all();
    // The tracker gets a moment to answer the half-close; then the stream is cancelled, which
    // also ends a write blocked under flow control.
    if (!state_->cv.wait_for(lock, kCloseGrace, [&] { return state_->finished; }) && state_->context) {
      state_->context->TryCancel();
    }
  }
  thread_.join();
}

template <class Frame>
void TrackerStreamLink<Frame>::send(const Frame& frame) {
  auto message = std::make_shared<const typename State::Message>(toProto(frame));
  std::vector<typename State::Drop> drops;
  {
    std::lock_guard lock(state_->mu);
    state_->queue.push_back(std::move(message));
    while (state_->queue.size() > state_->config.queue_frames) {
      state_->queue.pop_front();
      drops.push_back(state_->noteDrop());
    }
  }
  state_->cv.notify_all();
  state_->reportDrops(drops);
}

template <class Frame>
bool TrackerStreamLink<Frame>::flush(std::chrono::milliseconds timeout) {
  std::unique_lock lock(state_->mu);
  return state_->cv.wait_for(lock, timeout, [&] { return state_->queue.empty() && !state_->writing; });
}

template <class Frame>
std::uint64_t TrackerStreamLink<Frame>::sent() const {
  std::lock_guard lock(state_->mu);
  return state_->sent;
}

template <class Frame>
std::uint64_t TrackerStreamLink<Frame>::dropped() const {
  std::lock_guard lock(state_->mu);
  return state_->dropped;
}

template <class Frame>
std::size_t TrackerStreamLink<Frame>::queued() const {
  std::lock_guard lock(state_->mu);
  return state_->queue.size();
}

template <class Frame>
bool TrackerStreamLink<Frame>::connected() const {
  std::lock_guard lock(state_->mu);
  return state_->connected;
}

template class TrackerStreamLink<tracking::DetectionFrame>;
template class TrackerStreamLink<tracking::CentroidFrame>;

}  // namespace fogmap
