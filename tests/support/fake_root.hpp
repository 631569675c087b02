#pragma once
// A fake root on 127.0.0.1: a real gRPC GlobalMapService that writes the global maps a test gives
// it to its subscriber, as the root publishes them. What the tracker's feed and fogctl view are
// tested against, across the root's restarts.
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/proto_convert.hpp"

namespace fogmap::test_support {

class FakeRoot final : public v1::GlobalMapService::Service {
 public:
  grpc::Status Subscribe(grpc::ServerContext* context, const v1::SubscribeRequest* request,
                         grpc::ServerWriter<v1::GlobalMap>* writer) override {
    {
      std::lock_guard lock(mutex_);
      ++subscriptions_;
      asked_on_time_only_ = asked_on_time_only_ || request->on_time_only();
      changed_.notify_all();
    }
    while (!context->IsCancelled()) {
      std::unique_lock lock(mutex_);
      changed_.wait_for(lock, std::chrono::milliseconds(20), [&] { return !pending_.empty() || closing_; });
      if (closing_) break;
      if (pending_.empty()) continue;
      const v1::GlobalMap next = pending_.front();
      pending_.erase(pending_.begin());
      lock.unlock();
      if (!writer->Write(next)) break;
    }
    return grpc::Status::OK;
  }
  // Queued for the subscriber (the one that reads first takes it).
  void send(const GlobalMapMessage& g) { sendProto(toProto(g)); }
  void sendProto(v1::GlobalMap message) {
    std::lock_guard lock(mutex_);
    pending_.push_back(std::move(message));
    changed_.notify_all();
  }
  bool waitForSubscriptions(int n, std::chrono::seconds within = std::chrono::seconds(10)) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, within, [&] { return subscriptions_ >= n; });
  }
  // Whether any subscriber asked for on-time maps only.
  bool askedOnTimeOnly() {
    std::lock_guard lock(mutex_);
    return asked_on_time_only_;
  }
  // Ends every open stream (OK), as a root that shuts down does.
  void close() {
    std::lock_guard lock(mutex_);
    closing_ = true;
    changed_.notify_all();
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<v1::GlobalMap> pending_;
  int subscriptions_ = 0;
  bool asked_on_time_only_ = false;
  bool closing_ = false;
};

// Serves `root` on 127.0.0.1:port (0: a free port, written back to `port`).
inline std::unique_ptr<grpc::Server> serveFakeRoot(FakeRoot& root, int& port) {
  grpc::ServerBuilder builder;
  builder.AddListeningPort("127.0.0.1:" + std::to_string(port), grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&root);
  return builder.BuildAndStart();
}

}  // namespace fogmap::test_support
