// Faults against a real cluster: a tree of 8 edges at 10 Hz under the fault harness
// (harness/faults.hpp), the short forms of `fogctl faults`. Each run prints the harness's
// summary; every check of the harness must pass.
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <string>

#include "tests/support/free_ports.hpp"
#include "harness/faults.hpp"
#include "harness/netns.hpp"
#include "common/config/topology_presets.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
using harness::FaultPlan;
using harness::FaultReport;
using harness::FaultScenario;

TopologyConfig tree8(const std::string& name) {
  constexpr int kAnyBasePort = 40000;  // replaced by free ports below
  TopologyConfig t = makeTreeTopology(8, std::filesystem::path(FOGMAP_SOURCE_DIR) / "data" / "kitti_raw_seq_a", kAnyBasePort);
  test_support::useFreePorts(t);
  t.name = name;
  // The root emits at 3 x 150 ms: room for the eight edges that read a whole KITTI scan each at
  // the same instant on two cores (the default 80 ms is measured by the documented long form).
  t.deadline_ms = 150.0;
  return t;
}

std::filesystem::path scratchDir() {
  const auto dir = std::filesystem::temp_directory_path() / ("fogmap-faults-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir;
}

void expectAllChecksPass(const FaultReport& report) {
  std::cout << harness::summary(report);
  ASSERT_FALSE(report.checks.empty());
  for (const harness::Check& c : report.checks) EXPECT_TRUE(c.passed) << c.name << ": " << c.detail;
}

// The short form of a fault: 25 s of load after a 5 s warm-up, the fault lasting `downtime`.
FaultPlan shortForm(FaultScenario scenario, std::uint64_t seed, std::chrono::seconds downtime) {
  FaultPlan plan;
  plan.scenario = scenario;
  plan.duration = 25s;
  plan.warmup = 5s;
  plan.seed = seed;
  plan.downtime = downtime;
  return plan;
}

FaultReport run(const std::string& name, const FaultPlan& plan) {
  auto report = harness::runFaults(scratchDir(), tree8(name), plan);
  EXPECT_TRUE(report.ok()) << (report ? "" : report.error().message);
  return report ? *report : FaultReport{};
}

TEST(Faults, SoakOfOneMinuteLosesNothingAppliesNothingTwiceAndHoldsMemory) {
  FaultPlan plan;
  plan.scenario = FaultScenario::kSoak;
  plan.duration = 60s;
  plan.warmup = 20s;
  const FaultReport report = run("soak", plan);
  expectAllChecksPass(report);
  // The load was applied: 8 edges x 10 Hz for a minute is 4,800 frames. On 2 cores the 8 virtual
  // LiDARs, each reading a whole KITTI scan, skip some frames (counted as skipped epochs; 74 to
  // 100 % shipped, depending on the machine): the floor (half the frames) checks that the load
  // ran, the checks above that nothing shipped was lost or applied twice.
  EXPECT_GE(report.maps_acknowledged, 8U * 10U * 30U);
}

TEST(Faults, KilledEdgesAreMarkedMissingAndMergedAgainAfterRestart) {
  FaultPlan plan = shortForm(FaultScenario::kEdgeCrash, 7, 3s);
  plan.edge_kills = 2;
  const FaultReport report = run("edge-crash", plan);
  expectAllChecksPass(report);
  EXPECT_EQ(report.missing_notice_ms.size(), 2U);
  EXPECT_EQ(report.rejoin_ms.size(), 2U);
}

TEST(Faults, AKilledAggregatorIsRestartedAndTheRootConvergesToTheFaultFreeMaps) {
  FaultPlan plan = shortForm(FaultScenario::kAggregatorCrash, 3, 2s);
  const FaultReport report = run("aggregator-crash", plan);
  expectAllChecksPass(report);
  EXPECT_TRUE(report.recovery_ms.has_value());
}

TEST(Faults, AStoppedAggregatorIsNoticedOnBothSidesAndTheRootConverges) {
  FaultPlan plan = shortForm(FaultScenario::kStall, 5, 5s);
  const FaultReport report = run("stall", plan);
  expectAllChecksPass(report);
  EXPECT_TRUE(report.child_notice_ms.has_value());
}

TEST(Faults, ALinkWhosePacketsAreDroppedIsNoticedOnBothSidesAndTheRootConverges) {
  // The same stall made by the network: the aggregator runs in a namespace of its own and every
  // packet in or out of it is dropped for 5 s (no FIN, no RST). Where namespaces cannot be made
  // (no root, no ip or iptables) the test says so and is skipped; the SIGSTOP form above runs.
  {
    auto probe = harness::NetnsLink::create(static_cast<unsigned>(::getpid()) + 1U);
    if (!probe) GTEST_SKIP() << "no network namespace here: " << probe.error().message;
  }
  FaultPlan plan = shortForm(FaultScenario::kStall, 5, 5s);
  plan.stall_method = harness::StallMethod::kNetns;
  const FaultReport report = run("stall-netns", plan);
  expectAllChecksPass(report);
  EXPECT_NE(report.fault.find("iptables DROP"), std::string::npos) << report.fault;
  EXPECT_TRUE(report.child_notice_ms.has_value());
}

}  // namespace
}  // namespace fogmap
