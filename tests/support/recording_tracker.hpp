#pragma once
// A stand-in tracker for tests of what sends detections or centroids: TrackerService.PushDetections
// and PushCentroids on a real gRPC server on 127.0.0.1, recording every frame it receives (through
// the conversion a tracker uses).
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/proto_convert.hpp"
#include "tests/support/test_server.hpp"

namespace fogmap::test_support {

// The tracker's side of PushDetections and PushCentroids, recording every frame it receives
// (through the same conversion a tracker uses) and how each stream ended.
class RecordingTracker final : public v1::TrackerService::Service {
 public:
  grpc::Status PushDetections(grpc::ServerContext* /*context*/, grpc::ServerReader<v1::DetectionFrame>* reader,
                              v1::DetectionSummary* summary) override {
    return record(reader, frames_, summary);
  }

  grpc::Status PushCentroids(grpc::ServerContext* /*context*/, grpc::ServerReader<v1::CentroidFrame>* reader,
                             v1::CentroidSummary* summary) override {
    return record(reader, centroid_frames_, summary);
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
  // Reads a stream to its end: each frame converted and kept in `into` (or why not in errors_),
  // the count in the summary.
  template <class Message, class Frame, class Summary>
  grpc::Status record(grpc::ServerReader<Message>* reader, std::vector<Frame>& into, Summary* summary) {
    Message message;
    std::uint64_t received = 0;
    while (reader->Read(&message)) {
      Expected<Frame> frame = fromProto(message);
      {
        std::lock_guard lock(mu_);
        if (frame) {
          into.push_back(std::move(*frame));
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

  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::vector<tracking::DetectionFrame> frames_;
  std::vector<tracking::CentroidFrame> centroid_frames_;
  std::vector<std::string> errors_;
  int streams_ended_ = 0;
};

// The stand-in on a real gRPC server on 127.0.0.1; port 0 picks a free port.
using TestTracker = TestServer;

}  // namespace fogmap::test_support
