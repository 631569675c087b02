// The fault harness's composition: plan, observe, judge (harness/faults_*.hpp).
#include "harness/faults.hpp"

#include <algorithm>

#include "common/base/epochs.hpp"
#include "harness/faults_judge.hpp"
#include "harness/faults_observe.hpp"
#include "harness/faults_plan.hpp"

namespace fogmap::harness {

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

const char* stallMethodName(StallMethod method) {
  return method == StallMethod::kNetns ? "netns" : "sigstop";
}

bool FaultReport::passed() const {
  return std::all_of(checks.begin(), checks.end(), [](const Check& c) { return c.passed; });
}

Expected<FaultReport> runFaults(const std::filesystem::path& dir, const TopologyConfig& topology, const FaultPlan& plan) {
  if (topology.root() == nullptr) return invalidArgument("the topology has no root");
  const auto schedule = EpochSchedule::create(topology.period_ms, topology.deadline_ms);
  if (!schedule) return schedule.error();
  const std::vector<FaultAction> actions = planFaultActions(topology, plan);
  const auto seen = observeFaults(dir, topology, plan, actions);
  if (!seen) return seen.error();
  FaultReport report = judgeFaults(topology, plan, *schedule, *seen);
  report.fault = describeFault(plan, actions);
  return report;
}

}  // namespace fogmap::harness
