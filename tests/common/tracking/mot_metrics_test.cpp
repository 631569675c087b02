// Tracking metrics against hand-computed answers, and IDF1 against every one-to-one matching.
#include "common/tracking/mot_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <numbers>
#include <numeric>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace fogmap::tracking {
namespace {

constexpr double kTol = 1e-12;

MotObject objectAt(std::int64_t id, double x, double y) { return MotObject{id, Eigen::Vector2d(x, y)}; }

ClearMot clearOf(const std::vector<MotFrame>& frames, const MotConfig& config = {}) {
  Expected<ClearMot> result = clearMot(frames, config);
  EXPECT_TRUE(result.ok()) << result.error().message;
  return result.ok() ? result.value() : ClearMot{};
}

IdScores idOf(const std::vector<MotFrame>& frames, const MotConfig& config = {}) {
  Expected<IdScores> result = idScores(frames, config);
  EXPECT_TRUE(result.ok()) << result.error().message;
  return result.ok() ? result.value() : IdScores{};
}

// Two truth objects and two tracks that follow them exactly; after `swap_at` frames the tracks
// trade objects (truth 1 and 2 are 10 m apart, far beyond the gate).
std::vector<MotFrame> swappingTracks(int frames, int swap_at) {
  std::vector<MotFrame> out;
  for (int f = 0; f < frames; ++f) {
    const double x = f;
    const bool swapped = f >= swap_at;
    out.push_back(MotFrame{{objectAt(1, x, 0.0), objectAt(2, x, 10.0)},
                           {objectAt(10, x, swapped ? 10.0 : 0.0), objectAt(20, x, swapped ? 0.0 : 10.0)}});
  }
  return out;
}

TEST(MotMetrics, PerfectTrackingGivesMotaOneAndMotpTheConstantOffset) {
  // Every track sits (0.3, 0.4) from its object: 0.5 m off, always the same identity.
  std::vector<MotFrame> frames;
  for (int f = 0; f < 5; ++f) {
    frames.push_back(MotFrame{{objectAt(1, f, 0.0), objectAt(2, f, 5.0)}, {objectAt(7, f + 0.3, 0.4), objectAt(8, f + 0.3, 5.4)}});
  }
  const Expected<MotReport> report = evaluateMot(frames);
  ASSERT_TRUE(report.ok()) << report.error().message;
  const ClearMot& clear = report->clear;
  EXPECT_EQ(clear.truth_count, 10U);
  EXPECT_EQ(clear.matches, 10U);
  EXPECT_EQ(clear.misses, 0U);
  EXPECT_EQ(clear.false_positives, 0U);
  EXPECT_EQ(clear.id_switches, 0U);
  EXPECT_EQ(clear.fragmentations, 0U);
  EXPECT_DOUBLE_EQ(clear.mota, 1.0);
  EXPECT_NEAR(clear.motp_m, 0.5, kTol);
  EXPECT_EQ(clear.trajectories, 2U);
  EXPECT_EQ(clear.mostly_tracked, 2U);
  EXPECT_EQ(report->identity.idtp, 10U);
  EXPECT_DOUBLE_EQ(report->identity.idf1, 1.0);
  EXPECT_DOUBLE_EQ(report->identity.idp, 1.0);
  EXPECT_DOUBLE_EQ(report->identity.idr, 1.0);
  using Pair = std::pair<std::int64_t, std::int64_t>;
  EXPECT_EQ(report->identity.matching, (std::vector<Pair>{{1, 7}, {2, 8}}));
  EXPECT_EQ(report->localization.count, 10U);
  EXPECT_NEAR(report->localization.mean_m, 0.5, kTol);
  EXPECT_NEAR(report->localization.p95_m, 0.5, kTol);
  EXPECT_NEAR(report->localization.max_m, 0.5, kTol);
}

TEST(MotMetrics, TracksSwappingHalfwayCountTwoSwitches) {
  // 8 frames, swap after 4: in frame 4 both objects change hypothesis (2 switches), nothing else
  // goes wrong. MOTA = 1 - 2 / 16.
  const ClearMot clear = clearOf(swappingTracks(8, 4));
  EXPECT_EQ(clear.id_switches, 2U);
  EXPECT_EQ(clear.misses, 0U);
  EXPECT_EQ(clear.false_positives, 0U);
  EXPECT_EQ(clear.fragmentations, 0U);
  EXPECT_DOUBLE_EQ(clear.mota, 1.0 - 2.0 / 16.0);
  EXPECT_NEAR(clear.motp_m, 0.0, kTol);
}

TEST(Idf1, TracksSwappingHalfwayScoreOneHalf) {
  // Each (object, track) pair shares 4 of 8 frames; any one-to-one matching keeps 4 + 4 = 8 of the
  // 16 truth and 16 hypothesis detections: IDTP 8, IDFN 8, IDFP 8, IDF1 = 16 / 32.
  const IdScores id = idOf(swappingTracks(8, 4));
  EXPECT_EQ(id.idtp, 8U);
  EXPECT_EQ(id.idfn, 8U);
  EXPECT_EQ(id.idfp, 8U);
  EXPECT_DOUBLE_EQ(id.idf1, 0.5);
  EXPECT_DOUBLE_EQ(id.idp, 0.5);
  EXPECT_DOUBLE_EQ(id.idr, 0.5);
}

TEST(Idf1, PrefersTheLongerSharedStretchWhenTracksSwapLate) {
  // Swap after 6 of 8 frames: 1-10 and 2-20 share 6 frames each, the crossed pairs 2 each.
  // IDTP 12, IDFN 4, IDFP 4: IDF1 = 24 / 32.
  const IdScores id = idOf(swappingTracks(8, 6));
  EXPECT_EQ(id.idtp, 12U);
  EXPECT_DOUBLE_EQ(id.idf1, 0.75);
  using Pair = std::pair<std::int64_t, std::int64_t>;
  EXPECT_EQ(id.matching, (std::vector<Pair>{{1, 10}, {2, 20}}));
}

TEST(MotMetrics, MissedMiddleFrameIsOneMissAndOneFragmentation) {
  // Track 7 follows object 1 for 5 frames but is absent in frame 2.
  std::vector<MotFrame> frames;
  for (int f = 0; f < 5; ++f) {
    MotFrame frame{{objectAt(1, f, 0.0)}, {}};
    if (f != 2) frame.hypotheses.push_back(objectAt(7, f, 0.1));
    frames.push_back(frame);
  }
  const ClearMot clear = clearOf(frames);
  EXPECT_EQ(clear.misses, 1U);
  EXPECT_EQ(clear.fragmentations, 1U);
  EXPECT_EQ(clear.id_switches, 0U);  // the same track resumes
  EXPECT_DOUBLE_EQ(clear.mota, 1.0 - 1.0 / 5.0);
  // 4 of 5 frames is exactly 80 %: mostly tracked.
  EXPECT_EQ(clear.mostly_tracked, 1U);
  EXPECT_EQ(clear.partially_tracked, 0U);
  const IdScores id = idOf(frames);
  EXPECT_EQ(id.idtp, 4U);
  EXPECT_EQ(id.idfn, 1U);
  EXPECT_DOUBLE_EQ(id.idf1, 8.0 / 9.0);
}

TEST(MotMetrics, SwitchIsMeasuredAgainstTheLastMatchAcrossAGap) {
  // Object 1: track 7 in frame 0, nothing in frame 1, track 8 in frame 2. Frame 1 breaks the
  // previous-frame correspondence, but the identity still changed: one switch, one fragmentation.
  const std::vector<MotFrame> frames{
      MotFrame{{objectAt(1, 0.0, 0.0)}, {objectAt(7, 0.0, 0.0)}},
      MotFrame{{objectAt(1, 1.0, 0.0)}, {}},
      MotFrame{{objectAt(1, 2.0, 0.0)}, {objectAt(8, 2.0, 0.0)}},
  };
  const ClearMot clear = clearOf(frames);
  EXPECT_EQ(clear.id_switches, 1U);
  EXPECT_EQ(clear.fragmentations, 1U);
  EXPECT_EQ(clear.misses, 1U);
  // 2 of 3 frames tracked: neither mostly tracked nor mostly lost.
  EXPECT_EQ(clear.partially_tracked, 1U);
}

TEST(MotMetrics, TruthAbsentFromAFrameIsNeitherMissNorFragmentation) {
  // Object 1 is not in frame 1 (left the scene); its track stays and is then a false positive.
  const std::vector<MotFrame> frames{
      MotFrame{{objectAt(1, 0.0, 0.0)}, {objectAt(7, 0.0, 0.0)}},
      MotFrame{{}, {objectAt(7, 1.0, 0.0)}},
      MotFrame{{objectAt(1, 2.0, 0.0)}, {objectAt(7, 2.0, 0.0)}},
  };
  const ClearMot clear = clearOf(frames);
  EXPECT_EQ(clear.misses, 0U);
  EXPECT_EQ(clear.fragmentations, 0U);
  EXPECT_EQ(clear.id_switches, 0U);
  EXPECT_EQ(clear.false_positives, 1U);
  EXPECT_DOUBLE_EQ(clear.mota, 1.0 - 1.0 / 2.0);
}

TEST(MotMetrics, ExtraHypothesesAreFalsePositives) {
  // Track 7 is exact for 3 frames; track 9 is 50 m away in all 3; track 11 appears once, 3 m away.
  std::vector<MotFrame> frames;
  for (int f = 0; f < 3; ++f) {
    MotFrame frame{{objectAt(1, f, 0.0)}, {objectAt(7, f, 0.0), objectAt(9, f, 50.0)}};
    if (f == 1) frame.hypotheses.push_back(objectAt(11, f, 3.0));
    frames.push_back(frame);
  }
  const ClearMot clear = clearOf(frames);
  EXPECT_EQ(clear.false_positives, 4U);
  EXPECT_EQ(clear.misses, 0U);
  EXPECT_EQ(clear.matches, 3U);
  EXPECT_DOUBLE_EQ(clear.mota, 1.0 - 4.0 / 3.0);
  const IdScores id = idOf(frames);
  EXPECT_EQ(id.idfp, 4U);
  EXPECT_DOUBLE_EQ(id.idp, 3.0 / 7.0);
  EXPECT_DOUBLE_EQ(id.idr, 1.0);
}

TEST(MotMetrics, KeepsAValidCorrespondenceEvenWhenAnotherHypothesisIsCloser) {
  // Frame 0: only track 7, 0.5 m from object 1. Frame 1: track 7 is 0.6 m away, still inside the
  // gate, and track 8 has come within 0.1 m. CLEAR MOT keeps 1-7 (no switch) and 8 is a false
  // positive; re-matching by distance alone would have switched to 8.
  const std::vector<MotFrame> frames{
      MotFrame{{objectAt(1, 0.0, 0.0)}, {objectAt(7, 0.5, 0.0)}},
      MotFrame{{objectAt(1, 0.0, 0.0)}, {objectAt(7, 0.6, 0.0), objectAt(8, 0.1, 0.0)}},
  };
  const ClearMot clear = clearOf(frames);
  EXPECT_EQ(clear.id_switches, 0U);
  EXPECT_EQ(clear.matches, 2U);
  EXPECT_EQ(clear.false_positives, 1U);
  EXPECT_NEAR(clear.motp_m, (0.5 + 0.6) / 2.0, kTol);
}

TEST(MotMetrics, CorrespondenceLeavingTheGateIsRematched) {
  // Frame 1: track 7 has drifted 1.5 m away (beyond the gate), track 8 is on the object: a switch.
  const std::vector<MotFrame> frames{
      MotFrame{{objectAt(1, 0.0, 0.0)}, {objectAt(7, 0.2, 0.0)}},
      MotFrame{{objectAt(1, 0.0, 0.0)}, {objectAt(7, 1.5, 0.0), objectAt(8, 0.1, 0.0)}},
  };
  const ClearMot clear = clearOf(frames);
  EXPECT_EQ(clear.id_switches, 1U);
  EXPECT_EQ(clear.false_positives, 1U);
  EXPECT_NEAR(clear.total_distance_m, 0.3, kTol);
}

TEST(MotMetrics, MatchesTheMostPairsRatherThanTheNearestFirst) {
  // Object 1 at 0, object 2 at 1.5; tracks at 0.8 and 2.2. Nearest-first takes 2-(0.8) at 0.7 and
  // leaves object 1 alone; the optimum pairs 1-(0.8) and 2-(2.2).
  const std::vector<MotFrame> frames{
      MotFrame{{objectAt(1, 0.0, 0.0), objectAt(2, 1.5, 0.0)}, {objectAt(7, 0.8, 0.0), objectAt(8, 2.2, 0.0)}},
  };
  const ClearMot clear = clearOf(frames);
  EXPECT_EQ(clear.matches, 2U);
  EXPECT_EQ(clear.misses, 0U);
  EXPECT_NEAR(clear.total_distance_m, 1.5, 1e-9);
}

TEST(MotMetrics, PairAtExactlyTheThresholdIsNoMatch) {
  // The gate is strict (distance < threshold), as in CLEAR MOT.
  const std::vector<MotFrame> frames{MotFrame{{objectAt(1, 0.0, 0.0)}, {objectAt(7, 1.0, 0.0)}}};
  const ClearMot clear = clearOf(frames, MotConfig{1.0});
  EXPECT_EQ(clear.matches, 0U);
  EXPECT_EQ(clear.misses, 1U);
  EXPECT_EQ(clear.false_positives, 1U);
  EXPECT_EQ(clear.mostly_lost, 1U);
  EXPECT_EQ(idOf(frames, MotConfig{1.0}).idtp, 0U);
  EXPECT_EQ(clearOf(frames, MotConfig{1.01}).matches, 1U);
}

// Worked example (threshold 1 m). Objects a = 1, b = 2; tracks 10, 20, 30. "kept" = last frame's
// correspondence still valid; "new" = matched by least distance.
//
//  frame | a        | b        | tracks present        | matches (distance m)             | FN FP SW
//  ------+----------+----------+-----------------------+----------------------------------+---------
//    0   | (0,0)    | (5,0)    | 10 (0.2,0) 20 (5,0.4) | a-10 new 0.2, b-20 new 0.4       |  0  0  0
//    1   | (1,0)    | (5,1)    | 10 (1,0.3) 20 (5,1)   | a-10 kept 0.3, b-20 kept 0.0     |  0  1  0
//        |          |          | 30 (1.5,0)            |   (30 is 0.5 from a, but a keeps 10)
//    2   | (2,0)    | (5,2)    | 20 (5,2.5) 30 (2.6,0) | b-20 kept 0.5, a-30 new 0.6      |  0  0  1 (a: 10 -> 30)
//    3   | (3,0)    | (5,3)    | 10 (3.2,0) 30 (3.5,0) | a-30 kept 0.5 (10 is closer)     |  1  1  0 (b missed)
//    4   | (4,0)    | (5,4)    | 10 (5,4.1) 30 (4,0.2) | a-30 kept 0.2, b-10 new 0.1      |  0  0  1 (b: 20 -> 10)
//
//  10 truth, 11 hypotheses, 9 matches: FN 1, FP 2, IDSW 2, MOTA = 1 - 5/10 = 0.5.
//  Distances sum to 2.8: MOTP = 2.8 / 9. b is tracked, lost, tracked again: 1 fragmentation;
//  a 5/5 and b 4/5 tracked: both mostly tracked. Sorted distances 0 .1 .2 .2 .3 .4 .5 .5 .6:
//  p95 is the 9th (ceil 8.55), 0.6.
//  IDTP per pair (frames within the gate): a-10 3 (0,1,3), a-30 4 (1,2,3,4), b-10 1 (4),
//  b-20 3 (0,1,2), others 0. Best matching a-30 + b-20 = 7: IDFN 3, IDFP 4,
//  IDP 7/11, IDR 7/10, IDF1 = 14 / 21.
std::vector<MotFrame> workedExample() {
  return {
      MotFrame{{objectAt(1, 0, 0), objectAt(2, 5, 0)}, {objectAt(10, 0.2, 0), objectAt(20, 5, 0.4)}},
      MotFrame{{objectAt(1, 1, 0), objectAt(2, 5, 1)}, {objectAt(10, 1, 0.3), objectAt(20, 5, 1), objectAt(30, 1.5, 0)}},
      MotFrame{{objectAt(1, 2, 0), objectAt(2, 5, 2)}, {objectAt(20, 5, 2.5), objectAt(30, 2.6, 0)}},
      MotFrame{{objectAt(1, 3, 0), objectAt(2, 5, 3)}, {objectAt(10, 3.2, 0), objectAt(30, 3.5, 0)}},
      MotFrame{{objectAt(1, 4, 0), objectAt(2, 5, 4)}, {objectAt(10, 5, 4.1), objectAt(30, 4, 0.2)}},
  };
}

TEST(MotMetrics, WorkedExampleMatchesTheHandComputedTable) {
  const Expected<MotReport> report = evaluateMot(workedExample());
  ASSERT_TRUE(report.ok()) << report.error().message;
  const ClearMot& clear = report->clear;
  EXPECT_EQ(clear.truth_count, 10U);
  EXPECT_EQ(clear.hypothesis_count, 11U);
  EXPECT_EQ(clear.matches, 9U);
  EXPECT_EQ(clear.misses, 1U);
  EXPECT_EQ(clear.false_positives, 2U);
  EXPECT_EQ(clear.id_switches, 2U);
  EXPECT_EQ(clear.fragmentations, 1U);
  EXPECT_DOUBLE_EQ(clear.mota, 0.5);
  EXPECT_NEAR(clear.total_distance_m, 2.8, 1e-9);
  EXPECT_NEAR(clear.motp_m, 2.8 / 9.0, 1e-9);
  EXPECT_EQ(clear.mostly_tracked, 2U);
  EXPECT_EQ(clear.mostly_lost, 0U);

  const IdScores& id = report->identity;
  EXPECT_EQ(id.idtp, 7U);
  EXPECT_EQ(id.idfn, 3U);
  EXPECT_EQ(id.idfp, 4U);
  EXPECT_DOUBLE_EQ(id.idp, 7.0 / 11.0);
  EXPECT_DOUBLE_EQ(id.idr, 7.0 / 10.0);
  EXPECT_DOUBLE_EQ(id.idf1, 14.0 / 21.0);
  using Pair = std::pair<std::int64_t, std::int64_t>;
  EXPECT_EQ(id.matching, (std::vector<Pair>{{1, 30}, {2, 20}}));

  EXPECT_EQ(report->localization.count, 9U);
  EXPECT_NEAR(report->localization.mean_m, 2.8 / 9.0, 1e-9);
  EXPECT_NEAR(report->localization.p95_m, 0.6, 1e-9);
  EXPECT_NEAR(report->localization.max_m, 0.6, 1e-9);
}

TEST(MotMetrics, NoTruthLeavesTheRatiosUndefined) {
  const std::vector<MotFrame> frames{MotFrame{{}, {objectAt(7, 0, 0)}}};
  const Expected<MotReport> report = evaluateMot(frames);
  ASSERT_TRUE(report.ok()) << report.error().message;
  EXPECT_TRUE(std::isnan(report->clear.mota));
  EXPECT_TRUE(std::isnan(report->clear.motp_m));
  EXPECT_EQ(report->clear.false_positives, 1U);
  EXPECT_TRUE(std::isnan(report->identity.idr));
  EXPECT_DOUBLE_EQ(report->identity.idp, 0.0);
  EXPECT_DOUBLE_EQ(report->identity.idf1, 0.0);
  EXPECT_EQ(report->localization.count, 0U);
  EXPECT_TRUE(std::isnan(report->localization.mean_m));
}

// IDTP of every (truth, hypothesis) trajectory pair, from per-frame lookups by id.
using PairCounts = std::map<std::pair<std::int64_t, std::int64_t>, std::size_t>;

PairCounts pairCounts(const std::vector<MotFrame>& frames, double threshold_m) {
  PairCounts counts;
  for (const MotFrame& frame : frames) {
    for (const MotObject& o : frame.truth) {
      for (const MotObject& h : frame.hypotheses) {
        if ((o.position - h.position).norm() < threshold_m) ++counts[{o.id, h.id}];
      }
    }
  }
  return counts;
}

// The most IDTP over every one-to-one partial matching of truth ids to hypothesis ids.
std::size_t bestIdtpByEnumeration(const std::vector<std::int64_t>& truth_ids,
                                  const std::vector<std::int64_t>& hyp_ids, const PairCounts& counts) {
  std::size_t best = 0;
  std::vector<char> taken(hyp_ids.size(), 0);
  std::function<void(std::size_t, std::size_t)> visit = [&](std::size_t t, std::size_t sum) {
    if (t == truth_ids.size()) {
      best = std::max(best, sum);
      return;
    }
    visit(t + 1, sum);  // this truth trajectory left unmatched
    for (std::size_t h = 0; h < hyp_ids.size(); ++h) {
      if (taken[h]) continue;
      const auto it = counts.find({truth_ids[t], hyp_ids[h]});
      taken[h] = 1;
      visit(t + 1, sum + (it == counts.end() ? 0 : it->second));
      taken[h] = 0;
    }
  };
  visit(0, 0);
  return best;
}

TEST(Idf1, HungarianMatchingEqualsTheBestOfAllOneToOneMatchings) {
  std::mt19937 rng(20160826);
  std::uniform_int_distribution<int> count(0, 4);
  std::uniform_int_distribution<int> frame_count(1, 6);
  std::uniform_real_distribution<double> coordinate(0.0, 2.5);  // a small box: many pairs in the gate
  std::bernoulli_distribution present(0.7);
  const MotConfig config{1.0};
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<std::int64_t> truth_ids(static_cast<std::size_t>(count(rng)));
    std::vector<std::int64_t> hyp_ids(static_cast<std::size_t>(count(rng)));
    std::iota(truth_ids.begin(), truth_ids.end(), 100);
    std::iota(hyp_ids.begin(), hyp_ids.end(), 200);
    std::vector<MotFrame> frames(static_cast<std::size_t>(frame_count(rng)));
    std::size_t detections = 0;
    for (MotFrame& frame : frames) {
      for (const std::int64_t id : truth_ids) {
        if (present(rng)) frame.truth.push_back(objectAt(id, coordinate(rng), coordinate(rng)));
      }
      for (const std::int64_t id : hyp_ids) {
        if (present(rng)) frame.hypotheses.push_back(objectAt(id, coordinate(rng), coordinate(rng)));
      }
      detections += frame.truth.size() + frame.hypotheses.size();
    }
    const PairCounts counts = pairCounts(frames, config.match_distance_m);
    const std::size_t best = bestIdtpByEnumeration(truth_ids, hyp_ids, counts);
    const IdScores id = idOf(frames, config);
    ASSERT_EQ(id.idtp, best) << "trial " << trial;
    if (detections > 0) {
      EXPECT_DOUBLE_EQ(id.idf1, 2.0 * static_cast<double>(best) / static_cast<double>(detections))
          << "trial " << trial;
    }
    // The reported matching is one-to-one and accounts for the whole IDTP.
    std::size_t sum = 0;
    std::vector<std::int64_t> used;
    for (const auto& pair : id.matching) {
      EXPECT_EQ(std::count(used.begin(), used.end(), pair.second), 0) << "trial " << trial;
      used.push_back(pair.second);
      sum += counts.at(pair);
    }
    EXPECT_EQ(sum, best) << "trial " << trial;
  }
}

TEST(MotErrorStats, P95IsTheNearestRank) {
  // 1..20 in scrambled order: ceil(0.95 * 20) = 19th smallest.
  std::vector<double> errors(20);
  std::iota(errors.begin(), errors.end(), 1.0);
  std::shuffle(errors.begin(), errors.end(), std::mt19937(3));
  const Expected<ErrorStats> stats = errorStats(errors);
  ASSERT_TRUE(stats.ok()) << stats.error().message;
  EXPECT_EQ(stats->count, 20U);
  EXPECT_DOUBLE_EQ(stats->mean_m, 10.5);
  EXPECT_DOUBLE_EQ(stats->p95_m, 19.0);
  EXPECT_DOUBLE_EQ(stats->max_m, 20.0);

  // 21 values: ceil(19.95) = 20th.
  errors.push_back(21.0);
  EXPECT_DOUBLE_EQ(errorStats(errors)->p95_m, 20.0);

  const std::vector<double> one{0.25};
  EXPECT_DOUBLE_EQ(errorStats(one)->p95_m, 0.25);
}

TEST(MotErrorStats, EmptyListIsUndefinedAndNonFiniteIsRefused) {
  const Expected<ErrorStats> empty = errorStats({});
  ASSERT_TRUE(empty.ok());
  EXPECT_EQ(empty->count, 0U);
  EXPECT_TRUE(std::isnan(empty->p95_m));

  const std::vector<double> bad{0.1, 0.2, std::nan("")};
  const Expected<ErrorStats> refused = errorStats(bad);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(refused.error().message.find("value 2"), std::string::npos) << refused.error().message;
}

// Every entry point refuses, with a message holding every one of `needles`.
void expectRefused(const std::vector<MotFrame>& frames, const MotConfig& config,
                   const std::vector<std::string>& needles) {
  const Status status = validateMotInput(frames, config);
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().code, ErrorCode::kInvalidArgument);
  for (const std::string& needle : needles) {
    EXPECT_NE(status.error().message.find(needle), std::string::npos)
        << "'" << needle << "' not in: " << status.error().message;
  }
  EXPECT_FALSE(clearMot(frames, config).ok());
  EXPECT_FALSE(idScores(frames, config).ok());
  EXPECT_FALSE(evaluateMot(frames, config).ok());
}

TEST(MotInput, NonFinitePositionIsRefusedNamingFrameAndId) {
  std::vector<MotFrame> frames = workedExample();
  frames[2].truth[1].position.x() = std::nan("");
  expectRefused(frames, {}, {"frame 2", "truth id 2", "non-finite"});

  frames = workedExample();
  frames[4].hypotheses[0].position.y() = std::numeric_limits<double>::infinity();
  expectRefused(frames, {}, {"frame 4", "hypothesis id 10", "non-finite"});
}

TEST(MotInput, DuplicateIdInAFrameIsRefusedNamingFrameAndId) {
  std::vector<MotFrame> frames = workedExample();
  frames[1].hypotheses.push_back(objectAt(20, 9, 9));
  expectRefused(frames, {}, {"frame 1", "hypothesis id 20", "twice"});

  frames = workedExample();
  frames[3].truth.push_back(objectAt(1, 7, 7));
  expectRefused(frames, {}, {"frame 3", "truth id 1", "twice"});
}

TEST(MotInput, ThresholdMustBePositiveAndFinite) {
  const std::vector<MotFrame> frames = workedExample();
  expectRefused(frames, MotConfig{0.0}, {"match_distance_m", "got 0"});
  expectRefused(frames, MotConfig{-1.0}, {"match_distance_m", "got -1"});
  expectRefused(frames, MotConfig{std::nan("")}, {"match_distance_m"});
  expectRefused(frames, MotConfig{std::numeric_limits<double>::infinity()}, {"match_distance_m"});
}

TEST(MotInput, SameIdAsTruthAndHypothesisIsAllowed) {
  // Truth and hypothesis ids are separate name spaces.
  const std::vector<MotFrame> frames{MotFrame{{objectAt(1, 0, 0)}, {objectAt(1, 0, 0)}}};
  EXPECT_TRUE(validateMotInput(frames, {}).ok());
  EXPECT_DOUBLE_EQ(clearOf(frames).mota, 1.0);
}

// Headings are scored over the matches where both truth and track have one, as the angle between
// them in [0, 180] degrees; they never decide a match.
TEST(MotHeadings, TheAngleBetweenHeadingsIsScoredOverMatchesWhereBothHaveOne) {
  const double deg = std::numbers::pi / 180.0;
  const auto with = [](MotObject o, std::optional<double> heading) {
    o.heading_rad = heading;
    return o;
  };
  std::vector<MotFrame> frames;
  // A car (truth 1, heading 170 deg) tracked by 10 with -170 deg: 20 degrees apart across +-180.
  // A person (truth 2, no heading) tracked by 20 with one: not scored. Truth 3 (heading 0) tracked
  // by 30 with 90 deg, then without a heading.
  frames.push_back(MotFrame{{with(objectAt(1, 0, 0), 170 * deg), objectAt(2, 5, 0), with(objectAt(3, 10, 0), 0.0)},
                            {with(objectAt(10, 0.1, 0), -170 * deg), with(objectAt(20, 5, 0), 1.0), with(objectAt(30, 10, 0), 90 * deg)}});
  frames.push_back(MotFrame{{with(objectAt(1, 1, 0), 170 * deg), objectAt(2, 5, 1), with(objectAt(3, 10, 1), 0.0)},
                            {with(objectAt(10, 1, 0), 175 * deg), objectAt(20, 5, 1), objectAt(30, 10, 1)}});
  const auto report = evaluateMot(frames);
  ASSERT_TRUE(report.ok()) << report.error().message;
  EXPECT_EQ(report->clear.matches, 6U);
  ASSERT_EQ(report->clear.match_heading_errors_deg.size(), 3U);
  EXPECT_NEAR(report->clear.match_heading_errors_deg[0], 20.0, 1e-9);
  EXPECT_NEAR(report->clear.match_heading_errors_deg[1], 90.0, 1e-9);
  EXPECT_NEAR(report->clear.match_heading_errors_deg[2], 5.0, 1e-9);
  EXPECT_EQ(report->heading_error_deg.count, 3U);
  EXPECT_NEAR(report->heading_error_deg.mean_m, 115.0 / 3.0, 1e-9);
  EXPECT_NEAR(report->heading_error_deg.max_m, 90.0, 1e-9);
  EXPECT_EQ(report->clear.mota, 1.0) << "a wrong heading is no miss";

  // A heading opposite the truth's is the largest error, 180 degrees; a non-finite one is refused.
  const auto opposite = evaluateMot(
      std::vector<MotFrame>{MotFrame{{with(objectAt(1, 0, 0), 0.5)}, {with(objectAt(9, 0, 0), 0.5 - std::numbers::pi)}}});
  ASSERT_TRUE(opposite.ok());
  EXPECT_NEAR(opposite->heading_error_deg.max_m, 180.0, 1e-9);
  const auto bad = evaluateMot(
      std::vector<MotFrame>{MotFrame{{objectAt(1, 0, 0)}, {with(objectAt(9, 0, 0), std::numeric_limits<double>::quiet_NaN())}}});
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.error().message.find("hypothesis id 9 has a non-finite heading"), std::string::npos) << bad.error().message;
}

}  // namespace
}  // namespace fogmap::tracking
