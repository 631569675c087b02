// The edge-cluster process as its main composes it (EdgeProcess), in the test's own process: what
// its node must be, and a replay shipped to a root (served in-process on loopback) until the stop
// request, after which it flushes and exits 0.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <future>
#include <string>

#include "common/config/topology_presets.hpp"
#include "services/edge_cluster/edge_process.hpp"
#include "tests/support/free_ports.hpp"
#include "tests/support/served_aggregator.hpp"
#include "tests/support/service_context.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap {
namespace {

using test_support::GlobalMapWatcher;
using test_support::HandMadeContext;
using test_support::ServedAggregator;

using test_support::kittiSequenceDir;

TopologyConfig star() {
  TopologyConfig topology = makeStarTopology(1, kittiSequenceDir(), 0);
  test_support::useFreePorts(topology);
  return topology;
}

std::string refusal(TopologyConfig topology) {
  HandMadeContext edge(std::move(topology), "edge-1");
  const auto process = EdgeProcess::create(edge.context());
  return process ? std::string("created") : process.error().message;
}

TEST(EdgeProcess, AnEdgeWithoutAParentOrWithoutAPositiveRateIsRefusedNamingIt) {
  TopologyConfig orphan = star();
  for (auto& node : orphan.nodes) {
    if (node.name == "edge-1") node.parent.clear();
  }
  EXPECT_EQ(refusal(orphan), "edge 'edge-1' has no parent aggregator to send to");
  TopologyConfig still = star();
  for (auto& node : still.nodes) {
    if (node.name == "edge-1") node.sensor->rate_hz = 0.0;
  }
  EXPECT_EQ(refusal(still), "edge 'edge-1': rate_hz must be positive");
  TopologyConfig missing = star();
  for (auto& node : missing.nodes) {
    if (node.name == "edge-1") node.sensor->source = kittiSequenceDir() / "no-such-scans";
  }
  EXPECT_NE(refusal(missing).find("no-such-scans"), std::string::npos) << refusal(missing);
}

TEST(EdgeProcess, AnEdgeWhoseClassifierModelIsMissingStopsAtStartUpNamingTheFile) {
  TopologyConfig topology = star();
  topology.objects.boxes = true;
  topology.objects.classifier = kittiSequenceDir() / "no-such-model.yml.gz";
  const std::string message = refusal(topology);
  EXPECT_NE(message.find("edge 'edge-1'"), std::string::npos) << message;
  EXPECT_NE(message.find("no-such-model.yml.gz"), std::string::npos) << message;
  topology.objects.classifier = std::filesystem::path(FOGMAP_SOURCE_DIR) / "data" / "models" / "lidar_classifier.yml.gz";
  EXPECT_EQ(refusal(topology), "created");
}

TEST(EdgeProcess, ShipsItsEpochsToItsParentUntilTheStopThenFlushesAndExitsZero) {
  const TopologyConfig topology = star();
  ServedAggregator root(topology, "sink");
  GlobalMapWatcher watcher(root.channel());
  ASSERT_TRUE(watcher.subscribed());
  HandMadeContext edge(topology, "edge-1");
  auto process = EdgeProcess::create(edge.context());
  ASSERT_TRUE(process.ok()) << process.error().message;
  auto exit = std::async(std::launch::async, [&] { return (*process)->run(); });
  EXPECT_TRUE(watcher.waitForContribution(edge.node().id)) << "the root never published a map of the edge";
  edge.stop().request();  // as SIGTERM would
  EXPECT_EQ(exit.get(), 0);
  EXPECT_EQ(root.stop(), 0);
}

}  // namespace
}  // namespace fogmap
