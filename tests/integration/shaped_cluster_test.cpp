// Whole clusters whose edges run behind shaped links (harness/shaped_links.hpp), each edge in its
// own network namespace, as real processes: they publish complete epochs. As root; skipped with the
// reason where shaped links cannot be made. The links themselves: tests/harness/shaped_links_test.cpp.
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include "common/config/topology.hpp"
#include "common/config/topology_presets.hpp"
#include "common/config/topology_yaml.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "harness/launcher.hpp"
#include "harness/shaped_links.hpp"
#include "services/common/endpoint.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "tests/support/free_ports.hpp"
#include "tests/support/shaping.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using harness::NetnsLink;
using harness::ShapedLinks;

using test_support::kittiSequenceDir;
constexpr double kRateMbitPerS = test_support::kShapedRateMbitPerS;

// ---- whole clusters behind shaped links ----

// A Subscribe call to the root: the global maps as it publishes them.
class CompleteMapSubscription {
 public:
  CompleteMapSubscription(const std::string& target, std::size_t max_message_bytes)
      : stub_(v1::GlobalMapService::NewStub(makeChannel(target, max_message_bytes))) {
    context_.set_deadline(std::chrono::system_clock::now() + 20s);
    v1::SubscribeRequest request;
    request.set_on_time_only(true);
    reader_ = stub_->Subscribe(&context_, request);
  }
  ~CompleteMapSubscription() { context_.TryCancel(); }
  // Reads global maps until `wanted` of them miss no sensor; how many did before the stream ended.
  int completeMaps(int wanted) {
    int complete = 0;
    v1::GlobalMap message;
    while (complete < wanted && reader_->Read(&message)) {
      const auto global = fromProto(message);
      if (global.ok() && global->header.missing_nodes.empty()) ++complete;
    }
    return complete;
  }

 private:
  std::unique_ptr<v1::GlobalMapService::Stub> stub_;
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::GlobalMap>> reader_;
};

TopologyConfig withFreePorts(TopologyConfig t) {
  test_support::useFreePorts(t);
  t.deadline_ms = 500.0;  // generous: a loaded CI machine must not turn slow epochs into partial ones
  return t;
}

// The inode of a network namespace: a process is inside the namespace when its /proc/PID/ns/net
// names the same one as /var/run/netns/NAME.
ino_t namespaceInode(const fs::path& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? st.st_ino : 0;
}

// Starts the shaped topology as real processes, each edge under its prefix, checks that every edge
// runs in its own namespace, and reads complete global maps from the root.
void expectCompleteEpochsThroughShapedLinks(const ShapedLinks& shaped) {
  const TopologyConfig& t = shaped.topology();
  const auto state = fs::temp_directory_path() / ("fogmap-shaped-" + std::to_string(::getpid()) + "-" + t.name);
  fs::remove_all(state);
  fs::create_directories(state);
  const auto file = state / (t.name + ".yaml");
  std::ofstream(file) << toYaml(t);
  harness::StartOptions options;
  options.prefixes = shaped.prefixes();
  // Ready means each edge's /metrics answered on its namespace address: the host reaches it over the pair.
  auto cluster = harness::startCluster(file, t, state, 30s, options);
  ASSERT_TRUE(cluster) << cluster.error().message;
  for (const harness::RunningNode& node : cluster->nodes) {
    const NetnsLink* link = shaped.link(node.name);
    const ino_t inode = namespaceInode("/proc/" + std::to_string(node.pid) + "/ns/net");
    if (link == nullptr) {
      EXPECT_EQ(inode, namespaceInode("/proc/self/ns/net")) << node.name << " is an aggregator: on the host";
    } else {
      EXPECT_EQ(inode, namespaceInode("/var/run/netns/" + link->name())) << node.name << " runs outside its namespace";
    }
  }
  const NodeConfig* root = t.root();
  CompleteMapSubscription watch(endpoint(root->host, root->port), t.max_message_bytes);
  EXPECT_EQ(watch.completeMaps(3), 3) << "the root published fewer than 3 complete epochs in 20 s; see " << state / "logs";
  harness::stopCluster(*cluster, 5s);
  fs::remove_all(state);
}

TEST(ShapedLinks, StarOfThreeEdgesEachInItsNamespacePublishesCompleteEpochs) {
  SKIP_UNLESS_SHAPING_IS_POSSIBLE();
  const TopologyConfig given = withFreePorts(makeStarTopology(3, kittiSequenceDir(), 40000));
  const auto shaped = ShapedLinks::create(given, kRateMbitPerS, static_cast<unsigned>(::getpid()));
  ASSERT_TRUE(shaped) << shaped.error().message;
  const TopologyConfig& t = shaped->topology();

  std::set<std::string> addresses;
  std::set<std::string> namespaces;
  for (const char* edge : {"edge-1", "edge-2", "edge-3"}) {
    const NetnsLink* link = shaped->link(edge);
    ASSERT_NE(link, nullptr) << edge;
    EXPECT_EQ(t.find(edge)->host, link->namespaceAddress());
    EXPECT_EQ(t.find(edge)->metrics_port, given.find(edge)->metrics_port);
    EXPECT_EQ(shaped->prefixes().at(edge), (std::vector<std::string>{harness::findProgram("ip"), "netns", "exec", link->name()}));
    EXPECT_EQ(link->namespaceAddress().rfind("10.213.", 0), 0U) << link->namespaceAddress();
    addresses.insert(link->namespaceAddress());
    addresses.insert(link->hostAddress());
    namespaces.insert(link->name());
  }
  EXPECT_EQ(addresses.size(), 6U);  // three pairs of their own
  EXPECT_EQ(namespaces.size(), 3U);
  EXPECT_EQ(shaped->prefixes().size(), 3U);  // the sink runs on the host
  EXPECT_EQ(t.find("sink")->host, shaped->link("edge-1")->hostAddress());
  EXPECT_EQ(t.find("sink")->port, given.find("sink")->port);
  EXPECT_EQ(shaped->link("sink"), nullptr);

  expectCompleteEpochsThroughShapedLinks(*shaped);
}

TEST(ShapedLinks, TreeOfFourEdgesKeepsAggregatorLinksOnTheHostAndPublishesCompleteEpochs) {
  SKIP_UNLESS_SHAPING_IS_POSSIBLE();
  // sink <- agg-1 <- edge-1, edge-2; sink <- agg-2 <- edge-3, edge-4.
  const TopologyConfig given = withFreePorts(makeTreeTopology(4, kittiSequenceDir(), 40000));
  ASSERT_EQ(given.find("edge-3")->parent, "agg-2");
  const auto shaped = ShapedLinks::create(given, kRateMbitPerS, static_cast<unsigned>(::getpid()));
  ASSERT_TRUE(shaped) << shaped.error().message;
  const TopologyConfig& t = shaped->topology();

  for (const char* edge : {"edge-1", "edge-2", "edge-3", "edge-4"}) {
    ASSERT_NE(shaped->link(edge), nullptr) << edge;
    EXPECT_EQ(t.find(edge)->host, shaped->link(edge)->namespaceAddress());
    EXPECT_EQ(shaped->prefixes().count(edge), 1U);
  }
  EXPECT_EQ(shaped->prefixes().size(), 4U);
  EXPECT_EQ(t.find("agg-1")->host, shaped->link("edge-1")->hostAddress());
  EXPECT_EQ(t.find("agg-2")->host, shaped->link("edge-3")->hostAddress());
  EXPECT_EQ(t.find("sink")->host, given.find("sink")->host);  // no edge children: stays where it was

  expectCompleteEpochsThroughShapedLinks(*shaped);
}

}  // namespace
}  // namespace fogmap
