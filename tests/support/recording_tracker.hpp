#pragma once
// A stand-in tracker for tests of what sends detections or centroids: TrackerService.PushDetections
// and PushCentroids on a real gRPC server on 127.0.0.1, recording every frame it receives (through
// the conversion a tracker uses).
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"

namespace fogmap::test_support {

// The tracker's side of PushDetections, recording every frame it receives (through the same
// conversion a tracker uses) and how each stream ended.
class RecordingTracker final : public v1::TrackerService::Service {
 public:
  grpc::Status PushDetections(grpc::ServerContext* /*context*/, grpc::ServerReader<v1::DetectionFrame>* reader,
                              v1::DetectionSummary* summary) override {
    v1::DetectionFrame message;
    std::uint64_t received = 0;
    while (reader->Read(&message)) {
      Expected<tracking::DetectionFrame> frame = fromProto(message);
      {
        std::lock_guard lock(mu_);
        if (frame) {
          frames_.push_back(std::move(*frame));
        } else {
          errors_.push_back(frame.error().message);
        }
      }
      ++received;
      cv_.notify_all();
    }
    summary->set_received(received);
    {
      std::lock_guard lock(mu_);
      ++streams_ended_;
    }
    cv_.notify_all();
    return grpc::Status::OK;
  }

  grpc::Status PushCentroids(grpc::ServerContext* /*context*/, grpc::ServerReader<v1::CentroidFrame>* reader,
                             v1::CentroidSummary* summary) override {
    v1::CentroidFrame message;
    std::uint64_t received = 0;
    while (reader->Read(&message)) {
      Expected<tracking::CentroidFrame> frame = fromProto(message);
      {
        std::lock_guard lock(mu_);
        if (frame) {
          centroid_frames_.push_back(std::move(*frame));
        } else {
          errors_.push_back(frame.error().message);
        }
      }
      ++received;
      cv_.notify_all();
    }
    summary->set_received(received);
    {
      std::lock_guard lock(mu_);
      ++streams_ended_;
    }
    cv_.notify_all();
    return grpc::Status::OK;
  }

  // Waits until `n` frames have arrived; bounded.
  bool waitFrames(std::size_t n, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, timeout, [&] { return frames_.size() >= n; });
  }
  bool waitStreamsEnded(int n, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, timeout, [&] { return streams_ended_ >= n; });
  }
  std::vector<tracking::DetectionFrame> frames() const {
    std::lock_guard lock(mu_);
    return frames_;
  }
  bool waitCentroidFrames(std::size_t n, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    std::unique_lock lock(mu_);
    return cv_.wait_for(lock, timeout, [&] { return centroid_frames_.size() >= n; });
  }
  std::vector<tracking::CentroidFrame> centroidFrames() const {
    std::lock_guard lock(mu_);
    return centroid_frames_;
  }
  std::vector<std::string> errors() const {
    std::lock_guard lock(mu_);
    return errors_;
  }

 private:
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::vector<tracking::DetectionFrame> frames_;
  std::vector<tracking::CentroidFrame> centroid_frames_;
  std::vector<std::string> errors_;
  int streams_ended_ = 0;
};

// A real gRPC server on 127.0.0.1; port 0 picks a free port.
class TestTracker {
 public:
  explicit TestTracker(RecordingTracker& service, int port = 0) {
    grpc::ServerBuilder builder;
    configureServer(builder, 64U << 20);
    builder.AddListeningPort("127.0.0.1:" + std::to_string(port), grpc::InsecureServerCredentials(), &port_);
    builder.RegisterService(&service);
    server_ = builder.BuildAndStart();
  }
  ~TestTracker() { stop(); }
  bool started() const { return server_ != nullptr && port_ > 0; }
  int port() const { return port_; }
  std::string target() const { return "127.0.0.1:" + std::to_string(port_); }
  // Cancels open streams at once: a PushDetections handler would otherwise keep Shutdown waiting.
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

}  // namespace fogmap::test_support
