#pragma once
// The fault harness's plan (harness/faults.hpp): which nodes a scenario hits and when, chosen by
// the plan's seed, and how the fault reads in the report. Pure: no processes, no clock.
#include <chrono>
#include <span>
#include <string>
#include <vector>

#include "common/config/topology.hpp"
#include "harness/faults.hpp"

namespace fogmap::harness {

// A fault to inject: `at` after the load starts, `what` happens to `node`.
struct FaultAction {
  std::chrono::milliseconds at{0};
  std::string what;  // "kill", "restart" (a killed node), "stop" (a stall), "continue" (its end)
  std::string node;
  bool operator==(const FaultAction&) const = default;
};

// The scenario's actions in time order; the same plan and topology give the same actions.
// - soak: none.
// - edge-crash: min(edge_kills, edges) distinct edges, each killed at a time in [0.2, 0.5] of the
//   duration and restarted `downtime` later.
// - aggregator-crash, stall: one aggregator other than the root, killed (stopped) at a time in
//   [0.25, 0.4] of the duration and restarted (continued) `downtime` later; none without such an
//   aggregator (a star).
std::vector<FaultAction> planFaultActions(const TopologyConfig& topology, const FaultPlan& plan);

// How the fault is made, for the report: "kill -9 of 2 edge(s), each restarted after 3 s",
// "kill -9 of agg-1, restarted after 2 s", "SIGSTOP of agg-1 for 5 s" or, with StallMethod::kNetns,
// "iptables DROP of every packet of agg-1's network namespace for 5 s". Empty without actions.
std::string describeFault(const FaultPlan& plan, std::span<const FaultAction> actions);

}  // namespace fogmap::harness
