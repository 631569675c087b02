// What fogctl demo reports (harness/demo_report), on hand-made runs and scores: which epochs are
// compared (the same scan, both complete), and the figures of its text and JSON report.
#include "harness/demo_report.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <utility>
#include <vector>

namespace fogmap::harness {
namespace {

GlobalMapMessage epochOf(bool complete) {
  GlobalMapMessage g;
  g.header.contributing_nodes = {1, 2};
  if (!complete) g.header.missing_nodes = {2};
  return g;
}

using Pairs = std::vector<std::pair<std::uint64_t, std::uint64_t>>;

TEST(DemoReport, ComparesEachCompleteEpochWithTheFirstCompleteBaselineEpochOfTheSameScan) {
  // 4 scans replayed in a loop: epoch e shows scan e mod 4.
  std::map<std::uint64_t, GlobalMapMessage> madc;
  for (std::uint64_t e = 10; e <= 15; ++e) madc.emplace(e, epochOf(e != 12));
  std::map<std::uint64_t, GlobalMapMessage> baseline;
  for (std::uint64_t e = 20; e <= 26; ++e) baseline.emplace(e, epochOf(e != 21 && e != 25));
  const EpochPairing p = pairEpochsByScan(madc, baseline, 4);
  // Scan 2: baseline 22 (26 came later); scan 3: 23; scan 1: 21 and 25 both incomplete, so MAD-C's
  // epoch 13 is compared with nothing; MAD-C's 12 is incomplete.
  EXPECT_EQ(p.compared, (Pairs{{10, 22}, {11, 23}, {14, 22}, {15, 23}}));
  EXPECT_EQ(p.incomplete, 1u);
}

TEST(DemoReport, NoScansOrNoBaselineGivesNothingToCompare) {
  std::map<std::uint64_t, GlobalMapMessage> madc{{1, epochOf(true)}, {2, epochOf(false)}};
  EXPECT_TRUE(pairEpochsByScan(madc, madc, 0).compared.empty());
  const EpochPairing p = pairEpochsByScan(madc, {}, 3);
  EXPECT_TRUE(p.compared.empty());
  EXPECT_EQ(p.incomplete, 1u);
}

RecordedScores twoEpochs() {
  RecordedScores s;
  s.published = 5;
  s.incomplete = 1;
  s.madc_bytes_per_frame = 2'000.0;
  s.baseline_bytes_per_frame = 290'000.0;
  s.wire.bytes = 2'850;  // 100 ellipsoids of 21.5 B, 40 of them with a 17.5 B view
  s.wire.view_bytes = 700;
  s.wire.exact_bytes = 5'300;
  s.wire.ellipsoids = 100;
  s.wire.views = 40;
  s.rand_index = 0.98;
  s.adjusted_rand_index = 0.9;
  s.rand_index_points = 0.97;
  s.latencies.merge_ms = {1.0, 3.0};
  s.latencies.e2e_ms = {40.0, 60.0};
  s.latencies.e2e_all_ms = {40.0, 60.0, 200.0};
  RecordedEpoch a;
  a.epoch = 7;
  a.scan = 3;
  a.objects = 12;
  a.baseline_objects = 13;
  a.madc_bytes = 500;
  a.baseline_bytes = 50'000;
  a.accuracy.ok = true;
  a.accuracy.clusters.rand_index = 0.98;
  RecordedEpoch b = a;
  b.epoch = 8;
  b.accuracy.ok = false;
  b.accuracy.problem = "labels do not match";
  s.epochs = {a, b};
  return s;
}

TEST(DemoReport, RecordedTextHasARowPerComparedEpochAndTheRatiosOfTheBytes) {
  const std::string text = recordedScoresText(twoEpochs());
  EXPECT_NE(text.find("           7     3       12       13          500          50000     100x"), std::string::npos) << text;
  EXPECT_NE(text.find("(labels do not match)"), std::string::npos) << text;
  EXPECT_NE(text.find("5 epochs published by MAD-C (1 incomplete"), std::string::npos) << text;
  EXPECT_NE(text.find("2 compared with the baseline"), std::string::npos) << text;
  EXPECT_NE(text.find("MAD-C 2000 B   baseline 290000 B   ratio 145x"), std::string::npos) << text;
  EXPECT_NE(text.find("ellipsoids on the wire:      21.5 B each in the edges' map uploads (53.0 B were they sent as "
                      "float32)"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("their boxes and classes:     7.0 B an ellipsoid more: 40 % of them carry one, 17.5 B each"),
            std::string::npos)
      << text;
}

TEST(DemoReport, RecordedReportHoldsTheSameFigures) {
  const Json j = recordedReport(twoEpochs());
  EXPECT_EQ(j.at("frames"), 2);
  EXPECT_EQ(j.at("epochs_published"), 5);
  EXPECT_EQ(j.at("epochs_incomplete"), 1);
  EXPECT_DOUBLE_EQ(j.at("bytes_ratio").get<double>(), 145.0);
  EXPECT_DOUBLE_EQ(j.at("bytes_per_ellipsoid").get<double>(), 21.5);
  EXPECT_DOUBLE_EQ(j.at("bytes_per_ellipsoid_exact_wire").get<double>(), 53.0);
  EXPECT_DOUBLE_EQ(j.at("view_bytes_per_ellipsoid").get<double>(), 7.0);
  EXPECT_DOUBLE_EQ(j.at("ellipsoids_with_views").get<double>(), 0.4);
  EXPECT_DOUBLE_EQ(j.at("rand_index_mean").get<double>(), 0.98);
  EXPECT_DOUBLE_EQ(j.at("merge_p99_ms").get<double>(), percentile({1.0, 3.0}, 0.99));
  EXPECT_DOUBLE_EQ(j.at("e2e_all_epochs_p99_ms").get<double>(), percentile({40.0, 60.0, 200.0}, 0.99));
}

TEST(DemoReport, TheWireCostSumsEdgeViewsAndCountsTheViewsApart) {
  EdgeView a;
  a.madc_bytes = 300;  // 10 ellipsoids: 200 B of records and upload, 100 B of views on 5 of them
  a.madc_view_bytes = 100;
  a.madc_exact_bytes = 600;
  a.madc_ellipsoids = 10;
  a.madc_views = 5;
  EdgeView b;
  b.madc_bytes = 220;  // 10 more ellipsoids, no view
  b.madc_exact_bytes = 500;
  b.madc_ellipsoids = 10;
  MapWireCost c;
  c.add(a);
  c.add(b);
  EXPECT_DOUBLE_EQ(c.bytesPerEllipsoid(), (200.0 + 220.0) / 20.0);
  EXPECT_DOUBLE_EQ(c.viewBytesPerEllipsoid(), 100.0 / 20.0);
  EXPECT_DOUBLE_EQ(c.exactBytesPerEllipsoid(), 1'100.0 / 20.0);
  EXPECT_DOUBLE_EQ(c.viewShare(), 0.25);
  EXPECT_DOUBLE_EQ(c.bytesPerFrame(2), 520.0 / 2.0);
  EXPECT_DOUBLE_EQ(c.viewBytesPerFrame(2), 100.0 / 2.0);
  EXPECT_DOUBLE_EQ(MapWireCost{}.bytesPerEllipsoid(), 0.0) << "no ellipsoid, no division by zero";
}

TEST(DemoReport, SceneTextAndReportGiveTheBytesAgainstTheBaselineAndTheRawScans) {
  SceneScores s;
  s.frames = 9;
  s.frames_vs_baseline = 8;
  s.madc_bytes_per_frame = 50.0;
  s.baseline_bytes_per_frame = 500.0;
  s.raw_bytes_per_frame = 5'000.0;
  s.madc_objects.objects_true = 20;
  s.madc_objects.found_whole = 17;
  s.madc_objects.missed = 3;
  const std::string text = sceneScoresText(s);
  EXPECT_NE(text.find("9 complete frames scored against the truth, 8 against the baseline"), std::string::npos) << text;
  EXPECT_NE(text.find("ratio 10x   (raw scans 5000 B: 100x)"), std::string::npos) << text;
  EXPECT_NE(text.find("20: found whole 17, split 0, merged 0, missed 3 (MAD-C)"), std::string::npos) << text;
  EXPECT_EQ(text.find("their boxes and classes"), std::string::npos) << "no view was shipped\n" << text;
  EXPECT_EQ(text.find("of which views"), std::string::npos) << text;
  const Json j = sceneScoresReport(s);
  EXPECT_DOUBLE_EQ(j.at("bytes_ratio").get<double>(), 10.0);
  EXPECT_DOUBLE_EQ(j.at("bytes_views_per_frame").get<double>(), 0.0);
  EXPECT_EQ(j.at("objects_missed"), 3);
  EXPECT_EQ(j.at("frames_vs_baseline"), 8);
}

TEST(DemoReport, SceneTextGivesTheRatiosWithoutTheViewsToo) {
  SceneScores s;
  s.frames = 9;
  s.madc_bytes_per_frame = 50.0;
  s.baseline_bytes_per_frame = 480.0;
  s.raw_bytes_per_frame = 5'000.0;
  s.madc_wire.bytes = 450;
  s.madc_wire.view_bytes = 90;  // 10 B a frame of the 50
  s.madc_wire.ellipsoids = 18;
  s.madc_wire.views = 9;
  const std::string text = sceneScoresText(s);
  EXPECT_NE(text.find("of which views 10 B; without them 40 B: 12x the baseline, 125x the raw scans"), std::string::npos)
      << text;
  EXPECT_NE(text.find("their boxes and classes:       5.0 B an ellipsoid more: 50 % of them carry one, 10.0 B each"),
            std::string::npos)
      << text;
  EXPECT_DOUBLE_EQ(sceneScoresReport(s).at("bytes_views_per_frame").get<double>(), 10.0);
}

}  // namespace
}  // namespace fogmap::harness
