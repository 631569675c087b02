#pragma once
// An aggregator process as its main composes it (AggregatorProcess served by serveUntilStopped),
// run in the test's own process on loopback until the test requests its stop; and a subscriber of a
// root's global maps that records what was published.
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <future>
#include <memory>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>

#include <grpcpp/grpcpp.h>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/service_main.hpp"
#include "services/merge_aggregator/aggregator_process.hpp"
#include "tests/support/service_context.hpp"

namespace fogmap::test_support {

// Aggregator `name` of `topology` (its ports must be free), serving from construction.
class ServedAggregator {
 public:
  ServedAggregator(const TopologyConfig& topology, const std::string& name) : node_(topology, name) {
    auto process = AggregatorProcess::create(node_.context());
    if (!process) throw std::runtime_error(process.error().message);
    process_ = std::move(*process);
    ServiceLifecycle lifecycle = process_->lifecycle();
    lifecycle.serving = [serving = std::move(lifecycle.serving), this](int port) {
      serving(port);
      serving_.set_value();
    };
    exit_ = std::async(std::launch::async, [this, lifecycle = std::move(lifecycle)] {
      return serveUntilStopped(node_.context(), process_->services(), lifecycle);
    });
    serving_.get_future().wait();
  }
  ~ServedAggregator() {
    if (exit_.valid()) stop();
  }
  ServedAggregator(const ServedAggregator&) = delete;
  ServedAggregator& operator=(const ServedAggregator&) = delete;

  // Requests the stop, as SIGTERM would; returns the process's exit code once it has stopped.
  int stop() {
    node_.stop().request();
    return exit_.get();
  }
  std::shared_ptr<grpc::Channel> channel() const {
    return makeChannel(endpoint(node_.node().host, node_.node().port), 64U << 20);
  }

 private:
  HandMadeContext node_;
  std::unique_ptr<AggregatorProcess> process_;
  std::promise<void> serving_;
  std::future<int> exit_;
};

// A Subscribe call to a root, read on its own thread until the stream ends.
class GlobalMapWatcher {
 public:
  // Bounds the call only so that a broken root fails the test instead of hanging it.
  static constexpr std::chrono::seconds kCallLimit{60};

  explicit GlobalMapWatcher(std::shared_ptr<grpc::Channel> channel)
      : stub_(v1::GlobalMapService::NewStub(std::move(channel))) {
    context_.set_deadline(std::chrono::system_clock::now() + kCallLimit);
    context_.set_wait_for_ready(true);
    reader_ = stub_->Subscribe(&context_, v1::SubscribeRequest{});
    // The root publishes every epoch from its first poll: one map read means the subscription is in.
    v1::GlobalMap first;
    subscribed_ = reader_->Read(&first);
    reading_ = std::async(std::launch::async, [this] {
      v1::GlobalMap map;
      while (reader_->Read(&map)) {
        std::lock_guard lock(mutex_);
        for (const std::uint32_t node : map.header().contributing_nodes()) seen_.insert({map.header().epoch(), node});
        published_.notify_all();
      }
      {
        std::lock_guard lock(mutex_);
        over_ = true;
      }
      published_.notify_all();
      return reader_->Finish();
    });
  }
  ~GlobalMapWatcher() { context_.TryCancel(); }  // a test that failed early does not wait for the stream
  GlobalMapWatcher(const GlobalMapWatcher&) = delete;
  GlobalMapWatcher& operator=(const GlobalMapWatcher&) = delete;

  bool subscribed() const { return subscribed_; }
  // Blocks until a global map names `node` among its contributing nodes; false when the stream
  // ended first.
  bool waitForContribution(std::uint32_t node) {
    const auto contributed = [&] {
      for (const auto& [epoch, seen] : seen_) {
        if (seen == node) return true;
      }
      return false;
    };
    std::unique_lock lock(mutex_);
    published_.wait(lock, [&] { return over_ || contributed(); });
    return contributed();
  }
  // Once the stream has ended: its status.
  grpc::Status ended() { return reading_.get(); }
  // Whether a global map of `epoch` named `node` among its contributing nodes.
  bool saw(std::uint64_t epoch, std::uint32_t node) {
    std::lock_guard lock(mutex_);
    return seen_.contains({epoch, node});
  }

 private:
  std::unique_ptr<v1::GlobalMapService::Stub> stub_;
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::GlobalMap>> reader_;
  bool subscribed_ = false;
  std::mutex mutex_;
  std::condition_variable published_;
  std::set<std::pair<std::uint64_t, std::uint32_t>> seen_;  // (epoch, contributing node)
  bool over_ = false;                                        // the stream ended
  std::future<grpc::Status> reading_;
};

}  // namespace fogmap::test_support
