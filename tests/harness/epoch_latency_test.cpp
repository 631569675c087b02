// The latencies fogctl demo reports (harness/epoch_latency) on hand-made runs: an epoch no
// node contributed to has no sensor time, so no end-to-end latency, and is counted apart.
#include "harness/epoch_latency.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <vector>

#include "harness/cluster_run.hpp"
#include "tests/support/epoch_times.hpp"

namespace fogmap::harness {
namespace {

constexpr std::int64_t kT0 = 1'764'000'000'000'000'000;  // a unix time in ns, as the sensors stamp them
using test_support::kMs;

GlobalMapMessage published(std::int64_t sensor_time_ns, std::int64_t published_time_ns, std::vector<std::uint32_t> missing,
                           double merge_seconds = 0.002) {
  GlobalMapMessage g;
  g.header.sensor_time_ns = sensor_time_ns;
  g.header.missing_nodes = std::move(missing);
  g.published_time_ns = published_time_ns;
  g.merge_seconds = merge_seconds;
  return g;
}

TEST(EpochLatency, EndToEndIsFromTheSensorTimeToThePublication) {
  EXPECT_EQ(endToEndLatencyMs(published(kT0, kT0 + 40 * kMs, {})), 40.0);
  EXPECT_EQ(endToEndLatencyMs(published(kT0, kT0 + 250 * kMs, {3})), 250.0);
}

TEST(EpochLatency, AMapWithoutSensorTimeHasNoEndToEndLatency) {
  EXPECT_FALSE(endToEndLatencyMs(published(0, kT0, {1, 2})).has_value());
}

TEST(EpochLatency, EpochsEveryNodeMissedAreLeftOutOfTheEndToEndFiguresAndCounted) {
  std::map<std::uint64_t, GlobalMapMessage> epochs;
  epochs[10] = published(kT0, kT0 + 40 * kMs, {});
  epochs[11] = published(kT0 + 100 * kMs, kT0 + 160 * kMs, {});
  epochs[12] = published(kT0 + 200 * kMs, kT0 + 320 * kMs, {2});     // a late node
  epochs[13] = published(0, kT0 + 400 * kMs, {1, 2}, 0.0001);       // every node missing
  const EpochLatencies latencies = epochLatencies(epochs);

  EXPECT_EQ(latencies.e2e_ms, (std::vector<double>{40.0, 60.0}));
  EXPECT_EQ(latencies.e2e_all_ms, (std::vector<double>{40.0, 60.0, 120.0}));
  EXPECT_EQ(latencies.without_sensor_time, 1U);
  EXPECT_EQ(percentile(latencies.e2e_all_ms, 0.99), 120.0) << "an epoch without sensor time must not inflate the p99";
  // Its merge still took its time at the sink.
  EXPECT_EQ(latencies.merge_ms.size(), 4U);
  EXPECT_EQ(latencies.incomplete_list,
            "\n    epoch 12: missing nodes 2, published 120 ms after the sensor time"
            "\n    epoch 13: missing nodes 1 2, no sensor time (no node contributed)");
}

TEST(EpochLatency, ARunOfCompleteEpochsHasNoneWithoutSensorTime) {
  std::map<std::uint64_t, GlobalMapMessage> epochs;
  for (std::uint64_t e = 0; e < 5; ++e) {
    const std::int64_t t = kT0 + static_cast<std::int64_t>(e) * 100 * kMs;
    epochs[e] = published(t, t + static_cast<std::int64_t>(10 + e) * kMs, {});
  }
  const EpochLatencies latencies = epochLatencies(epochs);
  EXPECT_EQ(latencies.e2e_ms, (std::vector<double>{10.0, 11.0, 12.0, 13.0, 14.0}));
  EXPECT_EQ(latencies.e2e_all_ms, latencies.e2e_ms);
  EXPECT_EQ(latencies.without_sensor_time, 0U);
  EXPECT_TRUE(latencies.incomplete_list.empty());
}

}  // namespace
}  // namespace fogmap::harness
