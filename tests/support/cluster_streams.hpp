#pragma once
// What a test reads from a running cluster over gRPC: the root's global maps, recorded by sensor
// time in a thread of their own, and a tracker's track lists, read where the test scores them.
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "common/geometry/map.hpp"
#include "common/config/topology.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"

namespace fogmap::test_support {

// A channel to the node's gRPC port, with room for large maps.
inline std::shared_ptr<grpc::Channel> channelTo(const NodeConfig& node) {
  return makeChannel(endpoint(node.host, node.port), 64U << 20);
}

// A Subscribe call to the root's GlobalMapService (maps published on time only), read in a thread
// of its own, each map recorded by its sensor time: what the LiDARs saw, beside the tracks.
class GlobalMapRecorder {
 public:
  // Subscribes to `root`; the call ends after `timeout` at the latest.
  GlobalMapRecorder(const NodeConfig& root, std::chrono::milliseconds timeout)
      : stub_(v1::GlobalMapService::NewStub(channelTo(root))) {
    context_.set_deadline(std::chrono::system_clock::now() + timeout);
    v1::SubscribeRequest request;
    request.set_on_time_only(true);
    reader_ = stub_->Subscribe(&context_, request);
    thread_ = std::thread([this] { record(); });
  }
  ~GlobalMapRecorder() { stop(); }
  GlobalMapRecorder(const GlobalMapRecorder&) = delete;
  GlobalMapRecorder& operator=(const GlobalMapRecorder&) = delete;

  // The map of the global map with this sensor time, when one has arrived.
  std::optional<Map> find(std::int64_t sensor_time_ns) const {
    std::lock_guard lock(mutex_);
    const auto it = maps_.find(sensor_time_ns);
    if (it == maps_.end()) return std::nullopt;
    return it->second;
  }

  // Ends the call and waits for the reading thread; the maps recorded stay.
  void stop() {
    context_.TryCancel();
    if (thread_.joinable()) thread_.join();
  }

 private:
  void record() {
    v1::GlobalMap message;
    while (reader_->Read(&message)) {
      auto global = fromProto(message);
      if (!global) continue;
      std::lock_guard lock(mutex_);
      maps_[global->header.sensor_time_ns] = std::move(global->map);
    }
  }

  std::unique_ptr<v1::GlobalMapService::Stub> stub_;
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::GlobalMap>> reader_;
  mutable std::mutex mutex_;
  std::map<std::int64_t, Map> maps_;  // by sensor time
  std::thread thread_;
};

// A Subscribe call to a tracker's TrackerService: its track lists as it publishes them.
class TrackStream {
 public:
  // Subscribes to `tracker`; the call ends after `timeout` at the latest.
  TrackStream(const NodeConfig& tracker, std::chrono::milliseconds timeout)
      : stub_(v1::TrackerService::NewStub(channelTo(tracker))) {
    context_.set_deadline(std::chrono::system_clock::now() + timeout);
    reader_ = stub_->Subscribe(&context_, v1::TrackSubscribeRequest{});
  }
  ~TrackStream() { cancel(); }
  TrackStream(const TrackStream&) = delete;
  TrackStream& operator=(const TrackStream&) = delete;

  // The next track list into `list`; false once the stream has ended.
  bool read(v1::TrackList& list) { return reader_->Read(&list); }
  // Ends the call.
  void cancel() { context_.TryCancel(); }

 private:
  std::unique_ptr<v1::TrackerService::Stub> stub_;
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::TrackList>> reader_;
};

}  // namespace fogmap::test_support
