// Integration: SIGTERM to real merge-aggregator and edge-cluster processes on 127.0.0.1 while the
// edges' streams, a raw uploading client and a subscriber are open. A node exits 0 within its
// shutdown deadline, and nothing it answered APPLIED is lost: the root publishes it before it
// goes, an intermediate flushes it to its parent, which publishes it.
#include <poll.h>
#include <signal.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/base/clock.hpp"
#include "common/base/epochs.hpp"
#include "common/config/topology_presets.hpp"
#include "common/config/topology_yaml.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "tests/support/free_ports.hpp"
#include "harness/launcher.hpp"
#include "tests/support/scratch_dir.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// The services' shutdown deadlines (merge-aggregator and edge-cluster main.cpp), with a margin for
// process exit on a loaded machine.
constexpr auto kAggregatorDeadline = 5s;
constexpr auto kEdgeDeadline = 1s + 50ms;  // the flush of unanswered uploads and the stop poll
constexpr auto kExitMargin = 1500ms;
constexpr std::uint32_t kFirstRawIndex = 1000;  // the raw client's ellipsoid indices (an edge's stay below)

using test_support::keptDir;
using test_support::kittiSequenceDir;

const harness::RunningNode& nodeNamed(const harness::Cluster& cluster, const std::string& name) {
  for (const auto& n : cluster.nodes) {
    if (n.name == name) return n;
  }
  throw std::runtime_error("no node " + name);
}

struct Exit {
  int status = 0;                    // waitpid's
  std::chrono::milliseconds after{};  // from the signal
};

// Sends SIGTERM and waits for the process to end (a pidfd becomes readable then), at most
// `timeout`; nullopt when it is still running.
std::optional<Exit> terminate(pid_t pid, std::chrono::milliseconds timeout) {
  const int fd = static_cast<int>(::syscall(SYS_pidfd_open, pid, 0));
  if (fd < 0) return std::nullopt;
  const auto signalled = Clock::now();
  ::kill(pid, SIGTERM);
  pollfd p{fd, POLLIN, 0};
  const int ready = ::poll(&p, 1, static_cast<int>(timeout.count()));
  const auto after = std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - signalled);
  ::close(fd);
  if (ready != 1) return std::nullopt;
  Exit exit;
  exit.after = after;
  if (::waitpid(pid, &exit.status, 0) != pid) return std::nullopt;
  return exit;
}

::testing::AssertionResult exitedCleanlyWithin(const std::optional<Exit>& exit, std::chrono::milliseconds deadline) {
  if (!exit) return ::testing::AssertionFailure() << "still running after its deadline and the margin";
  if (!WIFEXITED(exit->status) || WEXITSTATUS(exit->status) != 0) {
    return ::testing::AssertionFailure() << "ended with wait status " << exit->status;
  }
  if (exit->after > deadline) {
    return ::testing::AssertionFailure() << "exited " << exit->after.count() << " ms after SIGTERM, deadline "
                                         << deadline.count() << " ms";
  }
  return ::testing::AssertionSuccess();
}

// (epoch, ellipsoid index) of the raw client's ellipsoids.
using Mark = std::pair<std::uint64_t, std::uint32_t>;

// Subscribes to the root and records which of the raw client's ellipsoids each published global
// map holds (first publications and revisions), until the stream ends.
class Subscriber {
 public:
  Subscriber(const std::string& target, std::uint32_t raw_node) : raw_node_(raw_node) {
    channel_ = makeChannel(target, 256U << 20);
    stub_ = v1::GlobalMapService::NewStub(channel_);
    context_.set_deadline(std::chrono::system_clock::now() + 120s);
    thread_ = std::thread([this] { run(); });
  }
  ~Subscriber() {
    context_.TryCancel();
    if (thread_.joinable()) thread_.join();
  }

  // Blocks until `condition(epochs published, marks seen)` holds or the timeout passes.
  template <class F>
  bool waitFor(F condition, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, timeout, [&] { return condition(epochs_, seen_); });
  }
  std::set<Mark> seen() const {
    std::lock_guard lock(mutex_);
    return seen_;
  }
  // Blocks until the stream ended (the root ended it); its status.
  grpc::Status ended() {
    if (thread_.joinable()) thread_.join();
    return status_;
  }

 private:
  void run() {
    v1::SubscribeRequest request;  // every publication, revisions included
    auto reader = stub_->Subscribe(&context_, request);
    v1::GlobalMap map;
    while (reader->Read(&map)) {
      const auto global = fromProto(map);
      if (!global) continue;
      std::lock_guard lock(mutex_);
      epochs_.insert(global->header.epoch);
      for (const auto& object : global->map.objects) {
        for (const auto& e : object.ellipsoids) {
          if (e.id.node == raw_node_ && e.id.index >= kFirstRawIndex) seen_.insert({e.id.frame, e.id.index});
        }
      }
      changed_.notify_all();
    }
    status_ = reader->Finish();
    changed_.notify_all();
  }

  std::uint32_t raw_node_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::GlobalMapService::Stub> stub_;
  grpc::ClientContext context_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::set<std::uint64_t> epochs_;
  std::set<Mark> seen_;
  grpc::Status status_;
  std::thread thread_;
};

// A raw child: one stream that speaks for `node`, one map a few milliseconds (a fast sensor),
// each carrying one ellipsoid of its own index, written and answered in lock step until the stream
// ends. Records every answer. Each map is for the epoch after the current one (a clock a period
// ahead, well inside the admission window): an epoch is emitted as soon as every child reported,
// which the edges do a few milliseconds after it begins, so maps for the current epoch would mostly
// be answered LATE, and how many are APPLIED would depend on the machine's speed. An epoch that has
// not begun is never emitted before the drain, so every map is APPLIED while the node runs.
class RawChild {
 public:
  RawChild(const std::string& target, std::uint32_t node, const EpochSchedule& schedule)
      : node_(node), schedule_(schedule) {
    channel_ = makeChannel(target, 64U << 20);
    stub_ = v1::MapIngest::NewStub(channel_);
    context_.set_deadline(std::chrono::system_clock::now() + 120s);
    stream_ = stub_->Push(&context_);
    thread_ = std::thread([this] { run(); });
  }
  ~RawChild() {
    context_.TryCancel();
    if (thread_.joinable()) thread_.join();
  }

  // Blocks until `count` uploads were answered APPLIED (or the stream ended, or the timeout).
  bool waitForApplied(std::size_t count, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, timeout, [&] { return applied_.size() >= count || ended_; });
  }
  // Blocks until the stream ended; then what was answered APPLIED, and how many uploads were
  // answered otherwise or not at all, can be read.
  void join() { thread_.join(); }
  std::vector<Mark> applied() const {
    std::lock_guard lock(mutex_);
    return applied_;
  }
  std::size_t uploads() const {
    std::lock_guard lock(mutex_);
    return uploads_;
  }
  std::size_t unanswered() const {
    std::lock_guard lock(mutex_);
    return unanswered_;
  }
  std::size_t lateOrRefused() const {
    std::lock_guard lock(mutex_);
    return late_or_refused_;
  }
  std::string summary() const {
    std::lock_guard lock(mutex_);
    return std::to_string(uploads_) + " uploads: " + std::to_string(applied_.size()) + " applied, " +
           std::to_string(late_or_refused_) + " late or refused, " + std::to_string(unanswered_) + " unanswered";
  }

 private:
  void run() {
    constexpr std::size_t kMaxUploads = 20000;  // bounds the loop; the stream ends long before
    constexpr auto kPace = 5ms;
    auto next = Clock::now();
    for (std::uint64_t i = 0; i < kMaxUploads; ++i) {
      const std::uint64_t epoch = schedule_.epochAt(systemNowNs()) + 1;
      const auto index = static_cast<std::uint32_t>(kFirstRawIndex + i);
      Ellipsoid e;
      e.id = {node_, epoch, index};
      e.center = {5000.0 + static_cast<double>(i % 50) * 3.0, 0.0, 1.0};  // far from the scans' objects
      e.shape = Eigen::Matrix3d::Identity() * 0.25;
      e.point_count = 10;
      MapMessage message;
      message.header.node = node_;
      message.header.epoch = epoch;
      message.header.sensor_time_ns = systemNowNs();
      message.header.contributing_nodes = {node_};
      message.map = localMap({e});
      v1::Upload upload;
      upload.set_sequence(i + 1);
      *upload.mutable_map() = toProto(message);
      {
        std::lock_guard lock(mutex_);
        ++uploads_;
      }
      v1::Ack ack;
      if (!stream_->Write(upload) || !stream_->Read(&ack)) {
        std::lock_guard lock(mutex_);
        ++unanswered_;
        break;
      }
      {
        std::lock_guard lock(mutex_);
        if (ack.status() == v1::ACK_STATUS_APPLIED) {
          applied_.emplace_back(epoch, index);
        } else {
          ++late_or_refused_;  // not what this test follows
        }
      }
      changed_.notify_all();
      next += kPace;  // pacing like a sensor, not synchronisation
      std::this_thread::sleep_until(next);
    }
    (void)stream_->Finish();
    {
      std::lock_guard lock(mutex_);
      ended_ = true;
    }
    changed_.notify_all();
  }

  std::uint32_t node_;
  EpochSchedule schedule_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::MapIngest::Stub> stub_;
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::Upload, v1::Ack>> stream_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<Mark> applied_;
  std::size_t uploads_ = 0;
  std::size_t unanswered_ = 0;
  std::size_t late_or_refused_ = 0;
  bool ended_ = false;
  std::thread thread_;
};

TopologyConfig withFreePorts(TopologyConfig t, const std::string& name) {
  test_support::useFreePorts(t);
  t.name = name;
  t.deadline_ms = 500.0;  // a loaded machine must not turn slow epochs into partial ones
  for (auto& n : t.nodes) {
    if (n.sensor) n.sensor->frames = 100000;  // the test stops them
  }
  return t;
}

Expected<harness::Cluster> start(const TopologyConfig& t, const std::filesystem::path& dir) {
  const auto file = dir / (t.name + ".yaml");
  std::ofstream(file) << toYaml(t);
  return harness::startCluster(file, t, dir / t.name, 30s);
}

std::string target(const NodeConfig& node) { return endpoint(node.host, node.port); }

std::string missingMarks(const std::vector<Mark>& applied, const std::set<Mark>& seen) {
  std::string out;
  std::size_t missing = 0;
  for (const Mark& m : applied) {
    if (seen.contains(m)) continue;
    if (++missing <= 10) out += " (epoch " + std::to_string(m.first) + ", index " + std::to_string(m.second) + ")";
  }
  return std::to_string(missing) + " of " + std::to_string(applied.size()) + " missing:" + out;
}

TEST(Shutdown, RootExitsWithinItsDeadlineAndPublishesEveryAppliedUploadFirst) {
  const TopologyConfig t = withFreePorts(makeStarTopology(3, kittiSequenceDir(), 40000), "shutdown-star");
  const auto schedule = EpochSchedule::create(t.period_ms, t.deadline_ms);
  ASSERT_TRUE(schedule.ok());
  const auto dir = keptDir("shutdown-star");
  const auto cluster = start(t, dir);
  ASSERT_TRUE(cluster.ok()) << cluster.error().message;
  const NodeConfig& root = *t.root();
  std::optional<Exit> root_exit;
  std::size_t applied = 0;
  {
    Subscriber subscriber(target(root), 1);
    RawChild raw(target(root), 1, *schedule);  // speaks for edge 1, next to edge 1's own stream
    // Uploads applied and epochs published, then the signal: mid-stream for everyone.
    ASSERT_TRUE(raw.waitForApplied(200, 20s)) << raw.summary();
    ASSERT_TRUE(subscriber.waitFor([](const auto& epochs, const auto&) { return epochs.size() >= 3; }, 20s));
    root_exit = terminate(nodeNamed(*cluster, root.name).pid, kAggregatorDeadline + kExitMargin);
    raw.join();
    const grpc::Status end = subscriber.ended();
    EXPECT_EQ(end.error_code(), grpc::StatusCode::UNAVAILABLE) << "the root ends subscriptions itself: "
                                                               << end.error_message();
    const auto marks = raw.applied();
    applied = marks.size();
    const auto seen = subscriber.seen();
    const bool all_seen = std::all_of(marks.begin(), marks.end(), [&](const Mark& m) { return seen.contains(m); });
    EXPECT_TRUE(all_seen) << "uploads answered APPLIED but never published: " << missingMarks(marks, seen);
    std::printf("root: SIGTERM after %zu uploads (%zu applied, %zu late or refused, %zu unanswered); every applied "
                "upload published: %s; exited %lld ms after the signal\n",
                raw.uploads(), applied, raw.lateOrRefused(), raw.unanswered(), all_seen ? "yes" : "no",
                root_exit ? static_cast<long long>(root_exit->after.count()) : -1LL);
  }
  EXPECT_TRUE(exitedCleanlyWithin(root_exit, kAggregatorDeadline));
  EXPECT_GE(applied, 200U);
  harness::stopCluster(*cluster, 5000ms);
  if (!HasFailure()) std::filesystem::remove_all(dir);
}

TEST(Shutdown, EdgeExitsPromptlyAndAnIntermediateFlushesToItsParent) {
  // sink <- agg-1 <- edge-1, edge-2; sink <- agg-2 <- edge-3, edge-4.
  const TopologyConfig t = withFreePorts(makeTreeTopology(4, kittiSequenceDir(), 40000), "shutdown-tree");
  const auto schedule = EpochSchedule::create(t.period_ms, t.deadline_ms);
  ASSERT_TRUE(schedule.ok());
  const auto dir = keptDir("shutdown-tree");
  const auto cluster = start(t, dir);
  ASSERT_TRUE(cluster.ok()) << cluster.error().message;
  const NodeConfig* intermediate = t.find("agg-1");
  ASSERT_NE(intermediate, nullptr);
  std::optional<Exit> edge_exit;
  std::optional<Exit> intermediate_exit;
  {
    Subscriber subscriber(target(*t.root()), 1);
    RawChild raw(target(*intermediate), 1, *schedule);  // speaks for edge 1 at agg-1
    ASSERT_TRUE(raw.waitForApplied(200, 20s)) << raw.summary();
    ASSERT_TRUE(subscriber.waitFor([](const auto& epochs, const auto&) { return epochs.size() >= 3; }, 20s));

    edge_exit = terminate(nodeNamed(*cluster, "edge-2").pid, kEdgeDeadline + kExitMargin);
    intermediate_exit = terminate(nodeNamed(*cluster, intermediate->name).pid, kAggregatorDeadline + kExitMargin);
    raw.join();
    const auto marks = raw.applied();
    // The sink publishes what agg-1 flushed to it by the epochs' deadlines (as revisions when late).
    const bool all_seen = subscriber.waitFor(
        [&](const auto&, const auto& seen) {
          return std::all_of(marks.begin(), marks.end(), [&](const Mark& m) { return seen.contains(m); });
        },
        10s);
    EXPECT_TRUE(all_seen) << "uploads agg-1 answered APPLIED but the sink never published: "
                          << missingMarks(marks, subscriber.seen());
    std::printf("edge-2 exited %lld ms after SIGTERM; agg-1: SIGTERM after %zu uploads (%zu applied, %zu "
                "unanswered), exited %lld ms after the signal; every applied upload published by the sink: %s\n",
                edge_exit ? static_cast<long long>(edge_exit->after.count()) : -1LL, raw.uploads(), marks.size(),
                raw.unanswered(), intermediate_exit ? static_cast<long long>(intermediate_exit->after.count()) : -1LL,
                all_seen ? "yes" : "no");
  }
  EXPECT_TRUE(exitedCleanlyWithin(edge_exit, kEdgeDeadline)) << "edge-2";
  EXPECT_TRUE(exitedCleanlyWithin(intermediate_exit, kAggregatorDeadline)) << "agg-1";
  harness::stopCluster(*cluster, 5000ms);
  if (!HasFailure()) std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace fogmap
