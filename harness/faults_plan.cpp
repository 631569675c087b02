#include "harness/faults_plan.hpp"

#include <algorithm>
#include <random>
#include <sstream>

namespace fogmap::harness {

std::vector<FaultAction> planFaultActions(const TopologyConfig& topology, const FaultPlan& plan) {
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
  std::vector<FaultAction> actions;
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
  std::sort(actions.begin(), actions.end(), [](const FaultAction& a, const FaultAction& b) { return a.at < b.at; });
  return actions;
}

std::string describeFault(const FaultPlan& plan, std::span<const FaultAction> actions) {
  if (actions.empty()) return {};
  const std::string& victim = actions.front().node;
  const double seconds = static_cast<double>(plan.downtime.count()) / 1000.0;
  std::ostringstream fault;
  if (plan.scenario == FaultScenario::kStall) {
    fault << (plan.stall_method == StallMethod::kNetns ? "iptables DROP of every packet of " + victim + "'s network namespace for "
                                                       : "SIGSTOP of " + victim + " for ")
          << seconds << " s";
  } else if (plan.scenario == FaultScenario::kAggregatorCrash) {
    fault << "kill -9 of " << victim << ", restarted after " << seconds << " s";
  } else {
    fault << "kill -9 of " << plan.edge_kills << " edge(s), each restarted after " << seconds << " s";
  }
  return fault.str();
}

}  // namespace fogmap::harness
