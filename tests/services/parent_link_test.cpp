#include "services/common/parent_link.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <ostream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/base/clock.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "tests/support/eventually.hpp"
#include "tests/support/test_server.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using test_support::eventually;
// The parent: a real gRPC server on 127.0.0.1 serving a RecordingIngest; port 0 picks a free port.
using TestParent = test_support::TestServer;

// A one-shot event a test waits on, bounded.
class Signal {
 public:
  void set() {
    {
      std::lock_guard lock(mu_);
      set_ = true;
    }
    cv_.notify_all();
  }
  bool wait(std::chrono::milliseconds timeout = 10s) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, timeout, [&] { return set_; });
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  bool set_ = false;
};

// The link's clock (a steady clock in ns), held still until the test moves it on.
class ManualClock {
 public:
  NowNs fn() {
    return [this] {
      const std::int64_t now = now_.load();
      ++reads_;  // after the load: a read counted after advance() may still have seen the old time
      return now;
    };
  }
  void advance(std::chrono::nanoseconds d) { now_ += d.count(); }
  std::int64_t peek() const { return now_.load(); }  // not counted as a read

  // Waits (bounded) until the clock has been read twice more. While a single thread of the link
  // reads it (the one watching a stream, or the one backing off), the second read saw the time as
  // it is now, and the link decided on it under its lock before any query of the link returns.
  bool awaitLooks() {
    const std::uint64_t from = reads_.load();
    return eventually([&] { return reads_.load() >= from + 2; });
  }

 private:
  std::atomic<std::int64_t> now_{1'000'000'000'000};
  std::atomic<std::uint64_t> reads_{0};
};

// Holds a parent's answers until the test lets them go: the answer to an upload waits until its
// sequence is released (bounded, so that a failing test cannot keep its parent from stopping).
class AnswerGate {
 public:
  void release(std::uint64_t up_to) {
    {
      std::lock_guard lock(mu_);
      released_ = std::max(released_, up_to);
    }
    cv_.notify_all();
  }
  void open() { release(std::numeric_limits<std::uint64_t>::max()); }
  void await(std::uint64_t sequence) {
    std::unique_lock lock(mu_);
    cv_.wait_for(lock, 30s, [&] { return sequence <= released_; });
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::uint64_t released_ = 0;
};

// Opens the gate when the test's part ends, however it ends: declared after the parent, it lets
// the parent's handlers return before the parent stops.
class OpenOnExit {
 public:
  explicit OpenOnExit(AnswerGate& gate) : gate_(gate) {}
  ~OpenOnExit() { gate_.open(); }
  OpenOnExit(const OpenOnExit&) = delete;
  OpenOnExit& operator=(const OpenOnExit&) = delete;

 private:
  AnswerGate& gate_;
};

// What on_stalled reported: how long the answer was owed, per stall in order.
class StallLog {
 public:
  ParentLinkHooks hooks(ParentLinkHooks others) {
    others.on_stalled = [this](std::chrono::milliseconds waited) {
      std::lock_guard lock(mu_);
      waited_.push_back(waited);
    };
    return others;
  }
  std::vector<std::chrono::milliseconds> waited() const {
    std::lock_guard lock(mu_);
    return waited_;
  }

 private:
  mutable std::mutex mu_;
  std::vector<std::chrono::milliseconds> waited_;
};

v1::Ack answerWith(std::uint64_t sequence, v1::AckStatus status, const std::string& reason = "") {
  v1::Ack ack;
  ack.set_sequence(sequence);
  ack.set_status(status);
  ack.set_reason(reason);
  return ack;
}

// What a parent writes back for an upload that came on stream `stream_number` (from 1): nothing,
// one answer, or (misbehaving) several.
using Answer = std::function<std::vector<v1::Ack>(const v1::Upload& upload, int stream_number)>;

// Applies the uploads `ack_if` accepts and leaves the others unanswered.
Answer applyIf(std::function<bool(std::uint64_t)> ack_if) {
  return [ack_if = std::move(ack_if)](const v1::Upload& u, int /*stream_number*/) {
    return ack_if(u.sequence()) ? std::vector<v1::Ack>{answerWith(u.sequence(), v1::ACK_STATUS_APPLIED)}
                                : std::vector<v1::Ack>{};
  };
}

// A parent that records every upload it reads, with the number of the stream it came on (from 1),
// and writes back what `answer` says. With `end_first_stream_after`, the first stream is ended
// by the parent after that many uploads, so that the link opens a second one.
class RecordingIngest final : public v1::MapIngest::Service {
 public:
  explicit RecordingIngest(Answer answer = applyIf([](std::uint64_t) { return true; }),
                           std::size_t end_first_stream_after = 0)
      : answer_(std::move(answer)), end_first_stream_after_(end_first_stream_after) {}

  grpc::Status Push(grpc::ServerContext* /*context*/, grpc::ServerReaderWriter<v1::Ack, v1::Upload>* stream) override {
    int stream_number = 0;
    {
      std::lock_guard lock(mu_);
      stream_number = ++streams_;
    }
    std::size_t read = 0;
    v1::Upload upload;
    while (stream->Read(&upload)) {
      {
        std::lock_guard lock(mu_);
        received_.push_back(upload);
        stream_of_.push_back(stream_number);
      }
      cv_.notify_all();
      for (const v1::Ack& ack : answer_(upload, stream_number)) {
        if (!stream->Write(ack)) return grpc::Status::OK;
      }
      if (stream_number == 1 && ++read == end_first_stream_after_) {
        return grpc::Status(grpc::StatusCode::UNAVAILABLE, "ended by the test");
      }
    }
    return grpc::Status::OK;
  }

  // Waits until at least `n` uploads have arrived; bounded.
  bool waitForCount(std::size_t n, std::chrono::milliseconds timeout = 10s) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, timeout, [&] { return received_.size() >= n; });
  }

  std::vector<std::uint64_t> sequences() const {
    std::lock_guard lock(mu_);
    std::vector<std::uint64_t> out;
    for (const auto& u : received_) out.push_back(u.sequence());
    return out;
  }

  // The sequences that arrived on stream `number` (from 1), in arrival order.
  std::vector<std::uint64_t> sequencesOnStream(int number) const {
    std::lock_guard lock(mu_);
    std::vector<std::uint64_t> out;
    for (std::size_t i = 0; i < received_.size(); ++i) {
      if (stream_of_[i] == number) out.push_back(received_[i].sequence());
    }
    return out;
  }

  std::vector<v1::Upload> uploads() const {
    std::lock_guard lock(mu_);
    return received_;
  }

 private:
  Answer answer_;
  std::size_t end_first_stream_after_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  int streams_ = 0;
  std::vector<v1::Upload> received_;
  std::vector<int> stream_of_;
};

v1::Upload mapUpload(std::uint64_t epoch) {
  v1::Upload u;
  u.mutable_map()->mutable_header()->set_node(3);
  u.mutable_map()->mutable_header()->set_epoch(epoch);
  return u;
}

v1::Upload pointsUpload(std::uint64_t epoch) {
  v1::Upload u;
  u.mutable_points()->mutable_header()->set_epoch(epoch);
  u.mutable_points()->set_chunk_count(1);
  u.mutable_points()->set_xyz(std::string(12 * 100, '\0'));
  return u;
}

// Hooks that count into atomics and logs the test reads.
struct HookCounts {
  std::atomic<int> maps{0};
  std::atomic<int> points{0};
  std::atomic<std::size_t> bytes{0};
  std::atomic<int> reconnects{0};

  using Drop = std::pair<std::uint64_t, bool>;  // dropped_total, first_of_burst
  using Refusal = std::pair<std::uint64_t, std::string>;

  std::vector<Drop> drops() const {
    std::lock_guard lock(mu);
    return drops_;
  }
  std::vector<Refusal> refusals() const {
    std::lock_guard lock(mu);
    return refusals_;
  }
  std::vector<std::uint64_t> lates() const {
    std::lock_guard lock(mu);
    return lates_;
  }

  ParentLinkHooks hooks() {
    ParentLinkHooks h;
    h.on_sent = [this](const std::string& kind, std::size_t n) {
      if (kind == "map") ++maps;
      if (kind == "points") ++points;
      bytes += n;
    };
    h.on_reconnect = [this] { ++reconnects; };
    h.on_dropped = [this](std::uint64_t total, bool first_of_burst) {
      std::lock_guard lock(mu);
      drops_.emplace_back(total, first_of_burst);
    };
    h.on_refused = [this](std::uint64_t sequence, const std::string& reason) {
      std::lock_guard lock(mu);
      refusals_.emplace_back(sequence, reason);
    };
    h.on_late = [this](std::uint64_t sequence) {
      std::lock_guard lock(mu);
      lates_.push_back(sequence);
    };
    return h;
  }

 private:
  mutable std::mutex mu;
  std::vector<Drop> drops_;
  std::vector<Refusal> refusals_;
  std::vector<std::uint64_t> lates_;
};

// How one upload was settled, as its Settled callback saw it.
struct Outcome {
  std::optional<v1::AckStatus> status;
  std::string reason;
  bool operator==(const Outcome&) const = default;
};

std::ostream& operator<<(std::ostream& os, const Outcome& o) {
  if (!o.status) return os << "nullopt";
  return os << v1::AckStatus_Name(*o.status) << " '" << o.reason << "'";
}

const Outcome kApplied{v1::ACK_STATUS_APPLIED, ""};
const Outcome kDroppedOrAbandoned{std::nullopt, ""};

// Every Settled call, keyed by the upload the test tagged it with.
class SettledLog {
 public:
  ParentLink::Settled callbackFor(std::uint64_t key) {
    return [this, key](const std::optional<v1::Ack>& answer) {
      {
        std::lock_guard lock(mu_);
        outcomes_[key].push_back(answer ? Outcome{answer->status(), answer->reason()} : kDroppedOrAbandoned);
      }
      cv_.notify_all();
    };
  }

  // Every call made for `key`, in order: exactly one is expected once settled.
  std::vector<Outcome> of(std::uint64_t key) const {
    std::lock_guard lock(mu_);
    const auto it = outcomes_.find(key);
    return it == outcomes_.end() ? std::vector<Outcome>{} : it->second;
  }

  bool waitFor(std::uint64_t key, std::chrono::milliseconds timeout = 10s) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, timeout, [&] { return outcomes_.contains(key); });
  }

 private:
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::map<std::uint64_t, std::vector<Outcome>> outcomes_;
};

ParentLinkConfig configFor(const std::string& target) {
  ParentLinkConfig c;
  c.target = target;
  c.first_sequence = 1;  // the tests name uploads by sequence
  c.backoff_initial = 20ms;
  c.backoff_max = 500ms;
  return c;
}

// Serialised size of an upload once the link has given it `sequence`.
std::size_t sizeWithSequence(v1::Upload u, std::uint64_t sequence) {
  u.set_sequence(sequence);
  return u.ByteSizeLong();
}

// A port that was free a moment ago and now has no listener.
int closedPort() {
  RecordingIngest service;
  TestParent parent(service);
  return parent.port();
}

TEST(ParentLink, DeliversUploadsInOrderAndFlushes) {
  RecordingIngest service;
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  HookCounts counts;
  ParentLink link(configFor(parent.target()), counts.hooks());

  constexpr int kUploads = 40;
  std::size_t expected_bytes = 0;
  for (int i = 1; i <= kUploads; ++i) {
    v1::Upload u = i % 4 == 0 ? pointsUpload(static_cast<std::uint64_t>(i)) : mapUpload(static_cast<std::uint64_t>(i));
    u.set_sequence(static_cast<std::uint64_t>(i));  // what the link will assign
    expected_bytes += u.ByteSizeLong();
    link.send(std::move(u));
  }
  ASSERT_TRUE(link.flush(10s));
  EXPECT_EQ(link.unacknowledged(), 0U);
  EXPECT_TRUE(link.connected());

  const auto uploads = service.uploads();
  ASSERT_EQ(uploads.size(), static_cast<std::size_t>(kUploads));
  for (int i = 0; i < kUploads; ++i) {
    const v1::Upload& u = uploads[static_cast<std::size_t>(i)];
    EXPECT_EQ(u.sequence(), static_cast<std::uint64_t>(i + 1));
    const std::uint64_t epoch = u.has_map() ? u.map().header().epoch() : u.points().header().epoch();
    EXPECT_EQ(epoch, static_cast<std::uint64_t>(i + 1));
    EXPECT_EQ(u.has_points(), (i + 1) % 4 == 0);
  }
  EXPECT_EQ(counts.maps.load(), kUploads - kUploads / 4);
  EXPECT_EQ(counts.points.load(), kUploads / 4);
  EXPECT_EQ(counts.bytes.load(), expected_bytes);
  EXPECT_EQ(counts.reconnects.load(), 0);
  EXPECT_TRUE(counts.drops().empty());
  EXPECT_EQ(link.unacknowledgedBytes(), 0U);
  EXPECT_EQ(link.dropped(), 0U);
  EXPECT_EQ(link.refused(), 0U);
  EXPECT_EQ(link.late(), 0U);
}

TEST(ParentLink, FlushTimesOutWhileUploadsAreUnacknowledged) {
  RecordingIngest service(applyIf([](std::uint64_t) { return false; }));
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  ParentLink link(configFor(parent.target()), {});
  link.send(mapUpload(1));
  ASSERT_TRUE(service.waitForCount(1));
  EXPECT_FALSE(link.flush(100ms));
  EXPECT_EQ(link.unacknowledged(), 1U);
}

TEST(ParentLink, ResendsUnacknowledgedUploadsAfterParentRestart) {
  constexpr std::uint64_t kUploads = 10;
  constexpr std::uint64_t kAcked = 4;
  HookCounts counts;
  auto first_service = std::make_unique<RecordingIngest>(applyIf([](std::uint64_t s) { return s <= kAcked; }));
  auto first_parent = std::make_unique<TestParent>(*first_service);
  ASSERT_TRUE(first_parent->started());
  const int port = first_parent->port();
  ParentLink link(configFor(first_parent->target()), counts.hooks());

  for (std::uint64_t i = 1; i <= kUploads; ++i) link.send(mapUpload(i));
  ASSERT_TRUE(first_service->waitForCount(kUploads));
  ASSERT_TRUE(eventually([&] { return link.unacknowledged() == kUploads - kAcked; }));

  first_parent->stop();
  ASSERT_TRUE(eventually([&] { return !link.connected(); }));
  first_parent.reset();
  first_service.reset();

  RecordingIngest second_service;
  TestParent second_parent(second_service, port);
  ASSERT_TRUE(second_parent.started()) << "port " << port << " could not be bound again";
  ASSERT_TRUE(link.flush(15s));
  EXPECT_EQ(link.unacknowledged(), 0U);
  EXPECT_GE(counts.reconnects.load(), 1);

  // Re-sent in sequence order; duplicates would be allowed but every unacknowledged one arrives.
  auto resent = second_service.sequences();
  ASSERT_GE(resent.size(), kUploads - kAcked);
  EXPECT_EQ(resent.front(), kAcked + 1);
  EXPECT_TRUE(std::is_sorted(resent.begin(), resent.end()));
  for (std::uint64_t s = kAcked + 1; s <= kUploads; ++s) {
    EXPECT_NE(std::find(resent.begin(), resent.end(), s), resent.end()) << "sequence " << s;
  }
  for (std::uint64_t s = 1; s <= kAcked; ++s) {
    EXPECT_EQ(std::find(resent.begin(), resent.end(), s), resent.end()) << "acknowledged " << s << " was re-sent";
  }

  // The new stream carries new uploads too.
  link.send(mapUpload(kUploads + 1));
  ASSERT_TRUE(link.flush(10s));
  EXPECT_EQ(second_service.sequences().back(), kUploads + 1);
}

// --- Stalls and backoff, on the link's clock driven by the test: an answer is owed, and a backoff
// lasts, exactly as long as the test moves the clock on, however slow the machine.

TEST(ParentLink, AStreamWithoutAnswersIsGivenUpAsStalledAndTheUploadResent) {
  // The first stream reads and never answers (a parent stopped without a FIN looks like this);
  // later streams answer.
  RecordingIngest service([](const v1::Upload& u, int stream_number) {
    return stream_number == 1 ? std::vector<v1::Ack>{} : std::vector<v1::Ack>{answerWith(u.sequence(), v1::ACK_STATUS_APPLIED)};
  });
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  ManualClock clock;  // declared before the link, so that it outlives the link's threads
  ParentLinkConfig config = configFor(parent.target());
  config.answer_timeout = 60s;  // on the test's clock: never reached by the real one during the test
  config.backoff_initial = 0ms;
  StallLog stalls;
  HookCounts counts;
  SettledLog settled;
  ParentLink link(config, stalls.hooks(counts.hooks()), clock.fn());
  link.send(mapUpload(1), settled.callbackFor(1));
  ASSERT_TRUE(service.waitForCount(1));  // written: the answer is owed from here

  clock.advance(60s - 1ns);
  ASSERT_TRUE(clock.awaitLooks());
  EXPECT_EQ(link.stalls(), 0U) << "stalled before the answer timeout";
  EXPECT_TRUE(settled.of(1).empty());

  clock.advance(1ns);
  ASSERT_TRUE(settled.waitFor(1));
  EXPECT_EQ(settled.of(1), std::vector<Outcome>{kApplied});
  EXPECT_EQ(link.stalls(), 1U);
  EXPECT_GE(counts.reconnects.load(), 1);
  EXPECT_EQ(service.sequencesOnStream(1), std::vector<std::uint64_t>{1});
  EXPECT_EQ(service.sequencesOnStream(2), std::vector<std::uint64_t>{1});
  EXPECT_EQ(stalls.waited(), std::vector<std::chrono::milliseconds>{60s});
}

TEST(ParentLink, ASlowParentThatKeepsAnsweringIsNotStalled) {
  // Each answer comes 40 s (on the link's clock) after the previous one: 10 uploads queued at once
  // take 400 s in all, far beyond the 60 s answer timeout, but an answer is never owed for 60 s.
  AnswerGate gate;  // declared before the parent: its handler waits on it
  RecordingIngest service([&gate](const v1::Upload& u, int /*stream_number*/) {
    gate.await(u.sequence());
    return std::vector<v1::Ack>{answerWith(u.sequence(), v1::ACK_STATUS_APPLIED)};
  });
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  const OpenOnExit open_gate(gate);  // before the parent stops, however the test ends
  ManualClock clock;
  ParentLinkConfig config = configFor(parent.target());
  config.answer_timeout = 60s;
  ParentLink link(config, {}, clock.fn());
  constexpr std::uint64_t kUploads = 10;
  for (std::uint64_t i = 1; i <= kUploads; ++i) link.send(mapUpload(i));

  for (std::uint64_t i = 1; i <= kUploads; ++i) {
    // The parent holds upload i, and the link has taken in the answer to i - 1.
    ASSERT_TRUE(service.waitForCount(i)) << i;
    ASSERT_TRUE(eventually([&] { return link.unacknowledged() == kUploads - i + 1; })) << i;
    clock.advance(40s);
    ASSERT_TRUE(clock.awaitLooks()) << i;
    ASSERT_EQ(link.stalls(), 0U) << "stalled waiting for the answer to " << i;
    gate.release(i);
  }
  ASSERT_TRUE(link.flush(10s));
  EXPECT_EQ(link.stalls(), 0U);
  EXPECT_EQ(service.sequencesOnStream(2), std::vector<std::uint64_t>{});
}

TEST(ParentLink, AStreamReopenedAfterAStallOwesItsAnswerFromItsOwnResend) {
  // The first two streams never answer, the third does. A stream re-opened after a stall is
  // timed from its own re-send, not from the first send on the stalled stream: it must not be
  // given up at once (stalls cascading on a parent that would answer).
  RecordingIngest service([](const v1::Upload& u, int stream_number) {
    return stream_number <= 2 ? std::vector<v1::Ack>{} : std::vector<v1::Ack>{answerWith(u.sequence(), v1::ACK_STATUS_APPLIED)};
  });
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  ManualClock clock;
  ParentLinkConfig config = configFor(parent.target());
  config.answer_timeout = 60s;
  config.backoff_initial = 0ms;
  StallLog stalls;
  SettledLog settled;
  ParentLink link(config, stalls.hooks({}), clock.fn());
  link.send(mapUpload(1), settled.callbackFor(1));
  ASSERT_TRUE(service.waitForCount(1));
  clock.advance(60s);
  ASSERT_TRUE(eventually([&] { return service.sequencesOnStream(2) == std::vector<std::uint64_t>{1}; }));
  EXPECT_EQ(link.stalls(), 1U);

  // Re-sent at the time of the stall; nothing owed for long on the new stream yet.
  ASSERT_TRUE(clock.awaitLooks());
  EXPECT_EQ(link.stalls(), 1U) << "the re-opened stream was given up at once";
  clock.advance(60s - 1ns);
  ASSERT_TRUE(clock.awaitLooks());
  EXPECT_EQ(link.stalls(), 1U) << "the re-opened stream was given up before its own answer timeout";
  EXPECT_TRUE(service.sequencesOnStream(3).empty());

  clock.advance(1ns);
  ASSERT_TRUE(settled.waitFor(1));
  EXPECT_EQ(settled.of(1), std::vector<Outcome>{kApplied});
  EXPECT_EQ(link.stalls(), 2U);
  EXPECT_EQ(service.sequencesOnStream(3), std::vector<std::uint64_t>{1});
  EXPECT_EQ(stalls.waited(), (std::vector<std::chrono::milliseconds>{60s, 60s}));
}

TEST(ParentLink, AfterAStallTheStreamIsReopenedOnceTheBackoffHasPassedOnTheLinksClock) {
  RecordingIngest service([](const v1::Upload& u, int stream_number) {
    return stream_number == 1 ? std::vector<v1::Ack>{} : std::vector<v1::Ack>{answerWith(u.sequence(), v1::ACK_STATUS_APPLIED)};
  });
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  ManualClock clock;
  ParentLinkConfig config = configFor(parent.target());
  config.answer_timeout = 10s;
  config.backoff_initial = 60s;  // the first stream gave no answer and lived less than backoff_max
  config.backoff_max = 120s;
  std::atomic<std::int64_t> reopened_at{-1};  // the link's clock when the second stream opened
  HookCounts counts;
  ParentLinkHooks hooks = counts.hooks();
  hooks.on_reconnect = [&] {
    reopened_at = clock.peek();
    ++counts.reconnects;
  };
  SettledLog settled;
  ParentLink link(config, std::move(hooks), clock.fn());
  link.send(mapUpload(1), settled.callbackFor(1));
  ASSERT_TRUE(service.waitForCount(1));
  clock.advance(10s);
  ASSERT_TRUE(eventually([&] { return link.stalls() == 1U && !link.connected(); }));
  // Only the link's stream thread reads the clock now, and it has begun the backoff at this time.
  const std::int64_t stalled_at = clock.peek();
  ASSERT_TRUE(clock.awaitLooks());

  for (int step = 1; step < 6; ++step) {
    clock.advance(10s);
    ASSERT_TRUE(clock.awaitLooks()) << step;
    ASSERT_FALSE(link.connected()) << "re-opened " << step * 10 << " s into a 60 s backoff";
    ASSERT_EQ(counts.reconnects.load(), 0) << step;
  }
  clock.advance(10s);
  ASSERT_TRUE(settled.waitFor(1));
  EXPECT_EQ(settled.of(1), std::vector<Outcome>{kApplied});
  EXPECT_EQ(counts.reconnects.load(), 1);
  EXPECT_EQ(reopened_at.load(), stalled_at + std::chrono::nanoseconds(60s).count());
  EXPECT_EQ(service.sequencesOnStream(2), std::vector<std::uint64_t>{1});
}

TEST(ParentLink, UploadsQueuedBeforeParentStartsAreDelivered) {
  const int port = closedPort();
  ASSERT_GT(port, 0);
  HookCounts counts;
  ParentLink link(configFor("127.0.0.1:" + std::to_string(port)), counts.hooks());
  for (std::uint64_t i = 1; i <= 3; ++i) link.send(mapUpload(i));
  EXPECT_FALSE(link.connected());

  RecordingIngest service;
  TestParent parent(service, port);
  ASSERT_TRUE(parent.started());
  ASSERT_TRUE(link.flush(15s));
  EXPECT_EQ(service.sequences(), (std::vector<std::uint64_t>{1, 2, 3}));
  EXPECT_EQ(counts.reconnects.load(), 0);  // the first stream is a connect, not a reconnect
}

// --- 1. The queue is bounded in bytes, oldest dropped first, every drop counted and reported.

TEST(ParentLink, DropsOldestUploadsBeyondMaxUnackedBytes) {
  const int port = closedPort();
  ASSERT_GT(port, 0);
  HookCounts counts;
  SettledLog settled;
  ParentLinkConfig config = configFor("127.0.0.1:" + std::to_string(port));
  const std::size_t each = sizeWithSequence(pointsUpload(1), 1);  // all seven are this size
  config.max_unacked_bytes = 3 * each + each / 2;
  ParentLink link(config, counts.hooks());
  for (std::uint64_t i = 1; i <= 7; ++i) link.send(pointsUpload(i), settled.callbackFor(i));

  EXPECT_EQ(link.dropped(), 4U);
  EXPECT_EQ(link.unacknowledged(), 3U);
  EXPECT_EQ(link.unacknowledgedBytes(), 3 * each);
  EXPECT_EQ(counts.drops(), (std::vector<HookCounts::Drop>{{1, true}, {2, false}, {3, false}, {4, false}}));
  for (std::uint64_t i = 1; i <= 4; ++i) EXPECT_EQ(settled.of(i), std::vector<Outcome>{kDroppedOrAbandoned}) << i;
  for (std::uint64_t i = 5; i <= 7; ++i) EXPECT_TRUE(settled.of(i).empty()) << i;

  RecordingIngest service;
  TestParent parent(service, port);
  ASSERT_TRUE(parent.started());
  ASSERT_TRUE(link.flush(15s));
  EXPECT_EQ(service.sequences(), (std::vector<std::uint64_t>{5, 6, 7}));
  EXPECT_EQ(link.unacknowledgedBytes(), 0U);
  for (std::uint64_t i = 5; i <= 7; ++i) EXPECT_EQ(settled.of(i), std::vector<Outcome>{kApplied}) << i;
  for (std::uint64_t i = 1; i <= 4; ++i) EXPECT_EQ(settled.of(i).size(), 1U) << i;
}

TEST(ParentLink, KeepsManySmallUploadsWithinTheByteBound) {
  const int port = closedPort();
  ASSERT_GT(port, 0);
  HookCounts counts;
  ParentLink link(configFor("127.0.0.1:" + std::to_string(port)), counts.hooks());  // 64 MiB
  constexpr std::uint64_t kUploads = 1000;  // far more than any count bound the link had
  std::size_t bytes = 0;
  for (std::uint64_t i = 1; i <= kUploads; ++i) {
    bytes += sizeWithSequence(mapUpload(i), i);
    link.send(mapUpload(i));
  }
  EXPECT_EQ(link.unacknowledged(), kUploads);
  EXPECT_EQ(link.unacknowledgedBytes(), bytes);
  EXPECT_EQ(link.dropped(), 0U);
  EXPECT_TRUE(counts.drops().empty());
}

TEST(ParentLink, DropsAnUploadThatAloneExceedsTheBound) {
  const int port = closedPort();
  ASSERT_GT(port, 0);
  HookCounts counts;
  SettledLog settled;
  ParentLinkConfig config = configFor("127.0.0.1:" + std::to_string(port));
  config.max_unacked_bytes = 500;
  ASSERT_GT(sizeWithSequence(pointsUpload(2), 2), config.max_unacked_bytes);
  ParentLink link(config, counts.hooks());
  link.send(mapUpload(1), settled.callbackFor(1));
  link.send(pointsUpload(2), settled.callbackFor(2));

  EXPECT_EQ(link.dropped(), 1U);
  EXPECT_EQ(link.unacknowledged(), 1U);  // the older one stays: dropping it would not make room
  EXPECT_EQ(link.unacknowledgedBytes(), sizeWithSequence(mapUpload(1), 1));
  EXPECT_EQ(counts.drops(), (std::vector<HookCounts::Drop>{{1, true}}));
  EXPECT_EQ(settled.of(2), std::vector<Outcome>{kDroppedOrAbandoned});
  EXPECT_TRUE(settled.of(1).empty());

  RecordingIngest service;
  TestParent parent(service, port);
  ASSERT_TRUE(parent.started());
  link.send(mapUpload(3), settled.callbackFor(3));
  ASSERT_TRUE(link.flush(15s));
  EXPECT_EQ(service.sequences(), (std::vector<std::uint64_t>{1, 3}));
  EXPECT_EQ(settled.of(1), std::vector<Outcome>{kApplied});
  EXPECT_EQ(settled.of(3), std::vector<Outcome>{kApplied});
}

TEST(ParentLink, DropBurstEndsWhenAnUploadIsAnswered) {
  // Only 6 is answered: were 7 answered before 8 is sent (a matter of how fast the parent is),
  // 8 would fit beside 4 and 5 and nothing would be dropped.
  RecordingIngest service(applyIf([](std::uint64_t s) { return s == 6; }));
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  HookCounts counts;
  SettledLog settled;
  ParentLinkConfig config = configFor(parent.target());
  const std::size_t each = sizeWithSequence(pointsUpload(1), 1);
  config.max_unacked_bytes = 3 * each + each / 2;
  ParentLink link(config, counts.hooks());

  for (std::uint64_t i = 1; i <= 5; ++i) link.send(pointsUpload(i));  // drops 1, 2
  link.send(pointsUpload(6), settled.callbackFor(6));                 // drops 3; 6 is answered
  ASSERT_TRUE(settled.waitFor(6));
  EXPECT_EQ(settled.of(6), std::vector<Outcome>{kApplied});
  ASSERT_EQ(link.unacknowledged(), 2U);  // 4 and 5, never answered
  link.send(pointsUpload(7));  // never answered either
  link.send(pointsUpload(8));  // drops 4: a new burst

  EXPECT_EQ(counts.drops(), (std::vector<HookCounts::Drop>{{1, true}, {2, false}, {3, false}, {4, true}}));
  EXPECT_EQ(link.dropped(), 4U);
}

TEST(ParentLink, DropBurstEndsWhenTheQueueIsLeftEmpty) {
  const int port = closedPort();
  ASSERT_GT(port, 0);
  HookCounts counts;
  ParentLinkConfig config = configFor("127.0.0.1:" + std::to_string(port));
  config.max_unacked_bytes = 500;
  ParentLink link(config, counts.hooks());
  link.send(pointsUpload(1));  // too large: dropped, the queue is left empty
  link.send(pointsUpload(2));  // again
  link.send(mapUpload(3));     // fits
  link.send(pointsUpload(4));  // dropped: a new burst (the queue was left empty before)
  link.send(pointsUpload(5));  // dropped while 3 waits: the same burst
  EXPECT_EQ(counts.drops(), (std::vector<HookCounts::Drop>{{1, true}, {2, true}, {3, true}, {4, false}}));
  EXPECT_EQ(link.unacknowledged(), 1U);
}

// --- 2. Any answer settles an upload for good; refused and late ones are counted and reported.

TEST(ParentLink, AnsweredUploadsAreNeverResentAndRefusedAndLateAreReported) {
  // The first stream: 1 applied, 2 refused, 3 late, 4 unanswered, 5 refused, 6 unanswered, then
  // the parent ends it. Later streams apply everything.
  RecordingIngest service(
      [](const v1::Upload& u, int stream_number) {
        const std::uint64_t s = u.sequence();
        if (stream_number > 1) return std::vector<v1::Ack>{answerWith(s, v1::ACK_STATUS_APPLIED)};
        switch (s) {
          case 1: return std::vector<v1::Ack>{answerWith(s, v1::ACK_STATUS_APPLIED)};
          case 2: return std::vector<v1::Ack>{answerWith(s, v1::ACK_STATUS_REFUSED, "bad epoch")};
          case 3: return std::vector<v1::Ack>{answerWith(s, v1::ACK_STATUS_LATE)};
          case 5: return std::vector<v1::Ack>{answerWith(s, v1::ACK_STATUS_REFUSED, "too big")};
          default: return std::vector<v1::Ack>{};
        }
      },
      /*end_first_stream_after=*/6);
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  HookCounts counts;
  SettledLog settled;
  ParentLink link(configFor(parent.target()), counts.hooks());
  for (std::uint64_t i = 1; i <= 6; ++i) link.send(mapUpload(i), settled.callbackFor(i));
  ASSERT_TRUE(link.flush(15s));

  EXPECT_EQ(service.sequencesOnStream(1), (std::vector<std::uint64_t>{1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(service.sequencesOnStream(2), (std::vector<std::uint64_t>{4, 6}));
  EXPECT_EQ(service.sequences().size(), 8U);
  EXPECT_EQ(counts.reconnects.load(), 1);

  EXPECT_EQ(link.refused(), 2U);
  EXPECT_EQ(link.late(), 1U);
  EXPECT_EQ(counts.refusals(), (std::vector<HookCounts::Refusal>{{2, "bad epoch"}, {5, "too big"}}));
  EXPECT_EQ(counts.lates(), (std::vector<std::uint64_t>{3}));
  EXPECT_EQ(settled.of(1), std::vector<Outcome>{kApplied});
  EXPECT_EQ(settled.of(2), (std::vector<Outcome>{{v1::ACK_STATUS_REFUSED, "bad epoch"}}));
  EXPECT_EQ(settled.of(3), (std::vector<Outcome>{{v1::ACK_STATUS_LATE, ""}}));
  EXPECT_EQ(settled.of(4), std::vector<Outcome>{kApplied});
  EXPECT_EQ(settled.of(5), (std::vector<Outcome>{{v1::ACK_STATUS_REFUSED, "too big"}}));
  EXPECT_EQ(settled.of(6), std::vector<Outcome>{kApplied});
}

// --- 3. Sequence numbers never repeat across restarts of the sender.

TEST(ParentLink, SequencesStartAtTheWallClockInMicroseconds) {
  RecordingIngest service;
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  ParentLinkConfig config = configFor(parent.target());
  config.first_sequence.reset();
  const auto micros = [] {
    return static_cast<std::uint64_t>(
        std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count());
  };
  const std::uint64_t before = micros();
  ParentLink link(config, {});
  const std::uint64_t after = micros();
  link.send(mapUpload(1));
  link.send(mapUpload(2));
  ASSERT_TRUE(link.flush(10s));

  const auto sequences = service.sequences();
  ASSERT_EQ(sequences.size(), 2U);
  EXPECT_GE(sequences[0], before);
  EXPECT_LE(sequences[0], after);
  EXPECT_EQ(sequences[1], sequences[0] + 1);
}

TEST(ParentLink, SequencesDoNotRepeatAcrossRestartsOfTheSender) {
  RecordingIngest service;
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  ParentLinkConfig config = configFor(parent.target());
  config.first_sequence.reset();
  for (int run = 0; run < 2; ++run) {
    ParentLink link(config, {});
    for (std::uint64_t i = 1; i <= 3; ++i) link.send(mapUpload(i));
    ASSERT_TRUE(link.flush(10s));
  }
  const auto sequences = service.sequences();
  ASSERT_EQ(sequences.size(), 6U);
  EXPECT_TRUE(std::is_sorted(sequences.begin(), sequences.end()));
  EXPECT_EQ(std::adjacent_find(sequences.begin(), sequences.end()), sequences.end()) << "a sequence repeated";
}

TEST(ParentLink, SequencesIncreaseByOneFromFirstSequence) {
  RecordingIngest service;
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  ParentLinkConfig config = configFor(parent.target());
  constexpr std::uint64_t kFirst = 1'700'000'000'000'000;
  config.first_sequence = kFirst;
  ParentLink link(config, {});
  for (std::uint64_t i = 1; i <= 3; ++i) link.send(mapUpload(i));
  ASSERT_TRUE(link.flush(10s));
  EXPECT_EQ(service.sequences(), (std::vector<std::uint64_t>{kFirst, kFirst + 1, kFirst + 2}));
}

// --- 4. Each upload is settled exactly once, outside the link's lock.

TEST(ParentLink, SettledIsCalledOnceWhenAnUploadIsAnsweredTwice) {
  // 1 to 3 are answered twice (applied, then refused); 4 once, so that once 4 is settled every
  // earlier answer has been read (answers arrive in order on the stream).
  RecordingIngest service([](const v1::Upload& u, int /*stream_number*/) {
    const std::uint64_t s = u.sequence();
    std::vector<v1::Ack> answers{answerWith(s, v1::ACK_STATUS_APPLIED)};
    if (s <= 3) answers.push_back(answerWith(s, v1::ACK_STATUS_REFUSED, "seen before"));
    return answers;
  });
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  HookCounts counts;
  SettledLog settled;
  ParentLink link(configFor(parent.target()), counts.hooks());
  for (std::uint64_t i = 1; i <= 4; ++i) link.send(mapUpload(i), settled.callbackFor(i));
  ASSERT_TRUE(link.flush(10s));
  for (std::uint64_t i = 1; i <= 4; ++i) EXPECT_EQ(settled.of(i), std::vector<Outcome>{kApplied}) << i;
  EXPECT_EQ(link.refused(), 0U);
  EXPECT_TRUE(counts.refusals().empty());
}

TEST(ParentLink, SettledReportsUploadsAbandonedByTheDestructor) {
  const int port = closedPort();
  ASSERT_GT(port, 0);
  SettledLog settled;
  {
    ParentLink link(configFor("127.0.0.1:" + std::to_string(port)), {});
    for (std::uint64_t i = 1; i <= 3; ++i) link.send(mapUpload(i), settled.callbackFor(i));
    EXPECT_TRUE(settled.of(1).empty());
    EXPECT_EQ(link.dropped(), 0U);
  }
  for (std::uint64_t i = 1; i <= 3; ++i) EXPECT_EQ(settled.of(i), std::vector<Outcome>{kDroppedOrAbandoned}) << i;
}

TEST(ParentLink, SettledMayCallBackIntoTheLink) {
  RecordingIngest service;
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  ParentLinkConfig config = configFor(parent.target());
  config.max_unacked_bytes = 500;
  // Declared before the link, so that they outlive the link's threads.
  Signal chain_done;
  std::function<ParentLink::Settled(std::uint64_t)> relay;
  std::unique_ptr<ParentLink> link;
  link = std::make_unique<ParentLink>(config, ParentLinkHooks{});

  // On the reader thread: each answered upload sends the next, as a relay would, up to 5.
  constexpr std::uint64_t kChain = 5;
  relay = [&](std::uint64_t epoch) -> ParentLink::Settled {
    return [&, epoch](const std::optional<v1::Ack>& answer) {
      if (!answer) return;
      (void)link->unacknowledged();
      if (epoch == kChain) {
        chain_done.set();
      } else {
        link->send(mapUpload(epoch + 1), relay(epoch + 1));
      }
    };
  };
  link->send(mapUpload(1), relay(1));
  const bool chained = chain_done.wait();

  // In send(): a dropped upload's callback queries the link. Run on a thread of its own so that a
  // deadlock fails the test instead of hanging it.
  // (Shared, as the thread may outlive this test when it fails.)
  auto drop_done = std::make_shared<Signal>();
  auto seen_dropped = std::make_shared<std::atomic<std::uint64_t>>(0);
  std::thread([link = link.get(), drop_done, seen_dropped] {
    link->send(pointsUpload(1),
               [link, seen_dropped](const std::optional<v1::Ack>& /*answer*/) { *seen_dropped = link->dropped(); });
    drop_done->set();
  }).detach();
  const bool dropped_returned = drop_done->wait();

  EXPECT_TRUE(chained);
  EXPECT_TRUE(dropped_returned);
  if (!chained || !dropped_returned) {
    (void)link.release();  // deadlocked: leak it, its destructor would wait forever
    return;
  }
  EXPECT_EQ(seen_dropped->load(), 1U);
  ASSERT_TRUE(link->flush(10s));
  EXPECT_EQ(service.sequences(), (std::vector<std::uint64_t>{1, 2, 3, 4, 5}));
}

TEST(ParentLink, FlushWaitsForSettledCallbacksToReturn) {
  RecordingIngest service;
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  Signal entered;  // declared before the link, so they outlive its threads
  Signal release;
  std::atomic<bool> returned{false};
  ParentLink link(configFor(parent.target()), {});
  link.send(mapUpload(1), [&](const std::optional<v1::Ack>& /*answer*/) {
    entered.set();
    (void)release.wait();
    returned = true;
  });
  ASSERT_TRUE(entered.wait());
  EXPECT_EQ(link.unacknowledged(), 0U);  // answered, but its callback has not returned
  EXPECT_FALSE(link.flush(50ms));
  release.set();
  EXPECT_TRUE(link.flush(10s));
  EXPECT_TRUE(returned.load());
}

// --- 5. Unchanged behaviour: reconnects, backoff, prompt destruction.

TEST(ParentLink, DestructorReturnsPromptlyWhenParentIsGone) {
  const int port = closedPort();
  ASSERT_GT(port, 0);
  const auto start = Clock::now();
  {
    ParentLink link(configFor("127.0.0.1:" + std::to_string(port)), {});
    for (std::uint64_t i = 1; i <= 5; ++i) link.send(mapUpload(i));
    EXPECT_FALSE(link.flush(50ms));
  }
  EXPECT_LT(Clock::now() - start, 2s);
}

TEST(ParentLink, DestructorReturnsPromptlyWithOpenStream) {
  RecordingIngest service(applyIf([](std::uint64_t) { return false; }));
  TestParent parent(service);
  ASSERT_TRUE(parent.started());
  auto link = std::make_unique<ParentLink>(configFor(parent.target()), ParentLinkHooks{});
  link->send(mapUpload(1));
  ASSERT_TRUE(service.waitForCount(1));
  ASSERT_TRUE(link->connected());
  const auto start = Clock::now();
  link.reset();
  EXPECT_LT(Clock::now() - start, 2s);
}

}  // namespace
}  // namespace fogmap
