// The tracker's centroid input, driven by hand: an epoch is emitted once every edge has spoken for
// it, else at its deadline; frames that come too late, too early, twice or from strangers are
// refused; epochs come out in order, merged across edges.
#include "services/tracker/centroid_collector.hpp"
#include "tests/support/epoch_times.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace fogmap {
namespace {

using test_support::kE0;
using test_support::kMs;
using test_support::startOf;

EpochSchedule schedule() {
  auto s = EpochSchedule::create(100.0, 80.0);  // period 100 ms, deadline 80 ms
  EXPECT_TRUE(s.ok());
  return *s;
}

tracking::CentroidFrame frameOf(const std::string& edge, std::uint64_t epoch, std::vector<Eigen::Vector3d> positions,
                                std::int64_t offset_ns = 2 * kMs, const Eigen::Vector3d& sensor = Eigen::Vector3d::Zero()) {
  tracking::CentroidFrame f;
  f.edge = edge;
  f.epoch = epoch;
  f.time_ns = startOf(epoch) + offset_ns;
  f.sensor_position = sensor;
  for (const auto& p : positions) f.centroids.push_back({p, Eigen::Matrix3d::Identity() * 0.01, 20});
  return f;
}

CentroidCollector collector(std::vector<std::string> edges, std::size_t max_open = 16) {
  CentroidCollectorConfig config;
  config.edges = std::move(edges);
  config.merge_radius_m = 1.0;
  config.window_periods = 3.0;
  config.max_open_epochs = max_open;
  return CentroidCollector(config, schedule());
}

TEST(CentroidCollector, AnEpochIsOneLidarFrameOnceEveryEdgeSentIt) {
  auto c = collector({"a", "b"});
  const std::int64_t now = startOf(kE0) + 10 * kMs;
  auto first = c.add(frameOf("a", kE0, {{1.0, 0.0, 1.0}, {8.0, 8.0, 1.0}}, 3 * kMs, {-10, 0, 2}), now);
  EXPECT_EQ(first.verdict, CentroidVerdict::kAccepted);
  EXPECT_TRUE(first.ready.empty()) << "b has not sent epoch " << kE0;
  auto second = c.add(frameOf("b", kE0, {{1.4, 0.0, 1.2}}, 1 * kMs, {10, 0, 4}), now);
  EXPECT_EQ(second.verdict, CentroidVerdict::kAccepted);
  ASSERT_EQ(second.ready.size(), 1U);
  const tracking::CloudFrame& frame = second.ready[0];
  EXPECT_EQ(frame.time_ns, startOf(kE0) + 1 * kMs) << "the earliest sensor time";
  EXPECT_EQ(frame.sensor_position, Eigen::Vector3d(0, 0, 3)) << "the mean of the sensors";
  // The person seen by both is one observation at the mean of the two views; the other stays.
  ASSERT_EQ(frame.observations.size(), 2U);
  EXPECT_LT((frame.observations[0].position - Eigen::Vector3d(1.2, 0.0, 1.1)).norm(), 1e-12);
  EXPECT_LT((frame.observations[1].position - Eigen::Vector3d(8.0, 8.0, 1.0)).norm(), 1e-12);
  EXPECT_EQ(c.counters().epochs_emitted, 1U);
  EXPECT_EQ(c.counters().epochs_partial, 0U);
  EXPECT_EQ(c.openEpochs(), 0U);
}

TEST(CentroidCollector, NarrowCentroidsArePlacedOnTheirAxisSeenFromTheirOwnEdgesLidar) {
  CentroidCollectorConfig config;
  config.edges = {"a", "b"};
  config.visible_side_max_radius_m = 0.4;
  CentroidCollector c(config, schedule());
  const std::int64_t now = startOf(kE0) + 10 * kMs;
  // A person of radius 0.3 m at (5, 0): LiDAR a at (0, 0) sees its near side, LiDAR b at (5, 10)
  // its near side from the other direction. Spread across the line of sight: r^2 / 3.
  const double r = 0.3;
  const double offset = M_PI / 4.0 * r;
  auto fa = frameOf("a", kE0, {{5.0 - offset, 0.0, 1.0}}, 2 * kMs, {0, 0, 1.8});
  fa.centroids[0].covariance = Eigen::Vector3d(0.01, r * r / 3.0, 0.2).asDiagonal();
  auto fb = frameOf("b", kE0, {{5.0, offset, 1.0}}, 2 * kMs, {5, 10, 1.8});
  fb.centroids[0].covariance = Eigen::Vector3d(r * r / 3.0, 0.01, 0.2).asDiagonal();
  EXPECT_TRUE(c.add(fa, now).ready.empty());
  const auto added = c.add(fb, now);
  ASSERT_EQ(added.ready.size(), 1U);
  ASSERT_EQ(added.ready[0].observations.size(), 1U);
  EXPECT_LT((added.ready[0].observations[0].position.head<2>() - Eigen::Vector2d(5.0, 0.0)).norm(), 1e-9)
      << "each view moved to the axis, seen from its own LiDAR";
}

TEST(CentroidCollector, AnEdgeThatSentALaterEpochHasSpokenForTheEarlierOnes) {
  // b's scan did not change in epoch kE0 (a slower sensor): its frame of kE0 + 1 completes kE0.
  auto c = collector({"a", "b"});
  const std::int64_t now = startOf(kE0) + 10 * kMs;
  EXPECT_TRUE(c.add(frameOf("a", kE0, {{1, 0, 1}}), now).ready.empty());
  const auto added = c.add(frameOf("b", kE0 + 1, {{5, 0, 1}}), now);
  ASSERT_EQ(added.ready.size(), 1U);
  EXPECT_EQ(added.ready[0].time_ns, startOf(kE0) + 2 * kMs);
  const auto next = c.add(frameOf("a", kE0 + 1, {{1.1, 0, 1}}), now);
  ASSERT_EQ(next.ready.size(), 1U);
  EXPECT_EQ(next.ready[0].time_ns, startOf(kE0 + 1) + 2 * kMs);
  EXPECT_EQ(next.ready[0].observations.size(), 2U);
  EXPECT_EQ(c.counters().epochs_partial, 0U);
}

TEST(CentroidCollector, AtItsDeadlineAnEpochGoesWithWhatArrivedAndItsStragglersAreLate) {
  auto c = collector({"a", "b"});
  EXPECT_TRUE(c.add(frameOf("a", kE0, {{1, 0, 1}}), startOf(kE0) + 10 * kMs).ready.empty());
  EXPECT_TRUE(c.expire(startOf(kE0) + 80 * kMs - 1).empty());
  const auto expired = c.expire(startOf(kE0) + 80 * kMs);  // the deadline a level-1 aggregator keeps
  ASSERT_EQ(expired.size(), 1U);
  EXPECT_EQ(expired[0].observations.size(), 1U);
  EXPECT_EQ(c.counters().epochs_partial, 1U);
  const auto late = c.add(frameOf("b", kE0, {{5, 0, 1}}), startOf(kE0) + 90 * kMs);
  EXPECT_EQ(late.verdict, CentroidVerdict::kLate);
  EXPECT_TRUE(late.ready.empty());
  EXPECT_EQ(c.counters().frames_accepted, 1U);
}

TEST(CentroidCollector, DuplicatesStrangersAndFramesFromTheFutureAreRefused) {
  auto c = collector({"a", "b"});
  const std::int64_t now = startOf(kE0) + 10 * kMs;
  EXPECT_EQ(c.add(frameOf("a", kE0, {}), now).verdict, CentroidVerdict::kAccepted);
  EXPECT_EQ(c.add(frameOf("a", kE0, {{1, 1, 1}}), now).verdict, CentroidVerdict::kDuplicate);
  EXPECT_EQ(c.add(frameOf("stranger", kE0, {}), now).verdict, CentroidVerdict::kUnknownEdge);
  EXPECT_EQ(c.add(frameOf("a", kE0 - 1, {}), now).verdict, CentroidVerdict::kDuplicate)
      << "an edge's stream keeps order: an older epoch after a newer one is not news";
  EXPECT_EQ(c.add(frameOf("b", kE0 + 4, {}), now).verdict, CentroidVerdict::kClockSkew) << "4 periods ahead, window 3";
  EXPECT_EQ(c.add(frameOf("b", kE0 + 3, {}), now).verdict, CentroidVerdict::kAccepted);
  EXPECT_EQ(c.add(frameOf("a", kE0 - 1, {}), now).verdict, CentroidVerdict::kLate) << "epoch " << kE0 << " went";
  EXPECT_EQ(c.counters().frames_accepted, 2U);
  // std::uint64_t epochs at the top of the range are clock skew, not an overflow.
  tracking::CentroidFrame last = frameOf("b", kE0, {});
  last.epoch = std::numeric_limits<std::uint64_t>::max();
  EXPECT_EQ(c.add(last, now).verdict, CentroidVerdict::kClockSkew);
}

TEST(CentroidCollector, EpochsComeOutInOrderAndTheOpenOnesAreBounded) {
  // b is dead: a's epochs would wait for their deadlines, but at most 2 stay open.
  auto c = collector({"a", "b"}, 2);
  const std::int64_t now = startOf(kE0) + 10 * kMs;
  std::vector<std::int64_t> times;
  for (std::uint64_t e = kE0; e < kE0 + 4; ++e) {
    const auto added = c.add(frameOf("a", e, {{1, 0, 1}}), now);
    ASSERT_EQ(added.verdict, CentroidVerdict::kAccepted);
    for (const auto& f : added.ready) times.push_back(f.time_ns);
  }
  EXPECT_EQ(c.openEpochs(), 2U);
  EXPECT_EQ(times, (std::vector<std::int64_t>{startOf(kE0) + 2 * kMs, startOf(kE0 + 1) + 2 * kMs}));
  // When b comes back with a later epoch, everything before it goes, oldest first.
  const auto back = c.add(frameOf("b", kE0 + 3, {{4, 0, 1}}), now);
  ASSERT_EQ(back.ready.size(), 2U);
  EXPECT_EQ(back.ready[0].time_ns, startOf(kE0 + 2) + 2 * kMs);
  EXPECT_EQ(back.ready[1].time_ns, startOf(kE0 + 3) + 2 * kMs);
  EXPECT_EQ(back.ready[1].observations.size(), 2U);
  // The two pushed out by the bound went without b; b spoke for epoch + 2 by sending a later one.
  EXPECT_EQ(c.counters().epochs_partial, 2U);
}

}  // namespace
}  // namespace fogmap
