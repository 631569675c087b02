#pragma once
// The fault harness: runs a topology as local processes, injects one kind of fault at seeded
// times, and judges the root's global maps against what the edges sent and against the
// specification. Shared by `fogctl faults` and the integration tests, so a user can run the same
// faults against their own topology.
//
// What it measures, for every scenario:
// - sent vs applied: each edge journals how every upload ended (services/common/delivery_journal);
//   a map its parent acknowledged (applied or late) must appear at the root (its node among the
//   contributing nodes of a publication of that epoch). Maps acknowledged by an aggregator that
//   was then killed, for epochs it had not emitted yet, are counted apart (lost in the fault).
// - applied twice: an ellipsoid id twice in one global map, or a node twice among its
//   contributing nodes.
// - the oracle: every publication of the root (every revision) must equal mergeSpecification over
//   the local maps of its contributing nodes, recomputed from the same scans with the same code.
// - liveness: epochs the root never published, the longest silence between publications, and any
//   process that died without being killed.
// - latency (sensor timestamp to first publication, complete epochs) and RSS growth per process
//   after the warm-up.
// Scenarios add what their fault calls for (see FaultReport).
//
// runFaults composes four units: faults_plan (which nodes and when, from the seed; pure),
// faults_observe (the cluster under load and the faults as injected, recorded as data),
// faults_judge (the figures and checks from that data; pure) and faults_report (toJson, summary).
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"

namespace fogmap::harness {

enum class FaultScenario {
  kSoak,             // no fault: load held for the duration
  kEdgeCrash,        // kill -9 of `edge_kills` edges at seeded times, each restarted after `downtime`
  kAggregatorCrash,  // kill -9 of one non-root aggregator at a seeded time, restarted after `downtime`
  kStall,            // SIGSTOP of one non-root aggregator for `downtime`, then SIGCONT
};
const char* scenarioName(FaultScenario scenario);
std::optional<FaultScenario> parseScenario(const std::string& name);

// How a stall is made: SIGSTOP of the process, or an iptables DROP of every packet of a network
// namespace the process runs in (harness/netns.hpp; needs root, ip and iptables).
enum class StallMethod { kSigstop, kNetns };
const char* stallMethodName(StallMethod method);

struct FaultPlan {
  FaultScenario scenario = FaultScenario::kSoak;
  std::chrono::milliseconds duration{60000};  // the load, from the moment every node is ready
  std::chrono::milliseconds warmup{20000};    // RSS growth is measured from here to the end
  std::uint64_t seed = 1;
  int edge_kills = 2;
  std::chrono::milliseconds downtime{3000};   // crash: until the restart; stall: SIGSTOP to SIGCONT
  bool check_oracle = true;                   // needs mode madc
  StallMethod stall_method = StallMethod::kSigstop;
  std::string identity = "operator";  // with TLS, the client certificate the harness subscribes with
};

struct FaultEvent {
  std::string what;  // "kill", "restart", "stop", "continue", "drop", "restore"
  std::string node;
  std::int64_t at_ns = 0;  // unix time
};

struct ProcessMemory {
  std::string node;
  std::int64_t rss_after_warmup_kib = 0;
  std::int64_t rss_end_kib = 0;
};

struct Check {
  std::string name;
  bool passed = false;
  std::string detail;
};

struct FaultReport {
  std::string topology;
  std::string scenario;
  std::string fault;  // how the fault was made, e.g. "SIGSTOP of agg-4 for 5 s"
  std::uint64_t seed = 0;
  double duration_s = 0.0;
  int edges = 0;
  double period_ms = 0.0;
  double root_deadline_ms = 0.0;  // the root emits epoch k at k period + this

  // Liveness of the root.
  std::uint64_t epochs_in_window = 0;   // epochs from the first published to the last loaded one
  std::uint64_t epochs_unpublished = 0; // of those, never published
  std::vector<std::uint64_t> unpublished_examples;  // the first of them, counted from the first epoch
  double max_silence_ms = 0.0;          // longest time without a publication while loaded
  std::uint64_t publications = 0;       // every revision counted
  std::uint64_t late_publications = 0;
  std::uint64_t out_of_order = 0;       // first publications of an epoch older than one published before
  std::uint64_t root_caught_up = 0;     // epochs the root published late after a stall of its own
  double root_longest_poll_gap_ms = 0.0;  // the longest time between two polls of the root's emitter

  // Sent vs applied.
  std::uint64_t maps_sent = 0;           // map uploads journalled by the edges
  std::uint64_t maps_acknowledged = 0;   // answered applied or late
  std::uint64_t maps_refused = 0;
  std::uint64_t maps_unsettled = 0;      // dropped, or abandoned by a stopped edge
  std::uint64_t maps_lost = 0;           // acknowledged, absent at the root, outside any fault window
  // Acknowledged in the subtree of a killed or stopped aggregator during the fault: by it before
  // it was killed, or by the aggregators below it, whose uploads waited until too old to admit.
  std::uint64_t maps_lost_in_fault = 0;
  // The first maps lost: "NODE epoch +K (OUTCOME)", K counted from the first epoch of the load.
  std::vector<std::string> lost_examples;
  std::uint64_t applied_twice = 0;
  std::uint64_t duplicates_recognised = 0;  // re-sent copies the aggregators recognised (metrics)
  std::uint64_t observer_drops = 0;  // global maps the root dropped from the harness's subscription

  // The oracle.
  std::uint64_t publications_checked = 0;
  std::uint64_t publications_mismatched = 0;

  double e2e_p50_ms = 0.0;
  double e2e_p99_ms = 0.0;
  std::vector<ProcessMemory> memory;
  double max_rss_growth_kib = 0.0;

  std::vector<FaultEvent> events;
  std::vector<std::string> crashed;  // processes that died without being killed
  // Faults: time from the fault to the first global map marking the node's sensors missing, and
  // from the restart / SIGCONT to the first epoch from which every epoch is whole again.
  std::vector<double> missing_notice_ms;
  // Edge crash: from the restarted edge serving /metrics again (its process is up) to its first
  // merged map; and the start-up before it (restart command to /metrics answering).
  std::vector<double> rejoin_ms;
  std::vector<double> restart_startup_ms;
  std::optional<double> recovery_ms;   // aggregator crash, stall
  std::optional<double> child_notice_ms;  // stall: the children's links give the stream up
  // Epochs from the recovery to the end of the load: each one whole, i.e. its latest publication
  // holds every map the edges' parents acknowledged for it and equals the specification (the
  // fault-free result of what was sent); the recovery is the first epoch from which that holds.
  std::uint64_t epochs_after_recovery = 0;
  // The first epochs after the heal, as the root left them: "w" whole, "i" an acknowledged map
  // missing, "-" never published, with "!" when the map differs from the specification.
  std::vector<std::string> after_heal;

  // How long each phase of the harness took (oracle, start, load, stop), in seconds.
  std::vector<std::pair<std::string, double>> phases;

  std::vector<Check> checks;
  bool passed() const;
};

// Runs the plan on `topology` (its files under dir/<name>/: topology, logs, journals, report).
Expected<FaultReport> runFaults(const std::filesystem::path& dir, const TopologyConfig& topology, const FaultPlan& plan);

// The report as JSON (every figure, the events and the checks) and as text, one figure a line
// (harness/faults_report.cpp).
std::string toJson(const FaultReport& report);
std::string summary(const FaultReport& report);

}  // namespace fogmap::harness
