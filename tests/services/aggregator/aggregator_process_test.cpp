// The merge-aggregator process as its main composes it (AggregatorProcess served by
// serveUntilStopped), in the test's own process over real gRPC on loopback: on the stop request
// a root publishes every upload it answered APPLIED before it ends its subscribers' streams, and
// an intermediate flushes every one to its parent before it exits 0.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <future>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>

#include <grpcpp/grpcpp.h>

#include "common/base/clock.hpp"
#include "common/config/topology_presets.hpp"
#include "services/common/proto_convert.hpp"
#include "services/common/service_main.hpp"
#include "services/merge_aggregator/aggregator_process.hpp"
#include "tests/support/free_ports.hpp"
#include "tests/support/served_aggregator.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
using test_support::GlobalMapWatcher;
using test_support::ServedAggregator;

constexpr auto kProcessRpcTimeout = 30s;  // bounds a call only so that a broken process fails the test

using test_support::kittiSequenceDir;

// `node`'s map of one ellipsoid for the epoch now.
v1::Upload mapNow(const TopologyConfig& topology, std::uint32_t node, std::uint64_t sequence) {
  const std::int64_t now_ns = systemNowNs();
  const auto period_ns = static_cast<std::int64_t>(topology.period_ms * 1e6);
  Ellipsoid e;
  e.id = {node, static_cast<std::uint64_t>(now_ns / period_ns), 0};
  e.center = Eigen::Vector3d(1, 2, 1);
  e.shape = Eigen::Matrix3d::Identity() * 0.25;
  e.point_count = 20;
  MapMessage map;
  map.header.node = node;
  map.header.epoch = static_cast<std::uint64_t>(now_ns / period_ns);
  map.header.sensor_time_ns = now_ns;
  map.header.contributing_nodes = {node};
  map.map = localMap({e});
  v1::Upload upload;
  *upload.mutable_map() = toProto(map);
  upload.set_sequence(sequence);
  return upload;
}

// Pushes `upload` as its node would; its epoch when it was answered APPLIED or LATE.
std::optional<std::uint64_t> pushAnswered(const std::shared_ptr<grpc::Channel>& channel, const v1::Upload& upload) {
  auto stub = v1::MapIngest::NewStub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + kProcessRpcTimeout);
  context.set_wait_for_ready(true);
  auto stream = stub->Push(&context);
  v1::Ack ack;
  if (!stream->Write(upload) || !stream->Read(&ack)) return std::nullopt;
  stream->WritesDone();
  (void)stream->Finish();
  const bool merged = ack.status() == v1::ACK_STATUS_APPLIED || ack.status() == v1::ACK_STATUS_LATE;
  EXPECT_TRUE(merged) << v1::AckStatus_Name(ack.status()) << " " << ack.reason();
  return merged ? std::optional<std::uint64_t>(upload.map().header().epoch()) : std::nullopt;
}

TopologyConfig withFreePorts(TopologyConfig topology) {
  test_support::useFreePorts(topology);
  return topology;
}

TEST(AggregatorProcess, ARootPublishesEveryUploadItAppliedBeforeItEndsItsSubscribersStreamsAndExitsZero) {
  // Two edges, one of them silent: the epoch waits for its deadline, so only the drain publishes
  // it when the stop comes first.
  const TopologyConfig topology = withFreePorts(makeStarTopology(2, kittiSequenceDir(), 0));
  const std::uint32_t edge = topology.find("edge-1")->id;
  ServedAggregator root(topology, "sink");
  GlobalMapWatcher watcher(root.channel());
  ASSERT_TRUE(watcher.subscribed());
  const auto channel = root.channel();
  const auto applied = pushAnswered(channel, mapNow(topology, edge, 1));
  ASSERT_TRUE(applied);
  EXPECT_EQ(root.stop(), 0);
  const grpc::Status end = watcher.ended();
  EXPECT_EQ(end.error_code(), grpc::StatusCode::UNAVAILABLE) << "the root ends its subscribers itself";
  EXPECT_TRUE(watcher.saw(*applied, edge)) << "an upload answered APPLIED was not published";
}

TEST(AggregatorProcess, AnIntermediateFlushesWhatItAppliedToItsParentBeforeItExitsZero) {
  // sink <- agg-1 <- edge-1, edge-2; sink <- agg-2 <- edge-3, edge-4.
  const TopologyConfig topology = withFreePorts(makeTreeTopology(4, kittiSequenceDir(), 0));
  const std::uint32_t edge = topology.find("edge-1")->id;
  ServedAggregator sink(topology, "sink");
  GlobalMapWatcher watcher(sink.channel());
  ASSERT_TRUE(watcher.subscribed());
  std::optional<std::uint64_t> applied;
  {
    ServedAggregator intermediate(topology, "agg-1");
    const auto channel = intermediate.channel();
    applied = pushAnswered(channel, mapNow(topology, edge, 1));
    ASSERT_TRUE(applied);
    EXPECT_EQ(intermediate.stop(), 0);
  }
  // The sink publishes what agg-1 flushed to it, at the epoch's deadline or in its own drain.
  EXPECT_EQ(sink.stop(), 0);
  EXPECT_EQ(watcher.ended().error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_TRUE(watcher.saw(*applied, edge)) << "agg-1 answered APPLIED but never delivered it to the sink";
}

}  // namespace
}  // namespace fogmap
