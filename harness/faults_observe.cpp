#include "harness/faults_observe.hpp"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <condition_variable>
#include <cstdlib>
#include <deque>
#include <fstream>
#include <limits>
#include <mutex>
#include <sstream>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "common/base/clock.hpp"
#include "common/base/epochs.hpp"
#include "common/certs/certs.hpp"
#include "common/config/topology_yaml.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "harness/cluster_run.hpp"
#include "harness/faults_oracle.hpp"
#include "harness/launcher.hpp"
#include "harness/netns.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"

namespace fogmap::harness {
namespace {

using namespace std::chrono_literals;
using SteadyClock = std::chrono::steady_clock;

constexpr std::chrono::milliseconds kTick{20};

// Everything the root published, judged as it arrives: the subscriber reads, a checker thread
// runs the oracle so that a slow check never makes the root drop maps for this subscriber.
class Observer {
 public:
  Observer(const TopologyConfig& topology, Oracle* oracle) : topology_(topology), oracle_(oracle) {}

  void start(const std::string& target, std::shared_ptr<grpc::ChannelCredentials> credentials) {
    subscriber_ = std::thread([this, target, credentials] { subscribe(target, credentials); });
    checker_ = std::thread([this] { check(); });
  }

  // Waits (bounded) until the root ends the stream, then stops the checker.
  void finish(std::chrono::milliseconds timeout) {
    {
      std::unique_lock lock(mu_);
      cv_.wait_for(lock, timeout, [&] { return stream_ended_; });
    }
    context_.TryCancel();
    subscriber_.join();
    {
      std::lock_guard lock(mu_);
      stopping_ = true;
    }
    cv_.notify_all();
    checker_.join();
  }

  bool subscribed() const {
    std::lock_guard lock(mu_);
    return subscribed_;
  }

  // Copies, for the harness thread while the run goes on (notice times) and at the end.
  std::vector<Publication> publications() const {
    std::lock_guard lock(mu_);
    return publications_;
  }
  std::map<std::uint64_t, EpochVerdict> verdicts() const {
    std::lock_guard lock(mu_);
    return verdicts_;
  }
  std::uint64_t checked() const {
    std::lock_guard lock(mu_);
    return checked_;
  }
  std::uint64_t mismatched() const {
    std::lock_guard lock(mu_);
    return mismatched_;
  }
  std::uint64_t appliedTwice() const {
    std::lock_guard lock(mu_);
    return applied_twice_;
  }
  std::vector<std::string> problems() const {
    std::lock_guard lock(mu_);
    return problems_;
  }

 private:
  void subscribe(const std::string& target, const std::shared_ptr<grpc::ChannelCredentials>& credentials) {
    auto channel = makeChannel(target, credentials, topology_.max_message_bytes);
    auto stub = v1::GlobalMapService::NewStub(channel);
    context_.set_wait_for_ready(true);
    auto reader = stub->Subscribe(&context_, v1::SubscribeRequest{});
    {
      std::lock_guard lock(mu_);
      subscribed_ = true;
    }
    v1::GlobalMap message;
    while (reader->Read(&message)) {
      const std::int64_t now = systemNowNs();
      auto global = fromProto(message);
      std::lock_guard lock(mu_);
      if (!global) {
        problems_.push_back("the root published an unreadable map: " + global.error().message);
        continue;
      }
      Publication p;
      p.epoch = global->header.epoch;
      p.revision = global->revision;
      p.late = global->late;
      p.published_ns = global->published_time_ns;
      p.sensor_ns = global->header.sensor_time_ns;
      p.received_ns = now;
      p.contributing.insert(global->header.contributing_nodes.begin(), global->header.contributing_nodes.end());
      p.missing.insert(global->header.missing_nodes.begin(), global->header.missing_nodes.end());
      if (p.contributing.size() != global->header.contributing_nodes.size()) ++applied_twice_;
      std::set<EllipsoidId> ids;
      for (const MapObject& o : global->map.objects) {
        for (const Ellipsoid& e : o.ellipsoids) {
          if (!ids.insert(e.id).second) ++applied_twice_;
        }
      }
      publications_.push_back(std::move(p));
      queue_.push_back(std::move(*global));
      cv_.notify_all();
    }
    (void)reader->Finish();
    {
      std::lock_guard lock(mu_);
      stream_ended_ = true;
    }
    cv_.notify_all();
  }

  void check() {
    for (;;) {
      GlobalMapMessage global;
      {
        std::unique_lock lock(mu_);
        cv_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
        if (queue_.empty()) return;
        global = std::move(queue_.front());
        queue_.pop_front();
      }
      bool equal = true;
      std::string problem;
      if (oracle_ != nullptr) {
        auto ok = oracle_->matches(global);
        equal = ok && *ok;
        if (!ok) problem = "oracle: " + ok.error().message;
      }
      std::lock_guard lock(mu_);
      ++checked_;
      if (!equal) {
        ++mismatched_;
        if (problems_.size() < 20) {
          problems_.push_back(problem.empty() ? "epoch " + std::to_string(global.header.epoch) + " revision " +
                                                    std::to_string(global.revision) + " differs from the specification"
                                              : problem);
        }
      }
      EpochVerdict& v = verdicts_[global.header.epoch];
      if (global.revision >= v.revision) {
        v = {global.revision, {global.header.contributing_nodes.begin(), global.header.contributing_nodes.end()}, equal};
      }
    }
  }

  const TopologyConfig& topology_;
  Oracle* oracle_;
  grpc::ClientContext context_;
  std::thread subscriber_;
  std::thread checker_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  bool subscribed_ = false;
  bool stream_ended_ = false;
  bool stopping_ = false;
  std::deque<GlobalMapMessage> queue_;
  std::vector<Publication> publications_;
  std::map<std::uint64_t, EpochVerdict> verdicts_;
  std::uint64_t checked_ = 0;
  std::uint64_t mismatched_ = 0;
  std::uint64_t applied_twice_ = 0;
  std::vector<std::string> problems_;
};

std::int64_t rssKib(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::strtoll(line.c_str() + 6, nullptr, 10);
  }
  return 0;
}

double metricOf(const NodeConfig& node, const std::string& name) {
  const auto text = httpGet(node.host, node.metrics_port, "/metrics", 1000ms);
  return text ? sumMetric(*text, name) : 0.0;
}

// The edge's journal files (a restarted edge starts a new one) read in directory order.
Expected<EdgeJournal> readEdgeJournal(const std::filesystem::path& journal_dir, const NodeConfig& edge) {
  EdgeJournal journal{edge.id, edge.name, {}};
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(journal_dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name != edge.name + ".journal" && name.rfind(edge.name + ".journal.", 0) != 0) continue;
    auto entries = readJournal(entry.path());
    if (!entries) return entries.error();
    journal.entries.insert(journal.entries.end(), entries->begin(), entries->end());
  }
  return journal;
}

}  // namespace

Expected<FaultObservation> observeFaults(const std::filesystem::path& dir, const TopologyConfig& topology_in, const FaultPlan& plan,
                                         std::span<const FaultAction> planned) {
  TopologyConfig topology = topology_in;  // a stall by namespace moves two nodes' addresses
  const NodeConfig* root = topology.root();
  if (root == nullptr) return invalidArgument("the topology has no root");
  auto schedule = EpochSchedule::create(topology.period_ms, topology.deadline_ms);
  if (!schedule) return schedule.error();
  const bool with_oracle = plan.check_oracle && topology.mode == Mode::kMadc;

  FaultObservation seen;
  auto phase_start = SteadyClock::now();
  const auto phase = [&](const std::string& name) {
    const auto now = SteadyClock::now();
    seen.phases.emplace_back(name, std::chrono::duration<double>(now - phase_start).count());
    phase_start = now;
  };
  std::optional<Oracle> oracle;
  if (with_oracle) {
    auto created = Oracle::create(topology, *schedule);
    if (!created) return created.error();
    oracle.emplace(std::move(*created));
    auto warmed = oracle->warm(schedule->epochAt(systemNowNs()), 64);
    if (!warmed) return warmed.error();
  }

  const auto state = dir / topology.name;
  std::error_code ec;
  std::filesystem::create_directories(state, ec);
  StartOptions options;
  options.journal_dir = state / "journals";
  std::filesystem::remove_all(options.journal_dir, ec);

  std::optional<NetnsLink> netns;
  const bool by_netns = plan.scenario == FaultScenario::kStall && plan.stall_method == StallMethod::kNetns;
  if (by_netns && !planned.empty()) {
    auto link = NetnsLink::create(static_cast<unsigned>(::getpid()));
    if (!link) return Error{link.error().code, "a stall by network namespace cannot be made here: " + link.error().message};
    netns.emplace(std::move(*link));
    // The victim lives in the namespace; its parent listens on the host's end of the pair, which
    // every other node reaches as well.
    for (NodeConfig& n : topology.nodes) {
      if (n.name == planned.front().node) n.host = netns->namespaceAddress();
    }
    for (NodeConfig& n : topology.nodes) {
      if (n.name == topology.find(planned.front().node)->parent) n.host = netns->hostAddress();
    }
    options.prefixes[planned.front().node] = netns->prefix();
  }

  const auto file = state / (topology.name + ".yaml");
  {
    std::ofstream out(file);
    out << toYaml(topology);
    if (!out) return ioError("cannot write " + file.string());
  }
  // With TLS the harness subscribes as plan.identity, like any client.
  const auto tls = loadTls(topology, plan.identity, std::chrono::system_clock::now());
  if (!tls) return Error{tls.error().code, "tls: the harness's identity '" + plan.identity + "': " + tls.error().message};
  phase("oracle");
  Observer observer(topology, oracle ? &*oracle : nullptr);
  auto cluster = startCluster(file, topology, state, 30s, options);
  if (!cluster) return cluster.error();
  phase("start");
  observer.start(endpoint(root->host, root->port), channelCredentials(*tls));
  // Judged are the epochs that begin once the subscription delivers: the root publishes every
  // epoch, so the first map received says it does (bounded wait).
  for (int i = 0; i < 500 && observer.publications().empty(); ++i) std::this_thread::sleep_for(kTick);
  if (observer.publications().empty()) {
    stopNodes(cluster->nodes, 10s);
    observer.finish(1s);
    return Error{ErrorCode::kInternal, "the root published nothing within 10 s; see " + (state / "logs").string()};
  }
  seen.judged_from = schedule->epochAt(systemNowNs()) + 1;

  std::vector<bool> done(planned.size(), false);
  std::set<std::string> down;  // killed or stopped, not yet back
  std::map<std::string, std::int64_t> stopped_at;
  std::map<std::string, double> stalls_before;  // children's link stalls when their parent was stopped
  std::set<std::string> restarted;
  std::map<std::string, std::int64_t> rss_warm;

  const auto start = SteadyClock::now();
  seen.start_ns = systemNowNs();
  std::optional<std::string> failure;
  while (SteadyClock::now() - start < plan.duration && !stopRequested()) {
    const auto elapsed = std::chrono::duration_cast<std::chrono::milliseconds>(SteadyClock::now() - start);
    for (std::size_t k = 0; k < planned.size(); ++k) {
      const FaultAction& a = planned[k];
      if (done[k] || a.at > elapsed) continue;
      done[k] = true;
      auto node = std::find_if(cluster->nodes.begin(), cluster->nodes.end(), [&](const RunningNode& r) { return r.name == a.node; });
      const std::int64_t now = systemNowNs();
      seen.events.push_back({a.what, a.node, now});
      if (a.what == "stop" && netns) seen.events.back().what = "drop";
      if (a.what == "continue" && netns) seen.events.back().what = "restore";
      if (a.what == "kill" || a.what == "stop") {
        if (a.what == "stop" && netns) {
          if (auto s = netns->setDropping(true); !s) {
            failure = s.error().message;
            break;
          }
        } else {
          ::kill(node->pid, a.what == "kill" ? SIGKILL : SIGSTOP);
        }
        down.insert(a.node);
        if (a.what == "stop") {
          stopped_at[a.node] = now;
          for (const NodeConfig* child : topology.children(a.node)) {
            stalls_before[child->name] = metricOf(*child, "fogmap_link_stalls_total");
          }
        }
      } else if (a.what == "continue") {
        if (netns) {
          if (auto s = netns->setDropping(false); !s) {
            failure = s.error().message;
            break;
          }
        } else {
          ::kill(node->pid, SIGCONT);
        }
        down.erase(a.node);
      } else if (a.what == "restart") {
        auto again = restartNode(*cluster, topology, a.node, 10s, options);
        if (!again) {
          failure = "restarting " + a.node + ": " + again.error().message;
          break;
        }
        down.erase(a.node);
        restarted.insert(a.node);
        // Healed once the process is up again (it serves /metrics): its start-up on a loaded
        // machine (a second or more) is not the cluster's recovery.
        seen.restarts.push_back({a.node, now, systemNowNs()});
      }
    }
    if (failure) break;
    // Children of a stopped parent: when does the first of them give its stream up?
    if (!stopped_at.empty() && !seen.child_notice_ms) {
      for (const auto& [child, before] : stalls_before) {
        if (metricOf(*topology.find(child), "fogmap_link_stalls_total") > before) {
          // When the child gave up, by its own clock: the scrape may come much later on a loaded
          // machine, and that delay is the harness's, not the cluster's.
          const double at_s = metricOf(*topology.find(child), "fogmap_link_last_stall_time_seconds");
          const std::int64_t at_ns = at_s > 0 ? static_cast<std::int64_t>(at_s * 1e9) : systemNowNs();
          seen.child_notice_ms = nsToMs(at_ns - stopped_at.begin()->second);
          break;
        }
      }
    }
    if (!seen.warm_sampled && SteadyClock::now() - start >= plan.warmup) {
      seen.warm_sampled = true;
      for (const RunningNode& n : cluster->nodes) rss_warm[n.name] = rssKib(n.pid);
    }
    for (const RunningNode& n : cluster->nodes) {
      if (down.contains(n.name) || isRunning(n.pid)) continue;
      if (std::find(seen.crashed.begin(), seen.crashed.end(), n.name) == seen.crashed.end()) seen.crashed.push_back(n.name);
    }
    std::this_thread::sleep_for(kTick);
  }
  seen.end_ns = systemNowNs();
  phase("load");
  if (netns) (void)netns->setDropping(false);
  for (const std::string& name : down) {  // a stopped process must not stay stopped
    const auto node = std::find_if(cluster->nodes.begin(), cluster->nodes.end(), [&](const RunningNode& r) { return r.name == name; });
    if (node != cluster->nodes.end() && isRunning(node->pid)) ::kill(node->pid, SIGCONT);
  }
  for (const RunningNode& n : cluster->nodes) {
    if (!isRunning(n.pid)) continue;
    const auto warm = rss_warm.find(n.name);
    if (warm == rss_warm.end() || restarted.contains(n.name)) continue;
    seen.memory.push_back({n.name, warm->second, rssKib(n.pid)});
  }
  seen.observer_drops = static_cast<std::uint64_t>(metricOf(*root, "fogmap_subscriber_drops_total"));
  seen.root_caught_up = static_cast<std::uint64_t>(metricOf(*root, "fogmap_caught_up_epochs_total"));
  seen.root_longest_poll_gap_ms = 1000.0 * metricOf(*root, "fogmap_emitter_longest_poll_gap_seconds");
  for (const NodeConfig& n : topology.nodes) {
    if (n.role == Role::kAggregator) seen.duplicates_recognised += static_cast<std::uint64_t>(metricOf(n, "fogmap_duplicate_uploads_total"));
  }

  // Stop in order, so that everything acknowledged reaches the root: the edges first, then the
  // aggregators level by level from the leaves up, each level given time to emit and flush.
  std::map<int, std::vector<RunningNode>> levels;
  for (const RunningNode& n : cluster->nodes) levels[topology.aggregatorLevels(n.name)].push_back(n);
  for (const auto& [level, nodes] : levels) {
    if (level > 0) std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<long>(topology.deadline_ms + topology.period_ms)));
    stopNodes(nodes, 10s);
  }
  observer.finish(10s);
  ::unlink((state / "pids").c_str());
  phase("stop");
  if (failure) return Error{ErrorCode::kInternal, *failure};

  seen.publications = observer.publications();
  seen.verdicts = observer.verdicts();
  seen.checked = observer.checked();
  seen.mismatched = observer.mismatched();
  seen.applied_twice = observer.appliedTwice();
  seen.problems = observer.problems();
  for (const NodeConfig& n : topology.nodes) {
    if (n.role != Role::kEdge) continue;
    auto journal = readEdgeJournal(options.journal_dir, n);
    if (!journal) return journal.error();
    seen.journals.push_back(std::move(*journal));
  }
  return seen;
}

}  // namespace fogmap::harness
