#include "tools/fogctl/faults.hpp"

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <sstream>
#include <thread>

#include <grpcpp/grpcpp.h>

#include "common/certs.hpp"
#include "common/clock.hpp"
#include "common/epochs.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/delivery_journal.hpp"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "services/edge_cluster/edge_node.hpp"
#include "services/edge_cluster/edge_runner.hpp"
#include "services/edge_cluster/scan_source.hpp"
#include "tools/fogctl/cluster_run.hpp"
#include "tools/fogctl/launcher.hpp"
#include "tools/fogctl/netns.hpp"

namespace fogmap::cli {
namespace {

using namespace std::chrono_literals;
using SteadyClock = std::chrono::steady_clock;

constexpr std::chrono::milliseconds kTick{20};
// Scheduling slack allowed on top of the protocol's bound when a figure is checked against it.
constexpr double kSlackMs = 100.0;
constexpr double kChildNoticeBoundMs = 3000.0;
constexpr double kRejoinBoundMs = 2000.0;
constexpr double kRecoveryBoundMs = 5000.0;
constexpr std::int64_t kMaxRssGrowthKib = 64 * 1024;

double ms(std::int64_t ns) { return static_cast<double>(ns) / 1e6; }

// One global map as the harness keeps it (the maps themselves go to the oracle and are dropped).
struct Publication {
  std::uint64_t epoch = 0;
  std::uint32_t revision = 0;
  bool late = false;
  std::int64_t published_ns = 0;
  std::int64_t sensor_ns = 0;
  std::int64_t received_ns = 0;  // the harness's clock when it arrived
  std::set<std::uint32_t> contributing;
  std::set<std::uint32_t> missing;
};

// The latest revision of an epoch, as judged.
struct EpochVerdict {
  std::uint32_t revision = 0;
  std::set<std::uint32_t> contributing;
  bool equal = false;     // equal to the oracle (or no oracle)
};

// mergeSpecification over the local maps every edge computes for an epoch, recomputed from the
// same scans with the edges' code. Maps are compared with every ellipsoid's frame set to 0: the
// edges stamp the epoch there, and the scan shown (hence the geometry) repeats.
class Oracle {
 public:
  static Expected<Oracle> create(const TopologyConfig& topology, const EpochSchedule& schedule) {
    Oracle oracle(topology, schedule);
    for (const NodeConfig& n : topology.nodes) {
      if (n.role != Role::kEdge) continue;
      SensorConfig sensor = *n.sensor;
      sensor.frames.reset();
      sensor.loop = true;
      auto source = ScanSource::open(sensor, ReadLimits{topology.max_scan_bytes});
      if (!source) return source.error();
      oracle.sources_.emplace(n.id, std::move(*source));
    }
    return oracle;
  }

  // Whether `global` equals the specification's map over its contributing nodes.
  Expected<bool> matches(const GlobalMapMessage& global) {
    std::vector<std::pair<std::uint32_t, std::uint64_t>> key;  // (node, scan file)
    for (std::uint32_t node : global.header.contributing_nodes) {
      const NodeConfig* n = topology_.find(node);
      if (n == nullptr || n->role != Role::kEdge) return invalidArgument("unknown contributing node " + std::to_string(node));
      const auto files = sources_.at(node).files().size();
      key.emplace_back(node, scanNumberAt(schedule_, n->sensor->rate_hz, global.header.epoch) % files);
    }
    auto cached = expected_.find(key);
    if (cached == expected_.end()) {
      std::vector<Ellipsoid> all;
      for (const auto& [node, file] : key) {
        auto local = localMap(node, file);
        if (!local) return local.error();
        for (const MapObject& o : (*local)->objects) all.insert(all.end(), o.ellipsoids.begin(), o.ellipsoids.end());
      }
      cached = expected_.emplace(key, mergeSpecification(all)).first;
    }
    return withoutFrames(global.map) == cached->second;
  }

  // Fills the cache for complete epochs of every scan file, before the clock starts.
  Expected<bool> warm(std::uint64_t first_epoch, std::uint64_t epochs) {
    GlobalMapMessage probe;
    for (const auto& [node, source] : sources_) probe.header.contributing_nodes.push_back(node);
    for (std::uint64_t e = first_epoch; e < first_epoch + epochs; ++e) {
      probe.header.epoch = e;
      auto ok = matches(probe);
      if (!ok) return ok.error();
    }
    return true;
  }

 private:
  Oracle(const TopologyConfig& topology, const EpochSchedule& schedule) : topology_(topology), schedule_(schedule) {}

  static Map withoutFrames(Map map) {
    for (MapObject& o : map.objects) {
      for (Ellipsoid& e : o.ellipsoids) e.id.frame = 0;
    }
    return map;
  }

  Expected<const Map*> localMap(std::uint32_t node, std::uint64_t file) {
    const auto key = std::make_pair(node, file);
    if (const auto it = local_.find(key); it != local_.end()) return &it->second;
    auto frame = sources_.at(node).at(file);
    if (!frame) return frame.error();
    EdgeNode edge(edgeConfigFor(topology_, *topology_.find(node)));
    auto output = edge.processFrame(frame->points, 0, 0);
    if (!output) return output.error();
    if (!output->map) return invalidArgument("the oracle needs mode madc");
    // What the parent receives: the map after its trip through the wire format.
    auto received = fromProto(toProto(*output->map));
    if (!received) return received.error();
    return &local_.emplace(key, withoutFrames(received->map)).first->second;
  }

  const TopologyConfig& topology_;
  EpochSchedule schedule_;
  std::map<std::uint32_t, ScanSource> sources_;
  std::map<std::pair<std::uint32_t, std::uint64_t>, Map> local_;
  std::map<std::vector<std::pair<std::uint32_t, std::uint64_t>>, Map> expected_;
};

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

// A fault to inject: at `at` after the start, signal `node`; restarts are separate actions.
struct Action {
  std::chrono::milliseconds at{0};
  std::string what;  // kill, restart, stop, continue
  std::string node;
  bool done = false;
};

std::vector<Action> planActions(const TopologyConfig& topology, const FaultPlan& plan) {
  std::mt19937_64 rng(plan.seed);
  const auto when = [&](double from, double to) {
    std::uniform_real_distribution<double> u(from, to);
    return std::chrono::milliseconds(static_cast<long>(u(rng) * static_cast<double>(plan.duration.count())));
  };
  std::vector<const NodeConfig*> edges;
  std::vector<const NodeConfig*> middle;  // aggregators other than the root
  for (const NodeConfig& n : topology.nodes) {
    if (n.role == Role::kEdge) edges.push_back(&n);
    if (n.role == Role::kAggregator && !n.parent.empty()) middle.push_back(&n);
  }
  std::vector<Action> actions;
  switch (plan.scenario) {
    case FaultScenario::kSoak: break;
    case FaultScenario::kEdgeCrash: {
      std::shuffle(edges.begin(), edges.end(), rng);
      const int kills = std::min<int>(plan.edge_kills, static_cast<int>(edges.size()));
      for (int k = 0; k < kills; ++k) {
        const auto at = when(0.2, 0.5);
        actions.push_back({at, "kill", edges[static_cast<std::size_t>(k)]->name});
        actions.push_back({at + plan.downtime, "restart", edges[static_cast<std::size_t>(k)]->name});
      }
      break;
    }
    case FaultScenario::kAggregatorCrash:
    case FaultScenario::kStall: {
      if (middle.empty()) break;
      const NodeConfig* victim = middle[std::uniform_int_distribution<std::size_t>(0, middle.size() - 1)(rng)];
      const auto at = when(0.25, 0.4);
      const bool crash = plan.scenario == FaultScenario::kAggregatorCrash;
      actions.push_back({at, crash ? "kill" : "stop", victim->name});
      actions.push_back({at + plan.downtime, crash ? "restart" : "continue", victim->name});
      break;
    }
  }
  std::sort(actions.begin(), actions.end(), [](const Action& a, const Action& b) { return a.at < b.at; });
  return actions;
}

std::string jsonString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (static_cast<unsigned char>(c) < 0x20) {
      out += ' ';
      continue;
    }
    out += c;
  }
  return out + "\"";
}

}  // namespace

const char* scenarioName(FaultScenario scenario) {
  switch (scenario) {
    case FaultScenario::kSoak: return "soak";
    case FaultScenario::kEdgeCrash: return "edge-crash";
    case FaultScenario::kAggregatorCrash: return "aggregator-crash";
    case FaultScenario::kStall: return "stall";
  }
  return "soak";
}

std::optional<FaultScenario> parseScenario(const std::string& name) {
  for (FaultScenario s : {FaultScenario::kSoak, FaultScenario::kEdgeCrash, FaultScenario::kAggregatorCrash,
                          FaultScenario::kStall}) {
    if (name == scenarioName(s)) return s;
  }
  return std::nullopt;
}

bool FaultReport::passed() const {
  return std::all_of(checks.begin(), checks.end(), [](const Check& c) { return c.passed; });
}

const char* stallMethodName(StallMethod method) {
  return method == StallMethod::kNetns ? "netns" : "sigstop";
}

Expected<FaultReport> runFaults(const std::filesystem::path& dir, const TopologyConfig& topology_in, const FaultPlan& plan) {
  TopologyConfig topology = topology_in;  // a stall by namespace moves two nodes' addresses
  const NodeConfig* root = topology.root();
  if (root == nullptr) return invalidArgument("the topology has no root");
  auto schedule = EpochSchedule::create(topology.period_ms, topology.deadline_ms);
  if (!schedule) return schedule.error();
  const bool with_oracle = plan.check_oracle && topology.mode == Mode::kMadc;
  const std::vector<std::uint32_t> sensors = topology.sensorsBelow(root->name);

  FaultReport report;
  report.topology = topology.name;
  report.scenario = scenarioName(plan.scenario);
  report.seed = plan.seed;
  report.duration_s = static_cast<double>(plan.duration.count()) / 1000.0;
  report.edges = static_cast<int>(sensors.size());
  report.period_ms = topology.period_ms;
  report.root_deadline_ms = topology.deadline_ms * topology.aggregatorLevels(root->name);

  auto phase_start = SteadyClock::now();
  const auto phase = [&](const std::string& name) {
    const auto now = SteadyClock::now();
    report.phases.emplace_back(name, std::chrono::duration<double>(now - phase_start).count());
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

  std::vector<Action> actions = planActions(topology, plan);
  std::optional<NetnsLink> netns;
  const bool by_netns = plan.scenario == FaultScenario::kStall && plan.stall_method == StallMethod::kNetns;
  if (!actions.empty()) {
    const std::string& victim = actions.front().node;
    const double seconds = static_cast<double>(plan.downtime.count()) / 1000.0;
    std::ostringstream fault;
    if (plan.scenario == FaultScenario::kStall) {
      fault << (by_netns ? "iptables DROP of every packet of " + victim + "'s network namespace for "
                         : "SIGSTOP of " + victim + " for ") << seconds << " s";
    } else if (plan.scenario == FaultScenario::kAggregatorCrash) {
      fault << "kill -9 of " << victim << ", restarted after " << seconds << " s";
    } else {
      fault << "kill -9 of " << plan.edge_kills << " edge(s), each restarted after " << seconds << " s";
    }
    report.fault = fault.str();
  }
  if (by_netns && !actions.empty()) {
    auto link = NetnsLink::create(static_cast<unsigned>(::getpid()));
    if (!link) return Error{link.error().code, "a stall by network namespace cannot be made here: " + link.error().message};
    netns.emplace(std::move(*link));
    // The victim lives in the namespace; its parent listens on the host's end of the pair, which
    // every other node reaches as well.
    for (NodeConfig& n : topology.nodes) {
      if (n.name == actions.front().node) n.host = netns->namespaceAddress();
    }
    for (NodeConfig& n : topology.nodes) {
      if (n.name == topology.find(actions.front().node)->parent) n.host = netns->hostAddress();
    }
    options.prefixes[actions.front().node] = netns->prefix();
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
  observer.start(root->host + ":" + std::to_string(root->port), channelCredentials(*tls));
  // Judged are the epochs that begin once the subscription delivers: the root publishes every
  // epoch, so the first map received says it does (bounded wait).
  for (int i = 0; i < 500 && observer.publications().empty(); ++i) std::this_thread::sleep_for(kTick);
  if (observer.publications().empty()) {
    stopNodes(cluster->nodes, 10s);
    observer.finish(1s);
    return Error{ErrorCode::kInternal, "the root published nothing within 10 s; see " + (state / "logs").string()};
  }
  const std::uint64_t judged_from = schedule->epochAt(systemNowNs()) + 1;

  std::set<std::string> down;  // killed or stopped, not yet back
  std::map<std::string, std::int64_t> stopped_at;
  std::map<std::string, double> stalls_before;  // children's link stalls when their parent was stopped
  std::set<std::string> restarted;
  std::optional<std::int64_t> heal_ns;
  struct FaultWindow {
    std::string node;
    std::set<std::uint32_t> sensors;
    std::uint64_t first_epoch = 0;
    std::uint64_t last_epoch = 0;
  };
  std::vector<FaultWindow> windows;
  const auto closeWindow = [&](const std::string& node, std::int64_t heal) {
    const std::int64_t settle_ns = static_cast<std::int64_t>(
        (2000.0 + topology.admission.window_periods * topology.period_ms) * 1e6);  // ParentLink backoff cap
    for (FaultWindow& w : windows) {
      if (w.node == node && w.last_epoch == std::numeric_limits<std::uint64_t>::max()) w.last_epoch = schedule->epochAt(heal + settle_ns);
    }
  };
  std::map<std::string, std::int64_t> rss_warm;
  std::vector<std::pair<std::string, std::int64_t>> kills;    // node, time: for missing notices
  struct Restart {
    std::string node;
    std::int64_t commanded_ns = 0;  // the restart began
    std::int64_t ready_ns = 0;      // its /metrics answered: the process is up
  };
  std::vector<Restart> restarts;  // edge restarts, for rejoin times

  const auto start = SteadyClock::now();
  const std::int64_t start_ns = systemNowNs();
  bool warm_sampled = false;
  std::optional<std::string> failure;
  while (SteadyClock::now() - start < plan.duration && !stopRequested()) {
    const auto elapsed = std::chrono::duration_cast<std::chrono::milliseconds>(SteadyClock::now() - start);
    for (Action& a : actions) {
      if (a.done || a.at > elapsed) continue;
      a.done = true;
      auto node = std::find_if(cluster->nodes.begin(), cluster->nodes.end(), [&](const RunningNode& r) { return r.name == a.node; });
      const NodeConfig* config = topology.find(a.node);
      const std::int64_t now = systemNowNs();
      report.events.push_back({a.what, a.node, now});
      if (a.what == "stop" && netns) report.events.back().what = "drop";
      if (a.what == "continue" && netns) report.events.back().what = "restore";
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
        kills.emplace_back(a.node, now);
        if (config->role == Role::kAggregator) {
          // Maps it acknowledged for epochs it had not emitted yet die with it (kill), and maps the
          // aggregators below it acknowledged meanwhile wait in their links until they are too old
          // to be admitted: until the heal, plus the link's backoff cap and the admission window.
          const auto emit_ns = static_cast<std::int64_t>(
              (topology.deadline_ms * topology.aggregatorLevels(a.node) + topology.period_ms) * 1e6);
          const auto below = topology.sensorsBelow(a.node);
          windows.push_back({a.node, {below.begin(), below.end()}, schedule->epochAt(now - emit_ns),
                             std::numeric_limits<std::uint64_t>::max()});
        }
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
        heal_ns = now;
        closeWindow(a.node, now);
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
        const std::int64_t up = systemNowNs();
        if (config->role == Role::kEdge) restarts.push_back({a.node, now, up});
        if (config->role == Role::kAggregator) {
          heal_ns = up;
          closeWindow(a.node, up);
        }
      }
    }
    if (failure) break;
    // Children of a stopped parent: when does the first of them give its stream up?
    if (!stopped_at.empty() && !report.child_notice_ms) {
      for (const auto& [child, before] : stalls_before) {
        if (metricOf(*topology.find(child), "fogmap_link_stalls_total") > before) {
          // When the child gave up, by its own clock: the scrape may come much later on a loaded
          // machine, and that delay is the harness's, not the cluster's.
          const double at_s = metricOf(*topology.find(child), "fogmap_link_last_stall_time_seconds");
          const std::int64_t at_ns = at_s > 0 ? static_cast<std::int64_t>(at_s * 1e9) : systemNowNs();
          report.child_notice_ms = ms(at_ns - stopped_at.begin()->second);
          break;
        }
      }
    }
    if (!warm_sampled && SteadyClock::now() - start >= plan.warmup) {
      warm_sampled = true;
      for (const RunningNode& n : cluster->nodes) rss_warm[n.name] = rssKib(n.pid);
    }
    for (const RunningNode& n : cluster->nodes) {
      if (down.contains(n.name) || isRunning(n.pid)) continue;
      if (std::find(report.crashed.begin(), report.crashed.end(), n.name) == report.crashed.end()) {
        report.crashed.push_back(n.name);
      }
    }
    std::this_thread::sleep_for(kTick);
  }
  const std::int64_t end_ns = systemNowNs();
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
    report.memory.push_back({n.name, warm->second, rssKib(n.pid)});
    report.max_rss_growth_kib =
        std::max(report.max_rss_growth_kib, static_cast<double>(report.memory.back().rss_end_kib - warm->second));
  }
  report.observer_drops = static_cast<std::uint64_t>(metricOf(*root, "fogmap_subscriber_drops_total"));
  report.root_caught_up = static_cast<std::uint64_t>(metricOf(*root, "fogmap_caught_up_epochs_total"));
  report.root_longest_poll_gap_ms = 1000.0 * metricOf(*root, "fogmap_emitter_longest_poll_gap_seconds");
  for (const NodeConfig& n : topology.nodes) {
    if (n.role == Role::kAggregator) report.duplicates_recognised += static_cast<std::uint64_t>(metricOf(n, "fogmap_duplicate_uploads_total"));
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

  // Sent vs applied.
  const std::vector<Publication> pubs = observer.publications();
  std::map<std::uint64_t, std::set<std::uint32_t>> applied;
  std::map<std::uint64_t, std::set<std::uint32_t>> acknowledged;  // what the edges' parents acknowledged
  for (const Publication& p : pubs) applied[p.epoch].insert(p.contributing.begin(), p.contributing.end());
  for (const NodeConfig& n : topology.nodes) {
    if (n.role != Role::kEdge) continue;
    for (const auto& entry : std::filesystem::directory_iterator(options.journal_dir, ec)) {
      const std::string name = entry.path().filename().string();
      if (name != n.name + ".journal" && name.rfind(n.name + ".journal.", 0) != 0) continue;
      auto journal = readJournal(entry.path());
      if (!journal) return journal.error();
      for (const JournalEntry& j : *journal) {
        if (j.kind != "map" || j.epoch < judged_from) continue;
        ++report.maps_sent;
        if (j.outcome == Outcome::kRefused) ++report.maps_refused;
        if (j.outcome == Outcome::kUnsettled) ++report.maps_unsettled;
        if (j.outcome != Outcome::kApplied && j.outcome != Outcome::kLate) continue;
        ++report.maps_acknowledged;
        acknowledged[j.epoch].insert(n.id);
        if (applied[j.epoch].contains(n.id)) continue;
        const bool in_fault = std::any_of(windows.begin(), windows.end(), [&](const FaultWindow& w) {
          return w.sensors.contains(n.id) && j.epoch >= w.first_epoch && j.epoch <= w.last_epoch;
        });
        ++(in_fault ? report.maps_lost_in_fault : report.maps_lost);
        if (!in_fault && report.lost_examples.size() < 10) {
          report.lost_examples.push_back(n.name + " epoch +" + std::to_string(static_cast<long long>(j.epoch) - static_cast<long long>(schedule->epochAt(start_ns))) + " (" +
                                         outcomeName(j.outcome) + ")");
        }
      }
    }
  }
  report.applied_twice = observer.appliedTwice();
  report.publications_checked = observer.checked();
  report.publications_mismatched = observer.mismatched();

  // Liveness and latency over the loaded window.
  const std::uint64_t last_loaded = schedule->epochAt(end_ns) - 1;
  std::optional<std::uint64_t> first_published;
  std::vector<std::int64_t> first_times;
  std::vector<double> e2e;
  std::optional<std::uint64_t> newest_first;  // the newest epoch whose first publication came
  for (const Publication& p : pubs) {
    report.publications += 1;
    report.late_publications += p.late ? 1 : 0;
    if (p.revision == 0) {
      if (newest_first && p.epoch <= *newest_first) ++report.out_of_order;
      newest_first = std::max(newest_first.value_or(p.epoch), p.epoch);
    }
    // Only epochs that began once the subscription delivered: a late first publication of an
    // older epoch would otherwise pull the window back over epochs published before it.
    if (p.revision != 0 || p.epoch > last_loaded || p.epoch < judged_from || p.published_ns < start_ns) continue;
    first_published = std::min(first_published.value_or(p.epoch), p.epoch);
    first_times.push_back(p.published_ns);
    if (p.contributing.size() == sensors.size()) e2e.push_back(ms(p.published_ns - p.sensor_ns));
  }
  if (first_published) {
    report.epochs_in_window = last_loaded - *first_published + 1;
    for (std::uint64_t e = *first_published; e <= last_loaded; ++e) {
      if (applied.contains(e)) continue;
      ++report.epochs_unpublished;
      if (report.unpublished_examples.size() < 10) report.unpublished_examples.push_back(e - *first_published);
    }
  }
  std::sort(first_times.begin(), first_times.end());
  for (std::size_t i = 1; i < first_times.size(); ++i) {
    report.max_silence_ms = std::max(report.max_silence_ms, ms(first_times[i] - first_times[i - 1]));
  }
  report.e2e_p50_ms = percentile(e2e, 0.5);
  report.e2e_p99_ms = percentile(e2e, 0.99);

  // Fault figures.
  for (const auto& [name, at] : kills) {
    const auto below = topology.sensorsBelow(name);
    std::optional<double> notice;
    for (const Publication& p : pubs) {
      if (p.revision != 0 || p.published_ns < at) continue;
      if (std::any_of(below.begin(), below.end(), [&](std::uint32_t s) { return p.missing.contains(s); })) {
        notice = std::min(notice.value_or(1e18), ms(p.published_ns - at));
      }
    }
    report.missing_notice_ms.push_back(notice.value_or(-1.0));
  }
  for (const Restart& restart : restarts) {
    const std::uint32_t id = topology.find(restart.node)->id;
    const std::int64_t at = restart.ready_ns;
    std::optional<double> rejoin;
    for (const Publication& p : pubs) {
      if (p.published_ns >= at && p.contributing.contains(id)) rejoin = std::min(rejoin.value_or(1e18), ms(p.published_ns - at));
    }
    report.rejoin_ms.push_back(rejoin.value_or(-1.0));
    report.restart_startup_ms.push_back(ms(restart.ready_ns - restart.commanded_ns));
  }
  if (heal_ns) {
    const auto verdicts = observer.verdicts();
    // An epoch is whole when its latest publication holds every map the edges' parents
    // acknowledged for it and equals the specification: what the fault-free cluster would have
    // published from what the edges sent (an edge behind its schedule skips epochs; that is not
    // the fault's doing, and each skip is counted by the edge).
    const auto whole = [&](std::uint64_t e) {
      const auto v = verdicts.find(e);
      if (v == verdicts.end() || !v->second.equal) return false;
      const auto& sent = acknowledged[e];
      return std::includes(v->second.contributing.begin(), v->second.contributing.end(), sent.begin(), sent.end());
    };
    std::optional<std::uint64_t> recovered;  // first epoch from which every loaded epoch is whole
    for (std::uint64_t e = schedule->epochAt(*heal_ns); e <= last_loaded && report.after_heal.size() < 40; ++e) {
      const auto v = verdicts.find(e);
      report.after_heal.push_back(v == verdicts.end() ? "-" : std::string(whole(e) ? "w" : "i") + (v->second.equal ? "" : "!"));
    }
    for (std::uint64_t e = last_loaded; e >= schedule->epochAt(*heal_ns) && e > 0; --e) {
      if (!whole(e)) break;
      recovered = e;
    }
    if (recovered) {
      report.recovery_ms = ms(schedule->startNs(*recovered) - *heal_ns) + report.root_deadline_ms;
      report.epochs_after_recovery = last_loaded - *recovered + 1;
    }
  }

  // The checks.
  auto check = [&](const std::string& name, bool ok, const std::string& detail) { report.checks.push_back({name, ok, detail}); };
  const std::vector<std::string> problems = observer.problems();
  check("every global map the root published was readable", std::none_of(problems.begin(), problems.end(), [](const std::string& p) {
          return p.rfind("the root published an unreadable map", 0) == 0;
        }), problems.empty() ? "" : problems.front());
  check("no process died unless killed", report.crashed.empty(),
        report.crashed.empty() ? "" : "died: " + report.crashed.front());
  // Every epoch, in order: a stall of the root's own makes it publish the epochs it missed late
  // (flagged), never leave them out; an epoch complete early waits for the older ones.
  std::string unpublished = std::to_string(report.epochs_unpublished) + " of " + std::to_string(report.epochs_in_window) +
                            " unpublished";
  for (std::uint64_t e : report.unpublished_examples) unpublished += " +" + std::to_string(e);
  unpublished += "; the root dropped " + std::to_string(report.observer_drops) + " of the harness's subscription, caught up " +
                 std::to_string(report.root_caught_up) + " after stalls (longest poll gap " +
                 std::to_string(report.root_longest_poll_gap_ms) + " ms)";
  check("the root published every epoch", report.epochs_in_window > 0 && report.epochs_unpublished == 0, unpublished);
  check("the root published the epochs in order", report.out_of_order == 0,
        std::to_string(report.out_of_order) + " first publications of an epoch older than one published before");
  check("the root was never silent for more than 4 periods", report.max_silence_ms <= 4.0 * topology.period_ms,
        "longest silence " + std::to_string(report.max_silence_ms) + " ms");
  check("no acknowledged map lost", report.maps_lost == 0, std::to_string(report.maps_lost) + " lost");
  check("no map applied twice", report.applied_twice == 0, std::to_string(report.applied_twice) + " duplicates");
  if (with_oracle) {
    check("every global map equals the specification", report.publications_checked > 0 && report.publications_mismatched == 0,
          std::to_string(report.publications_mismatched) + " of " + std::to_string(report.publications_checked) +
              (problems.empty() ? std::string() : "; " + problems.front()));
  }
  std::ostringstream bound;
  const double missing_bound = topology.period_ms + report.root_deadline_ms + kSlackMs;
  bound << "bound " << missing_bound << " ms";
  switch (plan.scenario) {
    case FaultScenario::kSoak:
      check("memory bounded after the warm-up", warm_sampled && report.max_rss_growth_kib <= static_cast<double>(kMaxRssGrowthKib),
            std::to_string(static_cast<long>(report.max_rss_growth_kib)) + " KiB largest growth");
      break;
    case FaultScenario::kEdgeCrash:
      for (double n : report.missing_notice_ms) check("a killed edge is marked missing in time", n >= 0 && n <= missing_bound, std::to_string(n) + " ms, " + bound.str());
      for (double r : report.rejoin_ms) check("a restarted edge is merged again within 2 s of being up", r >= 0 && r <= kRejoinBoundMs, std::to_string(r) + " ms");
      break;
    case FaultScenario::kAggregatorCrash:
    case FaultScenario::kStall:
      for (double n : report.missing_notice_ms) check("the root marks the subtree missing within 3 s", n >= 0 && n <= kChildNoticeBoundMs, std::to_string(n) + " ms");
      if (plan.scenario == FaultScenario::kStall) {
        check("the children notice the stall within 3 s", report.child_notice_ms && *report.child_notice_ms <= kChildNoticeBoundMs,
              report.child_notice_ms ? std::to_string(*report.child_notice_ms) + " ms" : "never");
      }
      check("the root converges to the fault-free maps after recovery",
            report.recovery_ms && *report.recovery_ms <= kRecoveryBoundMs && report.epochs_after_recovery >= 10,
            report.recovery_ms ? std::to_string(*report.recovery_ms) + " ms, then " + std::to_string(report.epochs_after_recovery) + " epochs equal"
                               : "never");
      break;
  }
  return report;
}

std::string toJson(const FaultReport& r) {
  std::ostringstream o;
  o << std::setprecision(10);
  const auto list = [&](const std::vector<double>& v) {
    std::string s = "[";
    for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + std::to_string(v[i]);
    return s + "]";
  };
  o << "{\n  \"topology\": " << jsonString(r.topology) << ",\n  \"scenario\": " << jsonString(r.scenario)
    << ",\n  \"fault\": " << jsonString(r.fault) << ",\n  \"seed\": " << r.seed << ",\n  \"duration_s\": " << r.duration_s << ",\n  \"edges\": " << r.edges
    << ",\n  \"period_ms\": " << r.period_ms << ",\n  \"root_deadline_ms\": " << r.root_deadline_ms
    << ",\n  \"epochs_in_window\": " << r.epochs_in_window << ",\n  \"epochs_unpublished\": " << r.epochs_unpublished
    << ",\n  \"max_silence_ms\": " << r.max_silence_ms << ",\n  \"publications\": " << r.publications
    << ",\n  \"late_publications\": " << r.late_publications << ",\n  \"out_of_order\": " << r.out_of_order
    << ",\n  \"root_caught_up\": " << r.root_caught_up << ",\n  \"root_longest_poll_gap_ms\": " << r.root_longest_poll_gap_ms << ",\n  \"maps_sent\": " << r.maps_sent
    << ",\n  \"maps_acknowledged\": " << r.maps_acknowledged << ",\n  \"maps_refused\": " << r.maps_refused
    << ",\n  \"maps_unsettled\": " << r.maps_unsettled << ",\n  \"maps_lost\": " << r.maps_lost
    << ",\n  \"maps_lost_in_fault\": " << r.maps_lost_in_fault << ",\n  \"applied_twice\": " << r.applied_twice
    << ",\n  \"duplicates_recognised\": " << r.duplicates_recognised << ",\n  \"observer_drops\": " << r.observer_drops
    << ",\n  \"publications_checked\": " << r.publications_checked
    << ",\n  \"publications_mismatched\": " << r.publications_mismatched << ",\n  \"e2e_p50_ms\": " << r.e2e_p50_ms
    << ",\n  \"e2e_p99_ms\": " << r.e2e_p99_ms << ",\n  \"max_rss_growth_kib\": " << r.max_rss_growth_kib
    << ",\n  \"missing_notice_ms\": " << list(r.missing_notice_ms) << ",\n  \"rejoin_ms\": " << list(r.rejoin_ms)
    << ",\n  \"restart_startup_ms\": " << list(r.restart_startup_ms)
    << ",\n  \"recovery_ms\": " << (r.recovery_ms ? std::to_string(*r.recovery_ms) : "null")
    << ",\n  \"child_notice_ms\": " << (r.child_notice_ms ? std::to_string(*r.child_notice_ms) : "null")
    << ",\n  \"epochs_after_recovery\": " << r.epochs_after_recovery
    << ",\n  \"memory\": [";
  for (std::size_t i = 0; i < r.memory.size(); ++i) {
    o << (i ? ", " : "") << "{\"node\": " << jsonString(r.memory[i].node) << ", \"rss_after_warmup_kib\": "
      << r.memory[i].rss_after_warmup_kib << ", \"rss_end_kib\": " << r.memory[i].rss_end_kib << "}";
  }
  o << "],\n  \"events\": [";
  for (std::size_t i = 0; i < r.events.size(); ++i) {
    o << (i ? ", " : "") << "{\"what\": " << jsonString(r.events[i].what) << ", \"node\": " << jsonString(r.events[i].node)
      << ", \"at_ns\": " << r.events[i].at_ns << "}";
  }
  o << "],\n  \"crashed\": [";
  for (std::size_t i = 0; i < r.crashed.size(); ++i) o << (i ? ", " : "") << jsonString(r.crashed[i]);
  o << "],\n  \"checks\": [";
  for (std::size_t i = 0; i < r.checks.size(); ++i) {
    o << (i ? ",\n    " : "\n    ") << "{\"name\": " << jsonString(r.checks[i].name)
      << ", \"passed\": " << (r.checks[i].passed ? "true" : "false") << ", \"detail\": " << jsonString(r.checks[i].detail) << "}";
  }
  o << "],\n  \"passed\": " << (r.passed() ? "true" : "false") << "\n}\n";
  return o.str();
}

std::string summary(const FaultReport& r) {
  std::ostringstream o;
  o << std::fixed << std::setprecision(1);
  o << "faults " << r.scenario << " on " << r.topology << " (" << r.edges << " edges, period " << r.period_ms
    << " ms, seed " << r.seed << ", " << r.duration_s << " s)\n";
  if (!r.fault.empty()) o << "  fault: " << r.fault << "\n";
  for (const FaultEvent& e : r.events) o << "  event: " << e.what << " " << e.node << "\n";
  o << "  root: " << r.epochs_in_window - r.epochs_unpublished << " of " << r.epochs_in_window
    << " epochs published, longest silence " << r.max_silence_ms << " ms, " << r.late_publications << " late of "
    << r.publications << " publications, " << r.out_of_order << " out of order; " << r.root_caught_up
    << " caught up after stalls of the root (longest poll gap " << r.root_longest_poll_gap_ms << " ms)\n";
  if (!r.unpublished_examples.empty()) {
    o << "  never published (epochs after the first):";
    for (std::uint64_t e : r.unpublished_examples) o << " +" << e;
    o << "\n";
  }
  o << "  maps: " << r.maps_sent << " sent, " << r.maps_acknowledged << " acknowledged, " << r.maps_refused
    << " refused, " << r.maps_unsettled << " unsettled; " << r.maps_lost << " lost, " << r.maps_lost_in_fault
    << " lost in the faulty subtree during the fault; " << r.applied_twice << " applied twice (" << r.duplicates_recognised
    << " re-sent copies recognised); the root dropped " << r.observer_drops << " global maps of the harness's subscription\n";
  if (!r.lost_examples.empty()) {
    o << "  lost:";
    for (const std::string& l : r.lost_examples) o << " " << l << ";";
    o << "\n";
  }
  o << "  oracle: " << r.publications_mismatched << " of " << r.publications_checked
    << " global maps differ from the specification\n";
  o << "  end-to-end: p50 " << r.e2e_p50_ms << " ms, p99 " << r.e2e_p99_ms << " ms; largest RSS growth after warm-up "
    << r.max_rss_growth_kib / 1024.0 << " MiB\n";
  for (double n : r.missing_notice_ms) o << "  marked missing after " << n << " ms\n";
  for (std::size_t i = 0; i < r.rejoin_ms.size(); ++i) {
    o << "  restarted edge up after " << (i < r.restart_startup_ms.size() ? r.restart_startup_ms[i] : -1.0)
      << " ms, merged again " << r.rejoin_ms[i] << " ms after that\n";
  }
  if (r.child_notice_ms) o << "  children noticed the stall after " << *r.child_notice_ms << " ms\n";
  if (!r.after_heal.empty()) {
    o << "  epochs after the heal (w whole, i an acknowledged map missing, - unpublished, ! differs):";
    for (const std::string& e : r.after_heal) o << " " << e;
    o << "\n";
  }
  if (r.recovery_ms) {
    o << "  recovered " << *r.recovery_ms << " ms after the heal; " << r.epochs_after_recovery
      << " epochs after it, each holding every acknowledged map and equal to the specification\n";
  }
  o << "  phases:";
  for (const auto& [name, seconds] : r.phases) o << " " << name << " " << seconds << " s";
  o << "\n";
  for (const Check& c : r.checks) o << "  [" << (c.passed ? "ok" : "FAIL") << "] " << c.name << (c.detail.empty() ? "" : ": " + c.detail) << "\n";
  o << (r.passed() ? "PASSED\n" : "FAILED\n");
  return o.str();
}

}  // namespace fogmap::cli
