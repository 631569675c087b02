#include "services/common/parent_link.hpp"

#include <algorithm>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <utility>

#include <grpcpp/grpcpp.h>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"

namespace fogmap {
namespace {

using Clock = std::chrono::steady_clock;
using Stream = grpc::ClientReaderWriter<v1::Upload, v1::Ack>;

// Upper bound of every blocking wait, so that a stop request is seen within this long even when
// a notification is missed.
constexpr std::chrono::milliseconds kPollSlice{100};

const char* kindOf(const v1::Upload& upload) {
  switch (upload.payload_case()) {
    case v1::Upload::kMap: return "map";
    case v1::Upload::kPoints: return "points";
    case v1::Upload::PAYLOAD_NOT_SET: break;
  }
  return "empty";
}

}  // namespace

struct ParentLink::State {
  struct Pending {
    std::uint64_t sequence = 0;
    // Shared so the writer can send it outside the lock while an ack or a drop removes it.
    std::shared_ptr<const v1::Upload> upload;
  };

  ParentLinkConfig config;
  ParentLinkHooks hooks;
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<v1::MapIngest::Stub> stub;

  mutable std::mutex mu;
  std::condition_variable cv;  // any change: new upload, ack, broken stream, stop
  std::deque<Pending> unacked;  // ascending sequence
  std::uint64_t next_sequence = 1;
  std::uint64_t written_upto = 0;  // highest sequence written on the current stream
  bool stopping = false;
  bool connected = false;
  bool stream_broken = false;
  std::shared_ptr<grpc::ClientContext> context;  // the current stream's, for TryCancel

  State(ParentLinkConfig c, ParentLinkHooks h)
      : config(std::move(c)),
        hooks(std::move(h)),
        channel(makeChannel(config.target, config.max_message_bytes, config.keepalive)),
        stub(v1::MapIngest::NewStub(channel)) {}

  bool stopRequested() const {
    std::lock_guard lock(mu);
    return stopping;
  }

  // Waits until the backoff has passed or a stop is requested; true when stopping.
  bool sleepFor(std::chrono::milliseconds d) {
    std::unique_lock lock(mu);
    return cv.wait_for(lock, d, [&] { return stopping; });
  }

  // Waits in short slices so that the destructor never waits on a parent that is down. (gRPC
  // converts only system_clock deadlines; a clock step merely lengthens or shortens one slice.)
  bool waitConnected() {
    while (!stopRequested()) {
      if (channel->WaitForConnected(std::chrono::system_clock::now() + kPollSlice)) return true;
    }
    return false;
  }

  void acknowledge(std::uint64_t sequence) {
    {
      std::lock_guard lock(mu);
      const auto it = std::lower_bound(unacked.begin(), unacked.end(), sequence,
                                       [](const Pending& p, std::uint64_t s) { return p.sequence < s; });
      // A re-sent upload may be acknowledged twice; the second ack finds nothing.
      if (it != unacked.end() && it->sequence == sequence) unacked.erase(it);
    }
    cv.notify_all();
  }

  void readAcks(Stream& stream, bool& got_ack) {
    v1::Ack ack;
    while (stream.Read(&ack)) {
      got_ack = true;
      acknowledge(ack.sequence());
    }
    {
      std::lock_guard lock(mu);
      stream_broken = true;
    }
    cv.notify_all();
  }

  // Writes every queued upload not yet written on this stream, in sequence order, until the
  // stream breaks or a stop is requested.
  void writeUploads(Stream& stream) {
    for (;;) {
      std::shared_ptr<const v1::Upload> next;
      std::uint64_t sequence = 0;
      {
        std::unique_lock lock(mu);
        const auto unwritten = [&] {
          return std::find_if(unacked.begin(), unacked.end(),
                              [&](const Pending& p) { return p.sequence > written_upto; });
        };
        cv.wait_for(lock, kPollSlice, [&] { return stopping || stream_broken || unwritten() != unacked.end(); });
        if (stopping || stream_broken) return;
        const auto it = unwritten();
        if (it == unacked.end()) continue;
        next = it->upload;
        sequence = it->sequence;
      }
      // Blocks under flow control; TryCancel from the destructor or a failed read unblocks it.
      if (!stream.Write(*next)) return;
      {
        std::lock_guard lock(mu);
        written_upto = std::max(written_upto, sequence);
      }
      if (hooks.on_sent) hooks.on_sent(kindOf(*next), next->ByteSizeLong());
    }
  }

  void run() {
    auto backoff = config.backoff_initial;
    bool had_stream = false;
    while (waitConnected()) {
      auto context = std::make_shared<grpc::ClientContext>();
      {
        std::lock_guard lock(mu);
        if (stopping) break;
        this->context = context;
        stream_broken = false;
        written_upto = 0;  // a new stream re-sends everything unacknowledged
      }
      // No deadline: the stream lives as long as the link; keepalive detects a dead parent.
      std::unique_ptr<Stream> stream = stub->Push(context.get());
      const auto opened = Clock::now();
      {
        std::lock_guard lock(mu);
        connected = true;
      }
      if (had_stream && hooks.on_reconnect) hooks.on_reconnect();
      had_stream = true;

      bool got_ack = false;
      std::thread reader([&] { readAcks(*stream, got_ack); });
      writeUploads(*stream);
      context->TryCancel();  // ends a Read still waiting when the write side failed or we stop
      reader.join();
      (void)stream->Finish();  // the cause does not change what we do next: reconnect
      {
        std::lock_guard lock(mu);
        connected = false;
        this->context.reset();
      }

      // A parent that accepts streams and fails them at once must not be hammered; one that
      // served a while gets a quick reconnect.
      if (got_ack || Clock::now() - opened >= config.backoff_max) backoff = config.backoff_initial;
      if (sleepFor(backoff)) break;
      backoff = std::min(backoff * 2, config.backoff_max);
    }
  }
};

ParentLink::ParentLink(ParentLinkConfig config, ParentLinkHooks hooks)
    : state_(std::make_unique<State>(std::move(config), std::move(hooks))) {
  thread_ = std::thread([state = state_.get()] { state->run(); });
}

ParentLink::~ParentLink() {
  {
    std::lock_guard lock(state_->mu);
    state_->stopping = true;
    if (state_->context) state_->context->TryCancel();
  }
  state_->cv.notify_all();
  thread_.join();
}

void ParentLink::send(v1::Upload upload) {
  std::size_t dropped = 0;
  {
    std::lock_guard lock(state_->mu);
    const std::uint64_t sequence = state_->next_sequence++;
    upload.set_sequence(sequence);
    state_->unacked.push_back({sequence, std::make_shared<const v1::Upload>(std::move(upload))});
    while (state_->unacked.size() > std::max<std::size_t>(state_->config.max_unacked, 1)) {
      state_->unacked.pop_front();
      ++dropped;
    }
  }
  state_->cv.notify_all();
  if (state_->hooks.on_dropped) {
    for (std::size_t i = 0; i < dropped; ++i) state_->hooks.on_dropped();
  }
}

bool ParentLink::flush(std::chrono::milliseconds timeout) {
  std::unique_lock lock(state_->mu);
  return state_->cv.wait_for(lock, timeout, [&] { return state_->unacked.empty(); });
}

std::size_t ParentLink::unacknowledged() const {
  std::lock_guard lock(state_->mu);
  return state_->unacked.size();
}

bool ParentLink::connected() const {
  std::lock_guard lock(state_->mu);
  return state_->connected;
}

}  // namespace fogmap
