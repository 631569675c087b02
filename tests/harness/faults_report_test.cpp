// The fault harness's JSON report (harness/faults_report): every figure under the key and in the
// order the report has always used, numbers as numbers, absent figures as null.
#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "harness/faults.hpp"

namespace fogmap::harness {
namespace {

FaultReport aReport() {
  FaultReport r;
  r.topology = "tree-8";
  r.scenario = "edge-crash";
  r.fault = "kill -9 of 1 edge(s), each restarted after 3 s";
  r.seed = 7;
  r.duration_s = 25.0;
  r.edges = 8;
  r.period_ms = 100.0;
  r.root_deadline_ms = 450.0;
  r.epochs_in_window = 240;
  r.maps_sent = 1900;
  r.maps_acknowledged = 1890;
  r.e2e_p50_ms = 2.0 / 3.0;
  r.missing_notice_ms = {298.5};
  r.rejoin_ms = {-1.0};
  r.memory = {{"edge-1", 1000, 1200}};
  r.events = {{"kill", "edge-3", 1700000000000000000}};
  r.crashed = {"agg-1"};
  r.checks = {{"no acknowledged map lost", true, "0 lost"}, {"a restarted edge is merged again within 2 s of being up", false, "-1.000000 ms"}};
  return r;
}

TEST(FaultsReport, TheJsonReportHoldsEveryFigureUnderItsKeyInOrder) {
  const std::string text = toJson(aReport());
  ASSERT_EQ(text.back(), '\n');
  const auto j = nlohmann::ordered_json::parse(text);
  std::vector<std::string> keys;
  for (const auto& [key, value] : j.items()) keys.push_back(key);
  EXPECT_EQ(keys, (std::vector<std::string>{
                      "topology", "scenario", "fault", "seed", "duration_s", "edges", "period_ms", "root_deadline_ms",
                      "epochs_in_window", "epochs_unpublished", "max_silence_ms", "publications", "late_publications",
                      "out_of_order", "root_caught_up", "root_longest_poll_gap_ms", "maps_sent", "maps_acknowledged",
                      "maps_refused", "maps_unsettled", "maps_lost", "maps_lost_in_fault", "applied_twice",
                      "duplicates_recognised", "observer_drops", "publications_checked", "publications_mismatched",
                      "e2e_p50_ms", "e2e_p99_ms", "max_rss_growth_kib", "missing_notice_ms", "rejoin_ms",
                      "restart_startup_ms", "recovery_ms", "child_notice_ms", "epochs_after_recovery", "memory", "events",
                      "crashed", "checks", "passed"}));
  EXPECT_EQ(j["fault"], "kill -9 of 1 edge(s), each restarted after 3 s");
  EXPECT_EQ(j["seed"], 7);
  EXPECT_TRUE(j["maps_sent"].is_number_integer());
  EXPECT_EQ(j["maps_sent"], 1900);
  EXPECT_DOUBLE_EQ(j["duration_s"].get<double>(), 25.0);
  EXPECT_DOUBLE_EQ(j["e2e_p50_ms"].get<double>(), 0.6666666667) << "ten significant digits";
  EXPECT_EQ(j["missing_notice_ms"], nlohmann::ordered_json::parse("[298.5]"));
  EXPECT_EQ(j["rejoin_ms"], nlohmann::ordered_json::parse("[-1.0]"));
  EXPECT_TRUE(j["restart_startup_ms"].is_array() && j["restart_startup_ms"].empty());
  EXPECT_TRUE(j["recovery_ms"].is_null()) << "absent, not a number";
  EXPECT_TRUE(j["child_notice_ms"].is_null());
  EXPECT_EQ(j["memory"], nlohmann::ordered_json::parse(R"([{"node": "edge-1", "rss_after_warmup_kib": 1000, "rss_end_kib": 1200}])"));
  EXPECT_EQ(j["events"], nlohmann::ordered_json::parse(R"([{"what": "kill", "node": "edge-3", "at_ns": 1700000000000000000}])"));
  EXPECT_EQ(j["crashed"], nlohmann::ordered_json::parse(R"(["agg-1"])"));
  ASSERT_EQ(j["checks"].size(), 2U);
  EXPECT_EQ(j["checks"][1]["name"], "a restarted edge is merged again within 2 s of being up");
  EXPECT_EQ(j["checks"][1]["passed"], false);
  EXPECT_EQ(j["passed"], false) << "one check failed";
}

TEST(FaultsReport, AFigureThatIsNotANumberIsNullAndTextIsEscaped) {
  FaultReport r = aReport();
  r.max_silence_ms = std::numeric_limits<double>::quiet_NaN();
  r.recovery_ms = 260.0;
  r.fault = "a \"quoted\"\tfault";
  const std::string text = toJson(r);
  EXPECT_EQ(text.find("nan"), std::string::npos) << text;
  const auto j = nlohmann::ordered_json::parse(text);
  EXPECT_TRUE(j["max_silence_ms"].is_null());
  EXPECT_DOUBLE_EQ(j["recovery_ms"].get<double>(), 260.0);
  EXPECT_EQ(j["fault"], "a \"quoted\"\tfault");
}

}  // namespace
}  // namespace fogmap::harness
