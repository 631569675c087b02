#include "services/common/parent_link.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// Polls a condition that has no notification to wait on (state inside another object), bounded.
bool eventually(const std::function<bool()>& condition, std::chrono::milliseconds timeout = 10s) {
  const auto deadline = Clock::now() + timeout;
  while (Clock::now() < deadline) {
    if (condition()) return true;
    std::this_thread::sleep_for(5ms);
  }
  return condition();
}

// A parent that records every upload it reads and acknowledges those `ack_if` accepts.
class RecordingIngest final : public v1::MapIngest::Service {
 public:
  explicit RecordingIngest(std::function<bool(std::uint64_t)> ack_if = [](std::uint64_t) { return true; })
      : ack_if_(std::move(ack_if)) {}

  grpc::Status Push(grpc::ServerContext* /*context*/, grpc::ServerReaderWriter<v1::Ack, v1::Upload>* stream) override {
    v1::Upload upload;
    while (stream->Read(&upload)) {
      {
        std::lock_guard lock(mu_);
        received_.push_back(upload);
      }
      cv_.notify_all();
      if (ack_if_(upload.sequence())) {
        v1::Ack ack;
        ack.set_sequence(upload.sequence());
        if (!stream->Write(ack)) break;
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

  std::vector<v1::Upload> uploads() const {
    std::lock_guard lock(mu_);
    return received_;
  }

 private:
  std::function<bool(std::uint64_t)> ack_if_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::vector<v1::Upload> received_;
};

// A real gRPC server on 127.0.0.1; port 0 picks a free port.
class TestParent {
 public:
  TestParent(RecordingIngest& service, int port = 0) {
    grpc::ServerBuilder builder;
    configureServer(builder, 64U << 20);
    builder.AddListeningPort("127.0.0.1:" + std::to_string(port), grpc::InsecureServerCredentials(), &port_);
    builder.RegisterService(&service);
    server_ = builder.BuildAndStart();
  }
  ~TestParent() { stop(); }

  bool started() const { return server_ != nullptr && port_ > 0; }
  int port() const { return port_; }
  std::string target() const { return "127.0.0.1:" + std::to_string(port_); }

  // Cancels open streams at once: a Push handler would otherwise keep Shutdown waiting forever.
  void stop() {
    if (!server_) return;
    server_->Shutdown(std::chrono::system_clock::now());
    server_->Wait();
    server_.reset();
  }

 private:
  int port_ = 0;
  std::unique_ptr<grpc::Server> server_;
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

// Hooks that count into atomics the test reads.
struct HookCounts {
  std::atomic<int> maps{0};
  std::atomic<int> points{0};
  std::atomic<std::size_t> bytes{0};
  std::atomic<int> reconnects{0};
  std::atomic<int> dropped{0};

  ParentLinkHooks hooks() {
    ParentLinkHooks h;
    h.on_sent = [this](const std::string& kind, std::size_t n) {
      if (kind == "map") ++maps;
      if (kind == "points") ++points;
      bytes += n;
    };
    h.on_reconnect = [this] { ++reconnects; };
    h.on_dropped = [this] { ++dropped; };
    return h;
  }
};

ParentLinkConfig configFor(const std::string& target) {
  ParentLinkConfig c;
  c.target = target;
  c.backoff_initial = 20ms;
  c.backoff_max = 500ms;
  return c;
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
  EXPECT_EQ(counts.dropped.load(), 0);
}

TEST(ParentLink, FlushTimesOutWhileUploadsAreUnacknowledged) {
  RecordingIngest service([](std::uint64_t) { return false; });
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
  auto first_service = std::make_unique<RecordingIngest>([](std::uint64_t s) { return s <= kAcked; });
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

TEST(ParentLink, DropsOldestUploadsBeyondMaxUnacked) {
  const int port = closedPort();
  ASSERT_GT(port, 0);
  HookCounts counts;
  ParentLinkConfig config = configFor("127.0.0.1:" + std::to_string(port));
  config.max_unacked = 4;
  ParentLink link(config, counts.hooks());
  for (std::uint64_t i = 1; i <= 7; ++i) link.send(mapUpload(i));
  EXPECT_EQ(counts.dropped.load(), 3);
  EXPECT_EQ(link.unacknowledged(), 4U);

  RecordingIngest service;
  TestParent parent(service, port);
  ASSERT_TRUE(parent.started());
  ASSERT_TRUE(link.flush(15s));
  EXPECT_EQ(service.sequences(), (std::vector<std::uint64_t>{4, 5, 6, 7}));
}

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
  RecordingIngest service([](std::uint64_t) { return false; });
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
