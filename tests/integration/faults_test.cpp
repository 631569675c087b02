// Faults against a real cluster: a tree of 8 edges at 10 Hz under the fault harness
// (tools/fogctl/faults.hpp), the short forms of `fogctl faults`. Each run prints the harness's
// summary; every check of the harness must pass.
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <string>

#include "tests/support/free_ports.hpp"
#include "tools/fogctl/faults.hpp"
#include "tools/fogctl/netns.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
using cli::FaultPlan;
using cli::FaultReport;
using cli::FaultScenario;

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
  std::cout << cli::summary(report);
  ASSERT_FALSE(report.checks.empty());
  for (const cli::Check& c : report.checks) EXPECT_TRUE(c.passed) << c.name << ": " << c.detail;
}

FaultReport run(const std::string& name, const FaultPlan& plan) {
  auto report = cli::runFaults(scratchDir(), tree8(name), plan);
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
  EXPECT_GE(report.maps_acknowledged, 8U * 10U * 55U);  // 8 edges x 10 Hz, nearly all of a minute
}

TEST(Faults, KilledEdgesAreMarkedMissingAndMergedAgainAfterRestart) {
  FaultPlan plan;
  plan.scenario = FaultScenario::kEdgeCrash;
  plan.duration = 25s;
  plan.warmup = 5s;
  plan.seed = 7;
  plan.edge_kills = 2;
  plan.downtime = 3s;
  const FaultReport report = run("edge-crash", plan);
  expectAllChecksPass(report);
  EXPECT_EQ(report.missing_notice_ms.size(), 2U);
  EXPECT_EQ(report.rejoin_ms.size(), 2U);
}

TEST(Faults, AKilledAggregatorIsRestartedAndTheRootConvergesToTheFaultFreeMaps) {
  FaultPlan plan;
  plan.scenario = FaultScenario::kAggregatorCrash;
  plan.duration = 25s;
  plan.warmup = 5s;
  plan.seed = 3;
  plan.downtime = 2s;
  const FaultReport report = run("aggregator-crash", plan);
  expectAllChecksPass(report);
  EXPECT_TRUE(report.recovery_ms.has_value());
}

TEST(Faults, AStoppedAggregatorIsNoticedOnBothSidesAndTheRootConverges) {
  FaultPlan plan;
  plan.scenario = FaultScenario::kStall;
  plan.duration = 25s;
  plan.warmup = 5s;
  plan.seed = 5;
  plan.downtime = 5s;
  const FaultReport report = run("stall", plan);
  expectAllChecksPass(report);
  EXPECT_TRUE(report.child_notice_ms.has_value());
}

TEST(Faults, ALinkWhosePacketsAreDroppedIsNoticedOnBothSidesAndTheRootConverges) {
  // The same stall made by the network: the aggregator runs in a namespace of its own and every
  // packet in or out of it is dropped for 5 s (no FIN, no RST). Where namespaces cannot be made
  // (no root, no ip or iptables) the test says so and is skipped; the SIGSTOP form above runs.
  {
    auto probe = cli::NetnsLink::create(static_cast<unsigned>(::getpid()) + 1U);
    if (!probe) GTEST_SKIP() << "no network namespace here: " << probe.error().message;
  }
  FaultPlan plan;
  plan.scenario = FaultScenario::kStall;
  plan.stall_method = cli::StallMethod::kNetns;
  plan.duration = 25s;
  plan.warmup = 5s;
  plan.seed = 5;
  plan.downtime = 5s;
  const FaultReport report = run("stall-netns", plan);
  expectAllChecksPass(report);
  EXPECT_NE(report.fault.find("iptables DROP"), std::string::npos) << report.fault;
  EXPECT_TRUE(report.child_notice_ms.has_value());
}

}  // namespace
}  // namespace fogmap
