#include "services/common/parent_link.hpp"

#include <algorithm>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/backoff.hpp"
#include "services/common/stream_thread.hpp"

namespace fogmap {
namespace {

using Stream = grpc::ClientReaderWriter<v1::Upload, v1::Ack>;

const char* kindOf(const v1::Upload& upload) {
  switch (upload.payload_case()) {
    case v1::Upload::kMap: return "map";
    case v1::Upload::kPoints: return "points";
    case v1::Upload::PAYLOAD_NOT_SET: break;
  }
  return "empty";
}

}  // namespace

struct ParentLink::State : StreamThreadState {
  struct Pending {
    std::uint64_t sequence = 0;
    std::size_t bytes = 0;  // serialised size, counted against max_unacked_bytes
    // Shared so the writer can send it outside the lock while an answer or a drop removes it.
    std::shared_ptr<const v1::Upload> upload;
    Settled on_settled;
  };
  // A Settled call taken out of the queue under the lock, to be made after releasing it.
  struct Settlement {
    Settled on_settled;
    std::optional<v1::Ack> answer;
  };
  struct Drop {
    std::uint64_t total = 0;
    bool first_of_burst = false;
  };

  ParentLinkConfig config;
  ParentLinkHooks hooks;
  std::unique_ptr<v1::MapIngest::Stub> stub;

  // Under mu (cv: any change: new upload, answer, settlement, broken stream, stop).
  std::deque<Pending> unacked;  // ascending sequence
  std::size_t unacked_bytes = 0;
  std::uint64_t next_sequence = 0;
  std::uint64_t write_from = 0;  // lowest sequence not yet written on the current stream
  std::size_t settling = 0;      // Settlements taken out of the queue whose call has not returned
  std::uint64_t dropped = 0;
  std::uint64_t refused = 0;
  std::uint64_t late = 0;
  std::uint64_t stalls = 0;
  // Since when (the link's clock, ns) the current stream has owed an answer without giving any:
  // set by the first write on the stream or after the last answer, moved on by each answer while
  // written uploads remain unanswered, cleared when a stream is opened.
  std::optional<std::int64_t> awaiting_since;
  bool writing = false;  // a Write is in progress (it may block under flow control)
  bool drop_burst = false;  // a drop happened since the last answer or empty queue
  bool connected = false;
  bool stream_broken = false;
  std::shared_ptr<grpc::ClientContext> context;  // the current stream's, for TryCancel

  State(ParentLinkConfig c, ParentLinkHooks h, NowNs steady_now)
      : StreamThreadState(channelFor(c), std::move(steady_now)),
        config(std::move(c)),
        hooks(std::move(h)),
        stub(v1::MapIngest::NewStub(channel)),
        // The wall clock, not a counter from 1: a restarted sender must not reuse a sequence the
        // parent has already seen with other content.
        next_sequence(config.first_sequence.value_or(wallClockMicros())) {}

  static std::uint64_t wallClockMicros() {
    const auto now = std::chrono::system_clock::now().time_since_epoch();
    return static_cast<std::uint64_t>(std::chrono::duration_cast<std::chrono::microseconds>(now).count());
  }

  // Counts a drop; under the lock.
  Drop noteDrop(Settled on_settled, std::vector<Settlement>& settlements) {
    settlements.push_back({std::move(on_settled), std::nullopt});
    ++settling;
    const Drop drop{++dropped, !drop_burst};
    drop_burst = true;
    return drop;
  }

  // Makes the Settled calls taken out of the queue; without the lock.
  void settle(std::vector<Settlement>& settlements) {
    if (settlements.empty()) return;
    for (Settlement& s : settlements) {
      if (s.on_settled) s.on_settled(s.answer);
    }
    {
      std::lock_guard lock(mu);
      settling -= settlements.size();
    }
    cv.notify_all();
  }

  // Any answer settles its upload: it leaves the queue and is never re-sent.
  void answer(const v1::Ack& ack) {
    std::vector<Settlement> settlements;
    {
      std::lock_guard lock(mu);
      drop_burst = false;
      const auto it = std::lower_bound(unacked.begin(), unacked.end(), ack.sequence(),
                                       [](const Pending& p, std::uint64_t s) { return p.sequence < s; });
      // An upload dropped meanwhile, or answered twice, finds nothing: it is settled already.
      if (it == unacked.end() || it->sequence != ack.sequence()) return;
      if (ack.status() == v1::ACK_STATUS_REFUSED) ++refused;
      if (ack.status() == v1::ACK_STATUS_LATE) ++late;
      settlements.push_back({std::move(it->on_settled), ack});
      ++settling;
      unacked_bytes -= it->bytes;
      unacked.erase(it);
      const bool still_owed = writing || (!unacked.empty() && unacked.front().sequence < write_from);
      awaiting_since = still_owed ? std::optional(now()) : std::nullopt;
    }
    cv.notify_all();
    if (ack.status() == v1::ACK_STATUS_REFUSED && hooks.on_refused) hooks.on_refused(ack.sequence(), ack.reason());
    if (ack.status() == v1::ACK_STATUS_LATE && hooks.on_late) hooks.on_late(ack.sequence());
    settle(settlements);
  }

  void readAnswers(Stream& stream, bool& got_answer) {
    v1::Ack ack;
    while (stream.Read(&ack)) {
      got_answer = true;
      answer(ack);
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
      std::size_t bytes = 0;
      {
        std::unique_lock lock(mu);
        const auto unwritten = [&] {
          return std::lower_bound(unacked.begin(), unacked.end(), write_from,
                                  [](const Pending& p, std::uint64_t s) { return p.sequence < s; });
        };
        cv.wait_for(lock, kPollSlice, [&] { return stopping || stream_broken || unwritten() != unacked.end(); });
        if (stopping || stream_broken) return;
        const auto it = unwritten();
        if (it == unacked.end()) continue;
        next = it->upload;
        sequence = it->sequence;
        bytes = it->bytes;
        writing = true;
        if (!awaiting_since) awaiting_since = now();
      }
      // Blocks under flow control; TryCancel (destructor, failed read, stall) unblocks it.
      const bool written = stream.Write(*next);
      {
        std::lock_guard lock(mu);
        writing = false;
        if (written) write_from = std::max(write_from, sequence + 1);
      }
      if (!written) return;
      if (hooks.on_sent) hooks.on_sent(kindOf(*next), bytes);
    }
  }

  // Watches the current stream until it breaks, a stop is requested, or it stalls: an answer owed
  // for answer_timeout by the link's clock, which it reads at least every kPollSlice. Returns how
  // long the answer was owed when it stalled.
  std::optional<std::chrono::milliseconds> watch() {
    const std::chrono::nanoseconds timeout = config.answer_timeout;
    std::unique_lock lock(mu);
    for (;;) {
      if (stopping || stream_broken) return std::nullopt;
      if (timeout.count() > 0 && awaiting_since) {
        const std::chrono::nanoseconds owed{now() - *awaiting_since};
        if (owed >= timeout) {
          stream_broken = true;
          ++stalls;
          return std::chrono::duration_cast<std::chrono::milliseconds>(owed);
        }
      }
      cv.wait_for(lock, kPollSlice);
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
        stream_broken = false;
        write_from = 0;  // a new stream re-sends everything unanswered
        awaiting_since.reset();
      }
      // No deadline: the stream lives as long as the link; keepalive detects a dead parent.
      std::unique_ptr<Stream> stream = stub->Push(context.get());
      const std::int64_t opened = now();
      {
        std::lock_guard lock(mu);
        connected = true;
      }
      if (had_stream && hooks.on_reconnect) hooks.on_reconnect();
      had_stream = true;

      bool got_answer = false;
      std::thread reader([&] { readAnswers(*stream, got_answer); });
      std::thread writer([&] {
        writeUploads(*stream);
        {
          std::lock_guard lock(mu);
          stream_broken = true;
        }
        cv.notify_all();
      });
      const auto stalled = watch();
      cv.notify_all();
      context->TryCancel();  // ends a Read or a Write still blocked
      writer.join();
      reader.join();
      if (stalled && hooks.on_stalled) hooks.on_stalled(*stalled);
      (void)stream->Finish();  // the cause does not change what we do next: reconnect
      {
        std::lock_guard lock(mu);
        connected = false;
        this->context.reset();
      }

      // A parent that accepts streams and fails them at once must not be hammered; one that
      // served a while gets a quick reconnect.
      if (got_answer || std::chrono::nanoseconds(now() - opened) >= config.backoff_max) backoff.reset();
      if (sleepFor(backoff.next())) break;
    }
  }
};

ParentLink::ParentLink(ParentLinkConfig config, ParentLinkHooks hooks, NowNs steady_now)
    : state_(std::make_unique<State>(std::move(config), std::move(hooks), std::move(steady_now))) {
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
  std::deque<State::Pending> abandoned;
  {
    std::lock_guard lock(state_->mu);
    abandoned.swap(state_->unacked);
    state_->unacked_bytes = 0;
  }
  for (State::Pending& p : abandoned) {
    if (p.on_settled) p.on_settled(std::nullopt);
  }
}

void ParentLink::send(v1::Upload upload, Settled on_settled) {
  std::vector<State::Settlement> settlements;
  std::vector<State::Drop> drops;
  {
    std::lock_guard lock(state_->mu);
    const std::uint64_t sequence = state_->next_sequence++;
    upload.set_sequence(sequence);
    const std::size_t bytes = upload.ByteSizeLong();
    const std::size_t bound = state_->config.max_unacked_bytes;
    if (bytes > bound) {
      // Dropping older uploads could not make room for it.
      drops.push_back(state_->noteDrop(std::move(on_settled), settlements));
    } else {
      state_->unacked.push_back(
          {sequence, bytes, std::make_shared<const v1::Upload>(std::move(upload)), std::move(on_settled)});
      state_->unacked_bytes += bytes;
      while (state_->unacked_bytes > bound) {  // stops before the new one, which fits alone
        State::Pending& oldest = state_->unacked.front();
        state_->unacked_bytes -= oldest.bytes;
        drops.push_back(state_->noteDrop(std::move(oldest.on_settled), settlements));
        state_->unacked.pop_front();
      }
    }
    if (state_->unacked.empty()) state_->drop_burst = false;
  }
  state_->cv.notify_all();
  if (state_->hooks.on_dropped) {
    for (const State::Drop& d : drops) state_->hooks.on_dropped(d.total, d.first_of_burst);
  }
  state_->settle(settlements);
}

bool ParentLink::flush(std::chrono::milliseconds timeout) {
  std::unique_lock lock(state_->mu);
  return state_->cv.wait_for(lock, timeout, [&] { return state_->unacked.empty() && state_->settling == 0; });
}

std::size_t ParentLink::unacknowledged() const {
  std::lock_guard lock(state_->mu);
  return state_->unacked.size();
}

std::size_t ParentLink::unacknowledgedBytes() const {
  std::lock_guard lock(state_->mu);
  return state_->unacked_bytes;
}

std::uint64_t ParentLink::dropped() const {
  std::lock_guard lock(state_->mu);
  return state_->dropped;
}

std::uint64_t ParentLink::refused() const {
  std::lock_guard lock(state_->mu);
  return state_->refused;
}

std::uint64_t ParentLink::late() const {
  std::lock_guard lock(state_->mu);
  return state_->late;
}

std::uint64_t ParentLink::stalls() const {
  std::lock_guard lock(state_->mu);
  return state_->stalls;
}

bool ParentLink::connected() const {
  std::lock_guard lock(state_->mu);
  return state_->connected;
}

}  // namespace fogmap
