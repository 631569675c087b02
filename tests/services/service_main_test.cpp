// The one way a service process starts and stops: its command line, topology, node, TLS and
// metrics checked before the service runs (configuration errors exit 2, the outside world 1); a
// gRPC service served until the stop request and stopped in its one order within its budget; the
// upload link's observers every process shares.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "common/config/topology_presets.hpp"
#include "common/config/topology_yaml.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/service_main.hpp"
#include "tests/support/free_ports.hpp"
#include "tests/support/metric_values.hpp"
#include "tests/support/scratch_dir.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
using test_support::counterValue;

// What a file descriptor (1: stdout, 2: stderr) received while this lives.
class Captured {
 public:
  explicit Captured(int fd) : fd_(fd), file_(std::tmpfile()) {
    std::fflush(nullptr);
    saved_ = ::dup(fd_);
    ::dup2(::fileno(file_), fd_);
  }
  ~Captured() { restore(); }
  std::string text() {
    restore();
    std::rewind(file_);
    std::string out;
    for (int c = std::fgetc(file_); c != EOF; c = std::fgetc(file_)) out.push_back(static_cast<char>(c));
    return out;
  }

 private:
  void restore() {
    if (saved_ < 0) return;
    std::cout.flush();
    std::cerr.flush();
    std::fflush(nullptr);
    ::dup2(saved_, fd_);
    ::close(saved_);
    saved_ = -1;
  }
  int fd_;
  std::FILE* file_;
  int saved_ = -1;
};

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// A star of one edge under "sink" on free ports, written to a file.
class TopologyFile {
 public:
  TopologyFile() : dir_("service-main") {
    topology_ = makeStarTopology(1, std::filesystem::path(FOGMAP_SOURCE_DIR) / "data" / "kitti_raw_seq_a", 0);
    test_support::useFreePorts(topology_);
    path_ = dir_.path() / "star.yaml";
    std::ofstream(path_) << toYaml(topology_);
  }
  std::string path() const { return path_.string(); }
  const TopologyConfig& topology() const { return topology_; }

 private:
  test_support::ScratchDir dir_;
  TopologyConfig topology_;
  std::filesystem::path path_;
};

const ServiceSpec kAggregatorSpec{Role::kAggregator, "usage: merge-aggregator --topology FILE --node NAME\n"};
const ServiceSpec kEdgeSpec{
    Role::kEdge, "usage: edge-cluster --topology FILE --node NAME [--journal FILE]\n", {"journal"}};

struct RunOutcome {
  int code = -1;
  std::string out;
  std::string err;
};

RunOutcome runWith(const ServiceSpec& spec, std::vector<std::string> words,
                   const std::function<int(ServiceContext&)>& run = [](ServiceContext&) { return 0; }) {
  words.insert(words.begin(), serviceName(spec.role));
  std::vector<char*> argv;
  for (auto& w : words) argv.push_back(w.data());
  Captured out(1);
  Captured err(2);
  RunOutcome o;
  o.code = runService(static_cast<int>(argv.size()), argv.data(), spec, run);
  o.out = out.text();
  o.err = err.text();
  return o;
}

TEST(RunService, HelpPrintsTheUsageAndAWrongCommandLineIsAConfigurationError) {
  const RunOutcome help = runWith(kAggregatorSpec, {"--help"});
  EXPECT_EQ(help.code, 0);
  EXPECT_EQ(help.out, kAggregatorSpec.usage);
  const RunOutcome wrong = runWith(kAggregatorSpec, {"--topology", "t.yaml"});
  EXPECT_EQ(wrong.code, kExitBadConfig);
  EXPECT_TRUE(contains(wrong.err, "merge-aggregator: --topology FILE and --node NAME are required")) << wrong.err;
  EXPECT_TRUE(contains(wrong.err, kAggregatorSpec.usage)) << wrong.err;
  EXPECT_EQ(runWith(kAggregatorSpec, {"--topology", "t.yaml", "--node", "sink", "--journal", "j"}).code, kExitBadConfig)
      << "--journal is the edge's flag";
}

TEST(RunService, AMissingFileNodeOrRoleIsAConfigurationErrorNamingIt) {
  const TopologyFile file;
  RunOutcome o = runWith(kAggregatorSpec, {"--topology", file.path() + ".missing", "--node", "sink"});
  EXPECT_EQ(o.code, kExitBadConfig);
  EXPECT_TRUE(contains(o.err, "star.yaml.missing")) << o.err;
  o = runWith(kAggregatorSpec, {"--topology", file.path(), "--node", "nobody"});
  EXPECT_EQ(o.code, kExitBadConfig);
  EXPECT_TRUE(contains(o.err, "merge-aggregator: no node 'nobody' in " + file.path())) << o.err;
  o = runWith(kAggregatorSpec, {"--topology", file.path(), "--node", "edge-1"});
  EXPECT_EQ(o.code, kExitBadConfig);
  EXPECT_TRUE(contains(o.err, "has no aggregator named 'edge-1' (it is edge)")) << o.err;
}

TEST(RunService, TheServiceRunsWithItsNodeFlagsAndMetricsAndItsExitCodeIsTheProcesss) {
  const TopologyFile file;
  const NodeConfig& edge = *file.topology().find("edge-1");
  bool ran = false;
  const RunOutcome o = runWith(kEdgeSpec, {"--node", "edge-1", "--topology", file.path(), "--journal", "j.log"},
                               [&](ServiceContext& context) {
                                 ran = true;
                                 EXPECT_EQ(context.node.name, "edge-1");
                                 EXPECT_EQ(context.topology_file, file.path());
                                 EXPECT_EQ(context.flag("journal"), std::optional<std::string>("j.log"));
                                 EXPECT_FALSE(context.flag("other"));
                                 EXPECT_FALSE(context.tls) << "no tls section: plaintext";
                                 EXPECT_EQ(context.prefix(), "edge-cluster edge-1: ");
                                 EXPECT_EQ(context.metrics.listeningPort(), 0) << "not before its parts are checked";
                                 context.serveMetrics();
                                 EXPECT_EQ(context.metrics.listeningPort(), edge.metrics_port);
                                 EXPECT_FALSE(context.stop.requested());
                                 return 42;
                               });
  EXPECT_TRUE(ran);
  EXPECT_EQ(o.code, 42);
}

TEST(RunService, TheOutsideWorldFailingIsARuntimeError) {
  const TopologyFile file;
  const NodeConfig& sink = *file.topology().root();
  RunOutcome o = runWith(kAggregatorSpec, {"--topology", file.path(), "--node", "sink"},
                         [](ServiceContext&) -> int { throw std::runtime_error("the world ended"); });
  EXPECT_EQ(o.code, kExitRuntimeError);
  EXPECT_TRUE(contains(o.err, "merge-aggregator: the world ended")) << o.err;
  // Its metrics port taken: the service's parts are built, and nothing serves past the port.
  Metrics taken(endpoint(sink.host, sink.metrics_port), "merge-aggregator", "sink");
  bool served = false;
  o = runWith(kAggregatorSpec, {"--topology", file.path(), "--node", "sink"}, [&](ServiceContext& context) {
    context.serveMetrics();
    served = true;
    return 0;
  });
  EXPECT_EQ(o.code, kExitRuntimeError);
  EXPECT_FALSE(served);
  EXPECT_TRUE(contains(o.err, "cannot serve /metrics")) << o.err;
}

// A hand-made context for serveUntilStopped: node "sink" on 127.0.0.1, gRPC port `port` (0: any).
struct Context {
  explicit Context(std::uint16_t port) {
    node.name = "sink";
    node.role = Role::kAggregator;
    node.port = port;
    topology.nodes.push_back(node);
  }
  ServiceContext get() {
    return ServiceContext{kAggregatorSpec, file, topology, topology.nodes.front(), tls, flags, stop, metrics};
  }
  std::filesystem::path file = "star.yaml";
  TopologyConfig topology;
  NodeConfig node;
  std::optional<TlsPem> tls;
  std::map<std::string, std::string> flags;
  StopRequest stop;
  Metrics metrics{"", "merge-aggregator", "sink"};
};

// Each step of a lifecycle as it was called, with the budget it got.
struct Steps {
  ServiceLifecycle lifecycle(std::promise<int>& serving) {
    ServiceLifecycle l;
    l.serving = [this, &serving](int port) {
      note("serving", 0ms);
      serving.set_value(port);
    };
    l.stop_accepting = [this] { note("stop_accepting", 0ms); };
    l.drain = [this] { note("drain", 0ms); };
    l.end_subscriptions = [this](std::chrono::milliseconds budget) { note("end_subscriptions", budget); };
    l.flush = [this](std::chrono::milliseconds budget) { note("flush", budget); };
    return l;
  }
  void note(const std::string& step, std::chrono::milliseconds budget) {
    std::lock_guard lock(mutex);
    order.push_back(step);
    budgets[step] = budget;
  }
  std::mutex mutex;
  std::vector<std::string> order;
  std::map<std::string, std::chrono::milliseconds> budgets;
};

TEST(ServeUntilStopped, ServesUntilTheStopThenStopsInItsOrderWithinItsBudgetAndExitsZero) {
  Context context(0);
  v1::MapIngest::Service ingest;  // any service: every call unimplemented
  Steps steps;
  std::promise<int> serving;
  const ShutdownBudget budget{1h, 500ms, 500ms, 250ms};
  auto served = std::async(std::launch::async, [&] {
    return serveUntilStopped(context.get(), {&ingest}, steps.lifecycle(serving), budget);
  });
  const int port = serving.get_future().get();
  ASSERT_GT(port, 0);
  const auto channel = makeChannel(endpoint("127.0.0.1", port), 4U << 20);
  EXPECT_TRUE(channel->WaitForConnected(std::chrono::system_clock::now() + 30s)) << "serving";
  {
    std::lock_guard lock(steps.mutex);
    EXPECT_EQ(steps.order, (std::vector<std::string>{"serving"})) << "nothing stops before the request";
  }
  context.stop.request();
  EXPECT_EQ(served.get(), 0);
  EXPECT_EQ(steps.order,
            (std::vector<std::string>{"serving", "stop_accepting", "drain", "end_subscriptions", "flush"}));
  EXPECT_EQ(steps.budgets["end_subscriptions"], 500ms);
  EXPECT_LE(steps.budgets["flush"], 1h - 250ms) << "the teardown is kept";
  EXPECT_GT(steps.budgets["flush"], 0ms);
}

TEST(ServeUntilStopped, ADeadlineAlreadyPassedLeavesEveryStepNoTime) {
  Context context(0);
  v1::MapIngest::Service ingest;
  Steps steps;
  std::promise<int> serving;
  context.stop.request();  // before serving: the deadline counts from the request
  const ShutdownBudget none_left{0ms, 500ms, 500ms, 250ms};
  EXPECT_EQ(serveUntilStopped(context.get(), {&ingest}, steps.lifecycle(serving), none_left), 0);
  EXPECT_EQ(steps.order.size(), 5U);
  EXPECT_EQ(steps.budgets["end_subscriptions"], 0ms);
  EXPECT_EQ(steps.budgets["flush"], 0ms);
}

TEST(ServeUntilStopped, AnAddressTakenIsARuntimeErrorAndNothingRuns) {
  // A listener without SO_REUSEPORT: gRPC cannot share its port.
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof addr;
  ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  ASSERT_EQ(::listen(fd, 1), 0);
  ASSERT_EQ(::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len), 0);
  Context context(ntohs(addr.sin_port));
  v1::MapIngest::Service ingest;
  Steps steps;
  std::promise<int> serving;
  Captured err(2);
  EXPECT_EQ(serveUntilStopped(context.get(), {&ingest}, steps.lifecycle(serving)), kExitRuntimeError);
  const std::string text = err.text();
  ::close(fd);
  EXPECT_TRUE(contains(text, "merge-aggregator: cannot listen on 127.0.0.1:" + std::to_string(ntohs(addr.sin_port))))
      << text;
  EXPECT_TRUE(steps.order.empty());
}

TEST(ServiceContext, TheParentLinksObserversCountInTheMetricsAndLogWhatAPersonMustKnow) {
  Context context(0);
  const ServiceContext c = context.get();
  NodeConfig parent;
  parent.name = "agg-1";
  parent.host = "127.0.0.2";
  parent.port = 7001;
  const auto link = c.linkTo<ParentLinkConfig>(parent);
  EXPECT_EQ(link.target, "127.0.0.2:7001");
  EXPECT_EQ(link.max_message_bytes, context.topology.max_message_bytes);
  EXPECT_TRUE(link.credentials) << "channelCredentials of the node's identity (plaintext here)";
  const ParentLinkHooks hooks = c.parentLinkHooks(parent);
  Captured err(2);
  hooks.on_sent("map", 100);
  hooks.on_reconnect();
  hooks.on_stalled(2000ms);
  hooks.on_dropped(1, true);
  hooks.on_dropped(2, false);
  hooks.on_refused(17, "clock_skew: too old");
  const std::string text = err.text();
  EXPECT_EQ(counterValue(context.metrics, "fogmap_bytes_sent_total", "peer", "agg-1"), 100.0);
  EXPECT_EQ(counterValue(context.metrics, "fogmap_reconnects_total", "node", "sink"), 1.0);
  EXPECT_EQ(counterValue(context.metrics, "fogmap_link_stalls_total", "node", "sink"), 1.0);
  EXPECT_EQ(counterValue(context.metrics, "fogmap_dropped_uploads_total", "node", "sink"), 2.0);
  EXPECT_EQ(counterValue(context.metrics, "fogmap_uploads_refused_by_parent_total", "node", "sink"), 1.0);
  EXPECT_EQ(text,
            "merge-aggregator sink: the parent has owed an answer for 2000 ms; re-opening the stream\n"
            "merge-aggregator sink: the send queue to the parent is full; dropping the oldest uploads (1 dropped so "
            "far)\n"
            "merge-aggregator sink: the parent refused upload 17: clock_skew: too old\n");
}

}  // namespace
}  // namespace fogmap
