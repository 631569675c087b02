#pragma once
// The fault harness's observation (harness/faults.hpp): runs the topology as local processes under
// load, injects the planned faults, and records what happened, as data for the judge: every global
// map the root published (each checked against the oracle as it arrives), the faults as injected,
// restarts, processes that died, memory, the nodes' counters and the edges' delivery journals.
// Judges nothing.
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "harness/faults.hpp"
#include "harness/faults_plan.hpp"
#include "services/common/delivery_journal.hpp"

namespace fogmap::harness {

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

// The latest revision of an epoch, as checked.
struct EpochVerdict {
  std::uint32_t revision = 0;
  std::set<std::uint32_t> contributing;
  bool equal = false;  // equal to the oracle (or no oracle)
};

// A killed node started again: when the restart began and when its /metrics answered (the process
// is up), unix ns.
struct Restart {
  std::string node;
  std::int64_t commanded_ns = 0;
  std::int64_t ready_ns = 0;
};

// How an edge's uploads ended (every journal file of the node, restarts included).
struct EdgeJournal {
  std::uint32_t node = 0;
  std::string name;
  std::vector<JournalEntry> entries;
};

struct FaultObservation {
  // The root's publications in arrival order, every revision.
  std::vector<Publication> publications;
  // Per epoch, its latest revision checked against the oracle.
  std::map<std::uint64_t, EpochVerdict> verdicts;
  std::uint64_t checked = 0;       // publications checked against the oracle
  std::uint64_t mismatched = 0;    // of those, different from the specification
  std::uint64_t applied_twice = 0; // an ellipsoid id, or a contributing node, twice in one global map
  std::vector<std::string> problems;  // unreadable maps, mismatches, oracle errors (the first of them)

  std::uint64_t judged_from = 0;  // the first epoch begun once the subscription delivered
  std::int64_t start_ns = 0;      // the load, unix ns
  std::int64_t end_ns = 0;
  // The faults as injected, in order; a stall by network namespace shows "drop" and "restore"
  // where the plan says "stop" and "continue".
  std::vector<FaultEvent> events;
  std::vector<Restart> restarts;  // one per "restart" event, commanded_ns its at_ns
  // Stall: from the SIGSTOP (or drop) to the first child giving its stream to the parent up.
  std::optional<double> child_notice_ms;
  std::vector<std::string> crashed;  // processes that died without being killed
  bool warm_sampled = false;         // the RSS after the warm-up was sampled
  std::vector<ProcessMemory> memory; // processes running from the warm-up to the end, never restarted

  // Counters read from the nodes at the end of the load.
  std::uint64_t observer_drops = 0;         // the root: global maps dropped from the harness's subscription
  std::uint64_t root_caught_up = 0;         // the root: epochs published late after a stall of its own
  double root_longest_poll_gap_ms = 0.0;    // the root: the longest time between two polls of its emitter
  std::uint64_t duplicates_recognised = 0;  // every aggregator: re-sent copies recognised

  std::vector<EdgeJournal> journals;  // every edge, in the topology's order
  std::vector<std::pair<std::string, double>> phases;  // oracle, start, load, stop, in seconds
};

// Runs `topology` under `plan` with the planned `actions` (its files under dir/<name>/: topology,
// logs, journals). Errors: the cluster cannot start or publishes nothing within 10 s, a fault
// cannot be made (a network namespace, a restart), a journal cannot be read.
Expected<FaultObservation> observeFaults(const std::filesystem::path& dir, const TopologyConfig& topology, const FaultPlan& plan,
                                         std::span<const FaultAction> actions);

}  // namespace fogmap::harness
