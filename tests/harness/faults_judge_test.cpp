// The fault harness's judgement (harness/faults_judge) on observations made by hand: every figure
// and verdict below is worked out on paper from the epochs (period 100 ms, the root emitting at
// k P + 160 ms), the publications and the journals given.
#include "harness/faults_judge.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <set>
#include <string>
#include <vector>

#include "tests/harness/fault_topologies.hpp"
#include "tests/support/epoch_times.hpp"

namespace fogmap::harness {
namespace {

using namespace std::chrono_literals;
using fault_fixtures::treeOfFour;

using test_support::kMs;

std::int64_t startOf(std::uint64_t epoch) { return static_cast<std::int64_t>(epoch) * 100 * kMs; }

EpochSchedule epochs() { return *EpochSchedule::create(100.0, 80.0); }

// The epochs [first, last] loaded and judged: the load starts with `first` and ends 50 ms into the
// epoch after `last`. Every edge has a journal, empty.
FaultObservation loaded(std::uint64_t first, std::uint64_t last) {
  FaultObservation seen;
  seen.judged_from = first;
  seen.start_ns = startOf(first);
  seen.end_ns = startOf(last + 1) + 50 * kMs;
  seen.warm_sampled = true;
  for (std::uint32_t edge = 1; edge <= 4; ++edge) seen.journals.push_back({edge, "edge-" + std::to_string(edge), {}});
  return seen;
}

// The first publication of `epoch`, `delay_ms` after the epoch began (its sensor time), and the
// oracle's verdict on it.
void publish(FaultObservation& seen, std::uint64_t epoch, std::set<std::uint32_t> contributing, std::set<std::uint32_t> missing = {},
             std::int64_t delay_ms = 170, bool equal = true) {
  Publication p;
  p.epoch = epoch;
  p.published_ns = startOf(epoch) + delay_ms * kMs;
  p.sensor_ns = startOf(epoch);
  p.received_ns = p.published_ns;
  p.contributing = contributing;
  p.missing = std::move(missing);
  seen.publications.push_back(p);
  seen.verdicts[epoch] = {0, std::move(contributing), equal};
  ++seen.checked;
  if (!equal) ++seen.mismatched;
}

// `edge` journalled its map of every epoch in [first, last] with `outcome`.
void journal(FaultObservation& seen, std::uint32_t edge, std::uint64_t first, std::uint64_t last, Outcome outcome) {
  for (std::uint64_t e = first; e <= last; ++e) seen.journals[edge - 1].entries.push_back({e, "map", outcome});
}

const Check* checkNamed(const FaultReport& report, const std::string& name) {
  const auto it = std::find_if(report.checks.begin(), report.checks.end(), [&](const Check& c) { return c.name == name; });
  return it == report.checks.end() ? nullptr : &*it;
}

// The plan the judge is handed: `scenario` over 10 s, seed 3.
FaultPlan judgedPlanOf(FaultScenario scenario) {
  FaultPlan plan;
  plan.scenario = scenario;
  plan.duration = 10s;
  plan.seed = 3;
  return plan;
}

TEST(FaultsJudge, AFaultFreeRunPassesEveryCheckWithItsFiguresCountedByHand) {
  FaultObservation seen = loaded(1000, 1009);
  // Every epoch published once, whole, 170 to 179 ms after its sensor time.
  for (std::uint64_t e = 1000; e <= 1009; ++e) publish(seen, e, {1, 2, 3, 4}, {}, 170 + static_cast<std::int64_t>(e - 1000));
  // Each edge's maps of 999 (before the judged window) to 1009 applied; one more refused and one
  // unsettled; an upload of points is no map.
  for (std::uint32_t edge = 1; edge <= 4; ++edge) journal(seen, edge, 999, 1009, Outcome::kApplied);
  seen.journals[1].entries.push_back({1003, "map", Outcome::kRefused});
  seen.journals[2].entries.push_back({1004, "map", Outcome::kUnsettled});
  seen.journals[3].entries.push_back({1005, "points", Outcome::kApplied});
  seen.memory = {{"edge-1", 1000, 1500}, {"sink", 2000, 1800}};

  const FaultReport r = judgeFaults(treeOfFour(), judgedPlanOf(FaultScenario::kSoak), epochs(), seen);
  EXPECT_EQ(r.topology, "tree-4");
  EXPECT_EQ(r.scenario, "soak");
  EXPECT_EQ(r.edges, 4);
  EXPECT_DOUBLE_EQ(r.duration_s, 10.0);
  EXPECT_DOUBLE_EQ(r.root_deadline_ms, 160.0) << "two levels of aggregators, 80 ms each";
  EXPECT_EQ(r.epochs_in_window, 10U);
  EXPECT_EQ(r.epochs_unpublished, 0U);
  EXPECT_EQ(r.publications, 10U);
  EXPECT_EQ(r.out_of_order, 0U);
  EXPECT_EQ(r.maps_sent, 42U) << "10 per edge, the refused and the unsettled one";
  EXPECT_EQ(r.maps_acknowledged, 40U);
  EXPECT_EQ(r.maps_refused, 1U);
  EXPECT_EQ(r.maps_unsettled, 1U);
  EXPECT_EQ(r.maps_lost, 0U);
  EXPECT_EQ(r.maps_lost_in_fault, 0U);
  EXPECT_NEAR(r.max_silence_ms, 101.0, 1e-9) << "one period and the 1 ms each publication comes later";
  EXPECT_NEAR(r.e2e_p50_ms, 174.0, 1e-9) << "the 5th of 170 .. 179";
  EXPECT_NEAR(r.e2e_p99_ms, 179.0, 1e-9);
  EXPECT_DOUBLE_EQ(r.max_rss_growth_kib, 500.0) << "edge-1 grew 500 KiB; the sink shrank";
  EXPECT_TRUE(r.missing_notice_ms.empty());
  EXPECT_FALSE(r.recovery_ms.has_value());
  EXPECT_EQ(r.checks.size(), 9U) << "7 for every run, the oracle's, and the soak's memory";
  for (const Check& c : r.checks) EXPECT_TRUE(c.passed) << c.name << ": " << c.detail;
  EXPECT_TRUE(r.passed());
}

TEST(FaultsJudge, ALostMapAnUnpublishedEpochAndAnEpochPublishedOutOfOrderFailTheirChecks) {
  FaultObservation seen = loaded(1000, 1009);
  for (std::uint64_t e : {1000, 1001, 1002, 1003, 1004, 1006, 1008}) publish(seen, e, {1, 2, 3, 4});
  publish(seen, 1007, {2, 3, 4}, {1});  // after 1008, and without edge-1's map
  publish(seen, 1009, {1, 2, 3, 4});
  for (std::uint32_t edge = 1; edge <= 4; ++edge) {
    journal(seen, edge, 1000, 1004, Outcome::kApplied);
    journal(seen, edge, 1005, 1005, Outcome::kUnsettled);  // no edge got 1005 through
    journal(seen, edge, 1006, 1009, Outcome::kApplied);    // edge-1's 1007 among them
  }

  const FaultReport r = judgeFaults(treeOfFour(), judgedPlanOf(FaultScenario::kSoak), epochs(), seen);
  EXPECT_EQ(r.epochs_in_window, 10U);
  EXPECT_EQ(r.epochs_unpublished, 1U);
  EXPECT_EQ(r.unpublished_examples, (std::vector<std::uint64_t>{5})) << "1005, counted from 1000";
  EXPECT_EQ(r.out_of_order, 1U) << "1007 came after 1008";
  EXPECT_EQ(r.maps_lost, 1U);
  EXPECT_EQ(r.lost_examples, (std::vector<std::string>{"edge-1 epoch +7 (applied)"}));
  EXPECT_NEAR(r.max_silence_ms, 200.0, 1e-9) << "from 1004's publication to 1006's";
  EXPECT_NEAR(r.e2e_p99_ms, 170.0, 1e-9) << "the whole epochs only";

  const Check* every_epoch = checkNamed(r, "the root published every epoch");
  ASSERT_NE(every_epoch, nullptr);
  EXPECT_FALSE(every_epoch->passed);
  EXPECT_EQ(every_epoch->detail.rfind("1 of 10 unpublished +5; ", 0), 0U) << every_epoch->detail;
  for (const char* failed : {"the root published the epochs in order", "no acknowledged map lost"}) {
    ASSERT_NE(checkNamed(r, failed), nullptr) << failed;
    EXPECT_FALSE(checkNamed(r, failed)->passed) << failed;
  }
  for (const char* held : {"the root was never silent for longer than a period and its deadline", "no map applied twice",
                           "every global map equals the specification", "no process died unless killed"}) {
    ASSERT_NE(checkNamed(r, held), nullptr) << held;
    EXPECT_TRUE(checkNamed(r, held)->passed) << held << ": " << checkNamed(r, held)->detail;
  }
  EXPECT_FALSE(r.passed());
}

// The longest silence the schedule allows is a period plus the root's deadline (160 ms here), and
// 100 ms of slack: epochs published whole 5 ms after they began, then from 1005 on at their
// deadline (a child gone quiet) is a silence of 255 ms and holds; 300 ms after it does not.
TEST(FaultsJudge, TheRootMaySilentlyWaitForItsDeadlineButNoLonger) {
  const std::string name = "the root was never silent for longer than a period and its deadline";
  FaultObservation waited = loaded(1000, 1009);
  for (std::uint64_t e = 1000; e <= 1009; ++e) publish(waited, e, {1, 2, 3, 4}, {}, e >= 1005 ? 160 : 5);
  for (std::uint32_t edge = 1; edge <= 4; ++edge) journal(waited, edge, 1000, 1009, Outcome::kApplied);
  const FaultReport held = judgeFaults(treeOfFour(), judgedPlanOf(FaultScenario::kSoak), epochs(), waited);
  EXPECT_NEAR(held.max_silence_ms, 255.0, 1e-9) << "1004 at +5 ms, 1005 at its deadline +160 ms";
  ASSERT_NE(checkNamed(held, name), nullptr);
  EXPECT_TRUE(checkNamed(held, name)->passed) << checkNamed(held, name)->detail;

  FaultObservation stalled = loaded(1000, 1009);
  for (std::uint64_t e = 1000; e <= 1009; ++e) publish(stalled, e, {1, 2, 3, 4}, {}, e >= 1005 ? 460 : 5);
  for (std::uint32_t edge = 1; edge <= 4; ++edge) journal(stalled, edge, 1000, 1009, Outcome::kApplied);
  const FaultReport failed = judgeFaults(treeOfFour(), judgedPlanOf(FaultScenario::kSoak), epochs(), stalled);
  EXPECT_NEAR(failed.max_silence_ms, 555.0, 1e-9);
  ASSERT_NE(checkNamed(failed, name), nullptr);
  EXPECT_FALSE(checkNamed(failed, name)->passed);
  EXPECT_NE(checkNamed(failed, name)->detail.find("bound 360"), std::string::npos) << checkNamed(failed, name)->detail;
}

TEST(FaultsJudge, AKilledAggregatorsSubtreeIsNoticedItsLossesCountedApartAndTheRootRecovers) {
  FaultObservation seen = loaded(1000, 1039);
  // agg-1 (edge-1 and edge-2) is killed 20 ms into epoch 1003; restarted 20 ms into 1005, it
  // answers at the start of 1006.
  const std::int64_t killed = startOf(1003) + 20 * kMs;
  seen.events = {{"kill", "agg-1", killed}, {"restart", "agg-1", startOf(1005) + 20 * kMs}};
  seen.restarts = {{"agg-1", startOf(1005) + 20 * kMs, startOf(1006)}};
  for (std::uint64_t e = 1000; e <= 1039; ++e) {
    if (e >= 1003 && e <= 1007) {
      publish(seen, e, {3, 4}, {1, 2});
    } else {
      publish(seen, e, {1, 2, 3, 4});
    }
  }
  for (std::uint32_t edge : {3U, 4U}) journal(seen, edge, 1000, 1039, Outcome::kApplied);
  for (std::uint32_t edge : {1U, 2U}) {
    journal(seen, edge, 1000, 1002, Outcome::kApplied);
    journal(seen, edge, 1003, 1007, Outcome::kUnsettled);
    journal(seen, edge, 1008, 1039, Outcome::kApplied);
  }
  // agg-1 acknowledged edge-1's 1003 before it died, and its new process edge-1's 1006, which the
  // root published without (its window then starts at 1001: 1003's start less agg-1's emission at
  // 80 + 100 ms; it ends with 1029, the epoch of the restart plus 2 s and 3 periods).
  seen.journals[0].entries.push_back({1003, "map", Outcome::kApplied});
  seen.journals[0].entries.push_back({1006, "map", Outcome::kApplied});

  const FaultReport r = judgeFaults(treeOfFour(), judgedPlanOf(FaultScenario::kAggregatorCrash), epochs(), seen);
  EXPECT_EQ(r.maps_lost, 0U);
  EXPECT_EQ(r.maps_lost_in_fault, 2U);
  EXPECT_TRUE(r.lost_examples.empty()) << "only maps lost outside a fault are examples";
  ASSERT_EQ(r.missing_notice_ms.size(), 1U);
  EXPECT_NEAR(r.missing_notice_ms[0], 150.0, 1e-9) << "1003 published at +170 ms, 150 ms after the kill";
  EXPECT_TRUE(r.rejoin_ms.empty()) << "rejoins are the edges'";
  // Healed when agg-1 answered (1006's start): 1006 lacks edge-1's acknowledged map, 1007 on is
  // whole; 1007 is emitted 100 + 160 ms after the heal.
  ASSERT_TRUE(r.recovery_ms.has_value());
  EXPECT_NEAR(*r.recovery_ms, 260.0, 1e-9);
  EXPECT_EQ(r.epochs_after_recovery, 33U) << "1007 to 1039";
  ASSERT_EQ(r.after_heal.size(), 34U) << "1006 to 1039";
  EXPECT_EQ(r.after_heal[0], "i");
  EXPECT_EQ(r.after_heal[1], "w");
  for (const Check& c : r.checks) EXPECT_TRUE(c.passed) << c.name << ": " << c.detail;
  ASSERT_NE(checkNamed(r, "the root converges to the fault-free maps after recovery"), nullptr);
  EXPECT_EQ(checkNamed(r, "the root converges to the fault-free maps after recovery")->detail, "260.000000 ms, then 33 epochs equal");
}

TEST(FaultsJudge, TheFaultWindowRunsFromTheVictimsLastEmissionToTheHealPlusBackoffAndAdmission) {
  FaultObservation seen = loaded(1000, 1039);
  // agg-1 killed 20 ms into 1003, up again at 1006's start: its window is 1001 (1003's start less
  // its emission at 80 + 100 ms) to 1029 (the heal plus 2 s and 3 periods).
  seen.events = {{"kill", "agg-1", startOf(1003) + 20 * kMs}, {"restart", "agg-1", startOf(1005)}};
  seen.restarts = {{"agg-1", startOf(1005), startOf(1006)}};
  for (std::uint64_t e = 1000; e <= 1039; ++e) {
    const bool without_edge1 = e == 1000 || e == 1001 || e == 1029 || e == 1030;
    publish(seen, e, without_edge1 ? std::set<std::uint32_t>{2, 3, 4} : std::set<std::uint32_t>{1, 2, 3, 4});
  }
  journal(seen, 1, 1000, 1039, Outcome::kApplied);

  const FaultReport r = judgeFaults(treeOfFour(), judgedPlanOf(FaultScenario::kAggregatorCrash), epochs(), seen);
  EXPECT_EQ(r.maps_lost_in_fault, 2U) << "1001 and 1029";
  EXPECT_EQ(r.maps_lost, 2U) << "1000 and 1030";
  EXPECT_EQ(r.lost_examples, (std::vector<std::string>{"edge-1 epoch +0 (applied)", "edge-1 epoch +30 (applied)"}));
}

TEST(FaultsJudge, AKilledEdgeIsNoticedAndItsRejoinIsTimedFromWhenItWasUpAgain) {
  FaultObservation seen = loaded(1000, 1019);
  // edge-3 is killed 20 ms into 1003, restarted 20 ms into 1006, and up 50 ms into 1007.
  seen.events = {{"kill", "edge-3", startOf(1003) + 20 * kMs}, {"restart", "edge-3", startOf(1006) + 20 * kMs}};
  seen.restarts = {{"edge-3", startOf(1006) + 20 * kMs, startOf(1007) + 50 * kMs}};
  for (std::uint64_t e = 1000; e <= 1019; ++e) {
    if (e >= 1003 && e <= 1007) {
      publish(seen, e, {1, 2, 4}, {3});
    } else {
      publish(seen, e, {1, 2, 3, 4});
    }
  }
  FaultPlan plan = judgedPlanOf(FaultScenario::kEdgeCrash);
  plan.edge_kills = 1;

  const FaultReport r = judgeFaults(treeOfFour(), plan, epochs(), seen);
  ASSERT_EQ(r.missing_notice_ms.size(), 1U);
  EXPECT_NEAR(r.missing_notice_ms[0], 150.0, 1e-9);
  ASSERT_EQ(r.rejoin_ms.size(), 1U);
  EXPECT_NEAR(r.rejoin_ms[0], 220.0, 1e-9) << "1008 published at +170 ms; the edge was up 50 ms into 1007";
  ASSERT_EQ(r.restart_startup_ms.size(), 1U);
  EXPECT_NEAR(r.restart_startup_ms[0], 130.0, 1e-9);
  EXPECT_FALSE(r.recovery_ms.has_value()) << "an edge's restart heals no aggregator";
  const Check* notice = checkNamed(r, "a killed edge is marked missing in time");
  ASSERT_NE(notice, nullptr);
  EXPECT_TRUE(notice->passed);
  EXPECT_EQ(notice->detail, "150.000000 ms, bound 360 ms") << "a period, the root's deadline and 100 ms of slack";
  EXPECT_TRUE(r.passed());

  // Never merged again: the check fails with the time it could not give.
  seen.publications.erase(std::remove_if(seen.publications.begin(), seen.publications.end(),
                                         [](const Publication& p) { return p.epoch > 1007; }),
                          seen.publications.end());
  const FaultReport never = judgeFaults(treeOfFour(), plan, epochs(), seen);
  ASSERT_EQ(never.rejoin_ms.size(), 1U);
  EXPECT_EQ(never.rejoin_ms[0], -1.0);
  const Check* rejoin = checkNamed(never, "a restarted edge is merged again within 2 s of being up");
  ASSERT_NE(rejoin, nullptr);
  EXPECT_FALSE(rejoin->passed);
}

TEST(FaultsJudge, AStallByNetworkNamespaceIsJudgedAsAStopAndNeedsTheChildrenToNoticeIt) {
  FaultObservation seen = loaded(1000, 1029);
  seen.events = {{"drop", "agg-2", startOf(1003)}, {"restore", "agg-2", startOf(1008)}};
  for (std::uint64_t e = 1000; e <= 1029; ++e) {
    if (e >= 1003 && e <= 1008) {
      publish(seen, e, {1, 2}, {3, 4});
    } else {
      publish(seen, e, {1, 2, 3, 4});
    }
  }
  seen.child_notice_ms = 900.0;
  const FaultReport r = judgeFaults(treeOfFour(), judgedPlanOf(FaultScenario::kStall), epochs(), seen);
  ASSERT_EQ(r.missing_notice_ms.size(), 1U);
  EXPECT_NEAR(r.missing_notice_ms[0], 170.0, 1e-9) << "1003 published at +170 ms, the drop at its start";
  // Healed at 1008's start, which is whole (no edge journalled anything): 0 + 160 ms.
  ASSERT_TRUE(r.recovery_ms.has_value());
  EXPECT_NEAR(*r.recovery_ms, 160.0, 1e-9);
  EXPECT_EQ(r.epochs_after_recovery, 22U) << "1008 to 1029";
  for (const Check& c : r.checks) EXPECT_TRUE(c.passed) << c.name << ": " << c.detail;

  seen.child_notice_ms.reset();
  const FaultReport unnoticed = judgeFaults(treeOfFour(), judgedPlanOf(FaultScenario::kStall), epochs(), seen);
  const Check* children = checkNamed(unnoticed, "the children notice the stall within 3 s");
  ASSERT_NE(children, nullptr);
  EXPECT_FALSE(children->passed);
  EXPECT_EQ(children->detail, "never");
}

TEST(FaultsJudge, MemoryIsBoundedOnlyWhenSampledAfterTheWarmUpAndWithin64MiB) {
  FaultObservation seen = loaded(1000, 1009);
  for (std::uint64_t e = 1000; e <= 1009; ++e) publish(seen, e, {1, 2, 3, 4});
  seen.memory = {{"agg-1", 10'000, 10'000 + 64 * 1024}};
  EXPECT_TRUE(checkNamed(judgeFaults(treeOfFour(), judgedPlanOf(FaultScenario::kSoak), epochs(), seen), "memory bounded after the warm-up")->passed)
      << "64 MiB exactly is within the bound";
  seen.memory[0].rss_end_kib += 1;
  const FaultReport grown = judgeFaults(treeOfFour(), judgedPlanOf(FaultScenario::kSoak), epochs(), seen);
  EXPECT_FALSE(checkNamed(grown, "memory bounded after the warm-up")->passed);
  EXPECT_EQ(checkNamed(grown, "memory bounded after the warm-up")->detail, "65537 KiB largest growth");
  seen.memory.clear();
  seen.warm_sampled = false;
  EXPECT_FALSE(checkNamed(judgeFaults(treeOfFour(), judgedPlanOf(FaultScenario::kSoak), epochs(), seen), "memory bounded after the warm-up")->passed)
      << "a run shorter than its warm-up measured nothing";
}

}  // namespace
}  // namespace fogmap::harness
