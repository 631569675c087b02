// The fault harness's plan (harness/faults_plan): which nodes a scenario hits, when, and how the
// fault reads, against bounds and texts worked out by hand from the plan.
#include "harness/faults_plan.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <set>
#include <string>
#include <vector>

#include "tests/harness/fault_topologies.hpp"

namespace fogmap::harness {
namespace {

using namespace std::chrono_literals;
using fault_fixtures::starOfThree;
using fault_fixtures::treeOfFour;

FaultPlan planOf(FaultScenario scenario, std::uint64_t seed = 7) {
  FaultPlan plan;
  plan.scenario = scenario;
  plan.duration = 10s;
  plan.downtime = 3s;
  plan.seed = seed;
  return plan;
}

TEST(FaultsPlan, ASoakInjectsNothing) {
  const auto actions = planFaultActions(treeOfFour(), planOf(FaultScenario::kSoak));
  EXPECT_TRUE(actions.empty());
  EXPECT_EQ(describeFault(planOf(FaultScenario::kSoak), actions), "");
}

TEST(FaultsPlan, EdgeCrashKillsDistinctEdgesInTheMiddleOfTheLoadAndRestartsEachAfterTheDowntime) {
  FaultPlan plan = planOf(FaultScenario::kEdgeCrash);
  plan.edge_kills = 2;
  const auto actions = planFaultActions(treeOfFour(), plan);
  ASSERT_EQ(actions.size(), 4U) << "a kill and a restart per edge";
  std::set<std::string> killed;
  for (const FaultAction& a : actions) {
    if (a.what != "kill") continue;
    killed.insert(a.node);
    EXPECT_EQ(a.node.rfind("edge-", 0), 0U) << a.node;
    // 0.2 and 0.5 of the 10 s load.
    EXPECT_GE(a.at, 2000ms) << a.node;
    EXPECT_LE(a.at, 5000ms) << a.node;
    int restarts = 0;
    for (const FaultAction& b : actions) {
      if (b.what == "restart" && b.node == a.node) {
        ++restarts;
        EXPECT_EQ(b.at, a.at + 3000ms) << a.node;
      }
    }
    EXPECT_EQ(restarts, 1) << a.node;
  }
  EXPECT_EQ(killed.size(), 2U) << "two different edges";
  for (std::size_t i = 1; i < actions.size(); ++i) EXPECT_LE(actions[i - 1].at, actions[i].at) << "in time order";
}

TEST(FaultsPlan, EdgeCrashKillsNoMoreEdgesThanThereAre) {
  FaultPlan plan = planOf(FaultScenario::kEdgeCrash);
  plan.edge_kills = 9;
  const auto actions = planFaultActions(treeOfFour(), plan);
  std::set<std::string> killed;
  for (const FaultAction& a : actions) {
    if (a.what == "kill") killed.insert(a.node);
  }
  EXPECT_EQ(actions.size(), 8U);
  EXPECT_EQ(killed, (std::set<std::string>{"edge-1", "edge-2", "edge-3", "edge-4"}));
}

TEST(FaultsPlan, AggregatorFaultsHitAnAggregatorBelowTheRootAndNothingInAStar) {
  for (const FaultScenario scenario : {FaultScenario::kAggregatorCrash, FaultScenario::kStall}) {
    const bool crash = scenario == FaultScenario::kAggregatorCrash;
    SCOPED_TRACE(scenarioName(scenario));
    const auto actions = planFaultActions(treeOfFour(), planOf(scenario));
    ASSERT_EQ(actions.size(), 2U);
    EXPECT_EQ(actions[0].what, crash ? "kill" : "stop");
    EXPECT_EQ(actions[1].what, crash ? "restart" : "continue");
    EXPECT_TRUE(actions[0].node == "agg-1" || actions[0].node == "agg-2") << actions[0].node << ": never the root";
    EXPECT_EQ(actions[1].node, actions[0].node);
    // 0.25 and 0.4 of the 10 s load; back 3 s later.
    EXPECT_GE(actions[0].at, 2500ms);
    EXPECT_LE(actions[0].at, 4000ms);
    EXPECT_EQ(actions[1].at, actions[0].at + 3000ms);
    EXPECT_TRUE(planFaultActions(starOfThree(), planOf(scenario)).empty()) << "a star has no aggregator but the root";
  }
}

TEST(FaultsPlan, TheSeedChoosesThePlanAndTheSameSeedTheSamePlan) {
  FaultPlan plan = planOf(FaultScenario::kEdgeCrash, 1);
  const auto once = planFaultActions(treeOfFour(), plan);
  EXPECT_EQ(planFaultActions(treeOfFour(), plan), once);
  plan.seed = 2;
  EXPECT_NE(planFaultActions(treeOfFour(), plan), once);
}

TEST(FaultsPlan, TheFaultReadsAsHowItIsMade) {
  FaultPlan crash = planOf(FaultScenario::kEdgeCrash);
  crash.edge_kills = 2;
  EXPECT_EQ(describeFault(crash, planFaultActions(treeOfFour(), crash)), "kill -9 of 2 edge(s), each restarted after 3 s");

  const std::vector<FaultAction> on_agg1 = {{1000ms, "kill", "agg-1"}, {3500ms, "restart", "agg-1"}};
  FaultPlan aggregator = planOf(FaultScenario::kAggregatorCrash);
  aggregator.downtime = 2500ms;
  EXPECT_EQ(describeFault(aggregator, on_agg1), "kill -9 of agg-1, restarted after 2.5 s");

  FaultPlan stall = planOf(FaultScenario::kStall);
  stall.downtime = 5s;
  EXPECT_EQ(describeFault(stall, on_agg1), "SIGSTOP of agg-1 for 5 s");
  stall.stall_method = StallMethod::kNetns;
  EXPECT_EQ(describeFault(stall, on_agg1), "iptables DROP of every packet of agg-1's network namespace for 5 s");
}

}  // namespace
}  // namespace fogmap::harness
