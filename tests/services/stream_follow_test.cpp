// A command line's side of a server stream (stream_follow.hpp) against a real gRPC server on
// 127.0.0.1 that sends a given number of global maps, then ends the stream or holds it open.
#include "services/common/stream_follow.hpp"

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <grpcpp/grpcpp.h>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "tests/support/free_ports.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;

// Sends `maps` global maps (epochs 1, 2, ...), then ends the stream when `end` is set, else holds
// it open until the client cancels it.
class MapSource final : public v1::GlobalMapService::Service {
 public:
  MapSource(int maps, bool end) : maps_(maps), end_(end) {}

  grpc::Status Subscribe(grpc::ServerContext* context, const v1::SubscribeRequest*, grpc::ServerWriter<v1::GlobalMap>* writer) override {
    for (int k = 1; k <= maps_; ++k) {
      v1::GlobalMap map;
      map.mutable_header()->set_epoch(static_cast<std::uint64_t>(k));
      if (!writer->Write(map)) return grpc::Status::CANCELLED;
    }
    if (end_) return grpc::Status::OK;
    // Bounded: a client that never cancels fails the test rather than hanging it.
    for (int k = 0; k < 6000 && !context->IsCancelled(); ++k) std::this_thread::sleep_for(10ms);
    cancelled_ = context->IsCancelled();
    return grpc::Status::CANCELLED;
  }

  bool cancelled() const { return cancelled_; }

 private:
  const int maps_;
  const bool end_;
  std::atomic<bool> cancelled_{false};
};

class Server {
 public:
  Server(int maps, bool end) : source_(maps, end) {
    grpc::ServerBuilder builder;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port_);
    builder.RegisterService(&source_);
    server_ = builder.BuildAndStart();
  }
  ~Server() { server_->Shutdown(std::chrono::system_clock::now() + 2s); }
  std::string target() const { return "127.0.0.1:" + std::to_string(port_); }
  const MapSource& source() const { return source_; }

 private:
  MapSource source_;
  int port_ = 0;
  std::unique_ptr<grpc::Server> server_;
};

struct Followed {
  FollowResult result;
  std::vector<std::uint64_t> epochs;
};

Followed followMaps(const std::string& target, FollowOptions options) {
  const auto channel = makeChannel(target, 4U << 20);
  auto stub = v1::GlobalMapService::NewStub(channel);
  grpc::ClientContext context;
  auto reader = stub->Subscribe(&context, v1::SubscribeRequest{});
  Followed out;
  out.result = followStream<v1::GlobalMap>(
      context, *reader, [&](const v1::GlobalMap& m) { out.epochs.push_back(m.header().epoch()); }, options);
  return out;
}

TEST(StreamFollow, StopsAfterTheCountOfMessagesInTheirOrder) {
  Server server(5, false);
  FollowOptions options;
  options.count = 3;
  const Followed f = followMaps(server.target(), options);
  EXPECT_EQ(f.result.end, FollowEnd::kCounted);
  EXPECT_EQ(f.result.messages, 3);
  EXPECT_EQ(f.epochs, (std::vector<std::uint64_t>{1, 2, 3}));
}

TEST(StreamFollow, AServerThatEndsTheStreamIsLostWithTheReason) {
  Server server(2, true);
  const Followed f = followMaps(server.target(), FollowOptions{});
  EXPECT_EQ(f.result.end, FollowEnd::kLost);
  EXPECT_EQ(f.result.why, "it ended the stream");
  EXPECT_EQ(f.result.messages, 2);
}

TEST(StreamFollow, ASilentServerIsReportedAtEachIdlePeriodThenGivenUpOn) {
  Server server(1, false);
  FollowOptions options;
  options.idle_s = 0.05;
  options.timeout_s = 0.3;
  std::mutex mutex;
  std::vector<double> reported;
  options.on_idle = [&](double silent_s) {
    std::lock_guard lock(mutex);
    reported.push_back(silent_s);
  };
  const auto start = std::chrono::steady_clock::now();
  const Followed f = followMaps(server.target(), options);
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(f.result.end, FollowEnd::kGaveUp);
  EXPECT_EQ(f.result.messages, 1);
  EXPECT_GE(elapsed_s, 0.3) << "gave up before the timeout";
  std::lock_guard lock(mutex);
  ASSERT_FALSE(reported.empty());
  for (std::size_t k = 0; k < reported.size(); ++k) EXPECT_DOUBLE_EQ(reported[k], 0.05 * static_cast<double>(k + 1));
}

TEST(StreamFollow, AStopEndsTheStreamAndTheServerSeesItCancelled) {
  auto server = std::make_unique<Server>(1, false);
  std::atomic<bool> stop{false};
  FollowOptions options;
  options.stop = [&] { return stop.load(); };
  const auto channel = makeChannel(server->target(), 4U << 20);
  auto stub = v1::GlobalMapService::NewStub(channel);
  grpc::ClientContext context;
  auto reader = stub->Subscribe(&context, v1::SubscribeRequest{});
  const FollowResult result =
      followStream<v1::GlobalMap>(context, *reader, [&](const v1::GlobalMap&) { stop = true; }, options);
  EXPECT_EQ(result.end, FollowEnd::kStopped);
  EXPECT_EQ(result.messages, 1);
  server.reset();  // waits for the handler, which returns once it sees the cancellation
}

TEST(StreamFollow, WaitingForAChannelNamesWhyItGaveUpOrSucceeds) {
  Server server(0, true);
  EXPECT_EQ(waitForChannel(*makeChannel(server.target(), 4U << 20), 5.0), "");
  const std::string nowhere = "127.0.0.1:" + std::to_string(test_support::freePorts(1).front());
  const std::string problem = waitForChannel(*makeChannel(nowhere, 4U << 20), 0.3);
  EXPECT_NE(problem.find("within 0.3 s"), std::string::npos) << problem;
  EXPECT_EQ(waitForChannel(*makeChannel(nowhere, 4U << 20), 5.0, [] { return true; }), "interrupted");
}

}  // namespace
}  // namespace fogmap
