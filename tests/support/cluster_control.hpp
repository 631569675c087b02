#pragma once
// Pacing a cluster that harness::runCluster runs by what it does, not by the clock: wait for the root
// to publish a global map the test needs, and let the edges replay until the test stops them, so
// a run lasts as long as the test's part does, however slow the machine.
#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/io/messages.hpp"
#include "common/config/topology.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "harness/launcher.hpp"

namespace fogmap::test_support {

// A Subscribe call to the root: its global maps as it publishes them on time (what geofences see).
class RootSubscription {
 public:
  // Subscribes to the root of `topology`; the call ends after `timeout` at the latest.
  RootSubscription(const TopologyConfig& topology, std::chrono::milliseconds timeout)
      : stub_(v1::GlobalMapService::NewStub(
            makeChannel(endpoint(topology.root()->host, topology.root()->port), 64U << 20))) {
    context_.set_deadline(std::chrono::system_clock::now() + timeout);
    v1::SubscribeRequest request;
    request.set_on_time_only(true);
    reader_ = stub_->Subscribe(&context_, request);
  }
  ~RootSubscription() { context_.TryCancel(); }
  RootSubscription(const RootSubscription&) = delete;
  RootSubscription& operator=(const RootSubscription&) = delete;

  // Reads global maps until one satisfies `done` and returns it; nullopt when the call ended first.
  template <class Done>
  std::optional<GlobalMapMessage> readUntil(Done done) {
    v1::GlobalMap message;
    while (reader_->Read(&message)) {
      auto global = fromProto(message);
      if (global.ok() && done(*global)) return std::move(*global);
    }
    return std::nullopt;
  }

 private:
  std::unique_ptr<v1::GlobalMapService::Stub> stub_;
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::GlobalMap>> reader_;
};

// True for a global map every sensor of the topology contributed to.
inline bool everySensor(const TopologyConfig& topology, const GlobalMapMessage& global) {
  return global.header.contributing_nodes == topology.sensorsBelow(topology.root()->name);
}

// Lets every edge of the topology replay its scans in a loop, without a frame limit: the run then
// needs RunOptions::frames beyond any count and an EdgesStopper to end.
inline void replayUntilStopped(TopologyConfig& topology) {
  for (auto& n : topology.nodes) {
    if (!n.sensor) continue;
    n.sensor->frames.reset();
    n.sensor->loop = true;
  }
}

// Stops the cluster's edges when it goes out of scope, however the test's part ends (an assertion
// may end it early); harness::runCluster then ends once the root has published what they sent.
class EdgesStopper {
 public:
  EdgesStopper(const harness::Cluster& cluster, const TopologyConfig& topology) {
    for (const auto& n : cluster.nodes) {
      const NodeConfig* config = topology.find(n.name);
      if (config != nullptr && config->role == Role::kEdge) edges_.push_back(n);
    }
  }
  ~EdgesStopper() { harness::stopNodes(edges_, std::chrono::seconds(5)); }
  EdgesStopper(const EdgesStopper&) = delete;
  EdgesStopper& operator=(const EdgesStopper&) = delete;

 private:
  std::vector<harness::RunningNode> edges_;
};

}  // namespace fogmap::test_support
