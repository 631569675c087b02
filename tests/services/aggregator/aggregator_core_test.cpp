#include "services/merge_aggregator/aggregator_core.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <limits>
#include <map>
#include <random>
#include <set>

#include <Eigen/Geometry>

#include "common/config/topology_presets.hpp"
#include "common/perception/clustering.hpp"
#include "common/perception/madc.hpp"
#include "tests/support/topology_builders.hpp"
#include "tests/support/epoch_times.hpp"

namespace fogmap {
namespace {

// Epoch k of the tests is E(k), at(k, offset_ms) a time in it (its deadline at one level is offset 80).
using test_support::at;
using test_support::E;
using test_support::kE0;
using test_support::kMs;
using test_support::kPeriodNs;
using test_support::kRoot;
using test_support::kT0;

constexpr std::size_t kWireBytes = 1000;  // the serialised size the tests claim for an upload

AggregatorConfig starConfig(std::vector<std::uint32_t> edges, Mode mode = Mode::kMadc, bool is_root = true) {
  AggregatorConfig config;
  config.node = kRoot;
  config.mode = mode;
  config.is_root = is_root;
  config.period_ms = 100.0;
  config.deadline_ms = 80.0;
  for (const auto edge : edges) config.children.push_back({edge, {edge}, "edge-" + std::to_string(edge)});
  return config;
}

MergeAggregator makeAggregator(AggregatorConfig config) {
  auto aggregator = MergeAggregator::create(std::move(config));
  EXPECT_TRUE(aggregator.ok()) << (aggregator.ok() ? "" : aggregator.error().message);
  return std::move(aggregator).value();
}

void connectAll(MergeAggregator& aggregator, std::initializer_list<std::uint32_t> children) {
  for (const auto child : children) {
    const auto connected = aggregator.childConnected(child);
    ASSERT_TRUE(connected.ok());
    ASSERT_EQ(*connected, child);
  }
}

Eigen::Matrix3d randomShape(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> axis(0.3, 1.5);
  std::normal_distribution<double> normal;
  const Eigen::Matrix3d rotation =
      Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized().toRotationMatrix();
  const Eigen::Vector3d semi(axis(rng), axis(rng), axis(rng));
  return rotation * semi.cwiseAbs2().asDiagonal() * rotation.transpose();
}

// A local map of `count` random ellipsoids over a small square, so that maps of different nodes
// overlap and MERGE has objects to join.
Map randomLocalMap(std::mt19937_64& rng, std::uint32_t node, std::uint64_t frame, int count) {
  std::uniform_real_distribution<double> pos(-8.0, 8.0);
  std::vector<Ellipsoid> ellipsoids;
  for (int k = 0; k < count; ++k) {
    Ellipsoid e;
    e.id = {node, frame, static_cast<std::uint32_t>(k)};
    e.center = {pos(rng), pos(rng), 1.0};
    e.shape = randomShape(rng);
    e.point_count = 20;
    ellipsoids.push_back(e);
  }
  return localMap(std::move(ellipsoids));
}

MapMessage mapMessage(std::uint32_t node, std::uint64_t epoch, Map map, std::int64_t sensor_time_ns = kT0) {
  MapMessage message;
  message.header.node = node;
  message.header.epoch = epoch;
  message.header.sensor_time_ns = sensor_time_ns;
  message.header.contributing_nodes = {node};
  message.map = std::move(map);
  return message;
}

// A ball of radius 0.5 m.
Ellipsoid ball(std::uint32_t node, std::uint64_t epoch, std::uint32_t index, const Eigen::Vector3d& centre) {
  Ellipsoid e;
  e.id = {node, epoch, index};
  e.center = centre;
  e.shape = Eigen::Matrix3d::Identity() * 0.25;  // radius 0.5 m
  e.point_count = 10;
  return e;
}

// Numbers every child's uploads as its stream would: one sequence after the other, and a
// fingerprint that differs for different uploads (a re-send reuses its key).
class Streams {
 public:
  UploadKey next(std::uint32_t child) {
    const std::uint64_t sequence = ++sequences_[child];
    return {sequence, sequence * 7919 + child};
  }

 private:
  std::map<std::uint32_t, std::uint64_t> sequences_;
};

Outcome send(MergeAggregator& aggregator, Streams& streams, std::uint32_t child, const MapMessage& message,
             std::int64_t now_ns) {
  return aggregator.onMap(child, streams.next(child), message, kWireBytes, now_ns);
}

// The outputs of one epoch (a root also publishes the epochs nobody reported, all missing).
std::vector<EpochOutput> forEpoch(std::vector<EpochOutput> outputs, std::uint64_t epoch) {
  std::erase_if(outputs, [&](const EpochOutput& o) { return o.epoch != epoch; });
  return outputs;
}

// Sends a map on its own node's stream and expects it admitted with `expected`.
void accept(MergeAggregator& aggregator, Streams& streams, const MapMessage& message, std::int64_t now_ns,
            Arrival expected = Arrival::kAccepted) {
  const Outcome outcome = send(aggregator, streams, message.header.node, message, now_ns);
  ASSERT_TRUE(outcome.ok()) << outcome.refused->message;
  EXPECT_EQ(outcome.arrival, expected);
}

// Sends a map and expects it refused for `reason`.
void expectRefused(MergeAggregator& aggregator, Streams& streams, std::uint32_t child, const MapMessage& message,
                   std::int64_t now_ns, Refusal reason) {
  const Outcome outcome = send(aggregator, streams, child, message, now_ns);
  ASSERT_FALSE(outcome.ok()) << "admitted, expected refused as " << refusalName(reason);
  EXPECT_EQ(outcome.refused->reason, reason) << outcome.refused->message;
  EXPECT_FALSE(outcome.refused->message.empty());
}

const GlobalMapMessage& globalOf(const EpochOutput& output) { return std::get<GlobalMapMessage>(output.message); }

// ---------------------------------------------------------------------------------------------
// Collect, merge, emit.

TEST(MergeAggregator, EmitsOnceEveryChildReportedAndEqualsMergeAll) {
  std::mt19937_64 rng(7);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2, 3}));
  connectAll(aggregator, {1, 2, 3});
  std::vector<Map> maps;
  for (std::uint32_t node = 1; node <= 3; ++node) maps.push_back(randomLocalMap(rng, node, E(5), 12));

  accept(aggregator, streams, mapMessage(2, E(5), maps[1], at(5, 3)), at(5, 10));
  accept(aggregator, streams, mapMessage(1, E(5), maps[0], at(5, 1)), at(5, 11));
  EXPECT_TRUE(aggregator.poll(at(5, 12)).empty()) << "child 3 is live and has not reported";
  accept(aggregator, streams, mapMessage(3, E(5), maps[2], at(5, 2)), at(5, 13));

  const auto outputs = aggregator.poll(at(5, 14));
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_TRUE(outputs[0].complete);
  EXPECT_EQ(outputs[0].revision, 0U);
  EXPECT_FALSE(outputs[0].late);
  const auto& global = globalOf(outputs[0]);
  const auto expected = mergeAll(maps);
  EXPECT_EQ(global.map, expected.map);
  EXPECT_LT(global.map.objects.size(), 36U) << "the scene is dense enough that some objects merge";
  EXPECT_EQ(global.header.node, kRoot);
  EXPECT_EQ(global.header.epoch, E(5));
  EXPECT_EQ(global.header.sensor_time_ns, at(5, 1)) << "the earliest contribution";
  EXPECT_EQ(global.header.contributing_nodes, (std::vector<std::uint32_t>{1, 2, 3}));
  EXPECT_TRUE(global.header.missing_nodes.empty());
  EXPECT_EQ(global.mode, Mode::kMadc);
  EXPECT_GT(global.pairs_all, 0U);
  EXPECT_LE(global.pairs_tested, global.pairs_all);
  EXPECT_EQ(global.pairs_tested, outputs[0].stats.pairs_tested);
  EXPECT_TRUE(global.point_labels.empty());
  ASSERT_TRUE(aggregator.latestGlobalMap().has_value());
  EXPECT_EQ(aggregator.latestGlobalMap()->header.epoch, E(5));

  EXPECT_TRUE(forEpoch(aggregator.poll(at(20, 0)), E(5)).empty()) << "an epoch is emitted once";
  EXPECT_EQ(aggregator.counters().revisions, 0U);
}

TEST(MergeAggregator, IntermediateSendsItsMergeToTheParentWithItsOwnId) {
  std::mt19937_64 rng(8);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}, Mode::kMadc, /*is_root=*/false));
  connectAll(aggregator, {1, 2});
  const std::vector<Map> maps{randomLocalMap(rng, 1, E(9), 6), randomLocalMap(rng, 2, E(9), 6)};
  accept(aggregator, streams, mapMessage(1, E(9), maps[0]), at(9, 5));
  accept(aggregator, streams, mapMessage(2, E(9), maps[1]), at(9, 5));
  const auto outputs = aggregator.poll(at(9, 6));
  ASSERT_EQ(outputs.size(), 1U);
  const auto& up = std::get<MapMessage>(outputs[0].message);
  EXPECT_EQ(up.header.node, kRoot);
  EXPECT_EQ(up.header.epoch, E(9));
  EXPECT_EQ(up.header.contributing_nodes, (std::vector<std::uint32_t>{1, 2}));
  EXPECT_EQ(up.map, mergeAll(maps).map);
  EXPECT_FALSE(aggregator.latestGlobalMap().has_value()) << "only the root holds a global map";
}

TEST(MergeAggregator, DisconnectedChildIsNotWaitedForAfterItsGrace) {
  std::mt19937_64 rng(9);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2, 3}));
  connectAll(aggregator, {1, 2, 3});
  aggregator.childDisconnected(3, at(0, 0));
  // Grace: one period and one deadline, 180 ms.
  EXPECT_EQ(aggregator.liveChildren(at(1, 79)), 3U);
  EXPECT_EQ(aggregator.liveChildren(at(1, 80)), 2U);
  EXPECT_EQ(aggregator.staleChildren(at(1, 80)), 1U);

  accept(aggregator, streams, mapMessage(1, E(2), randomLocalMap(rng, 1, E(2), 4)), at(2, 5));
  accept(aggregator, streams, mapMessage(2, E(2), randomLocalMap(rng, 2, E(2), 4)), at(2, 5));
  const auto outputs = aggregator.poll(at(2, 6));  // long before the deadline
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_TRUE(outputs[0].complete);
  EXPECT_EQ(globalOf(outputs[0]).header.missing_nodes, (std::vector<std::uint32_t>{3}));
}

TEST(MergeAggregator, BriefReconnectKeepsTheChildWaitedFor) {
  std::mt19937_64 rng(10);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  const auto first = mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 4));
  const auto second = mapMessage(2, E(1), randomLocalMap(rng, 2, E(1), 4));
  accept(aggregator, streams, first, at(1, 5));
  aggregator.childDisconnected(2, at(1, 10));  // its stream broke; it will reconnect and re-send
  EXPECT_TRUE(aggregator.poll(at(1, 20)).empty()) << "child 2 is within its grace: still waited for";
  ASSERT_TRUE(aggregator.childConnected(2).ok());
  accept(aggregator, streams, second, at(1, 40));
  const auto outputs = aggregator.poll(at(1, 41));
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_TRUE(outputs[0].complete);
  EXPECT_EQ(globalOf(outputs[0]).header.contributing_nodes, (std::vector<std::uint32_t>{1, 2}));
}

TEST(MergeAggregator, OverlappingStreamsOfOneChildKeepItLive) {
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  // Child 1 reconnects: the new stream opens before the old one is noticed closed.
  ASSERT_TRUE(aggregator.childConnected(1).ok());
  aggregator.childDisconnected(1, at(0, 0));
  EXPECT_EQ(aggregator.liveChildren(at(10, 0)), 2U) << "the new stream keeps the child live";
  aggregator.childDisconnected(1, at(10, 0));
  EXPECT_EQ(aggregator.liveChildren(at(20, 0)), 1U);
}

TEST(MergeAggregator, SilentConnectedChildDelaysEmissionUntilTheAbsoluteDeadline) {
  std::mt19937_64 rng(10);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2, 3}));
  connectAll(aggregator, {1, 2, 3});
  accept(aggregator, streams, mapMessage(1, E(4), randomLocalMap(rng, 1, E(4), 4)), at(4, 30));
  accept(aggregator, streams, mapMessage(2, E(4), randomLocalMap(rng, 2, E(4), 4)), at(4, 60));

  // The deadline is the epoch's start + 80 ms, not the first arrival + 80 ms.
  EXPECT_TRUE(aggregator.poll(at(4, 80) - 1).empty());
  const auto outputs = aggregator.poll(at(4, 80));
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_FALSE(outputs[0].complete);
  EXPECT_FALSE(outputs[0].late);
  EXPECT_EQ(globalOf(outputs[0]).header.contributing_nodes, (std::vector<std::uint32_t>{1, 2}));
  EXPECT_EQ(globalOf(outputs[0]).header.missing_nodes, (std::vector<std::uint32_t>{3}));
}

TEST(MergeAggregator, TheRootPublishesEveryEpochEvenWhenNoChildSendsAnything) {
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  // The first poll invents no history; from then on each epoch is published at its deadline with
  // every sensor missing, one per period, whether or not the children are connected.
  EXPECT_TRUE(aggregator.poll(at(0, 90)).empty());
  for (int k = 1; k <= 5; ++k) {
    EXPECT_TRUE(aggregator.poll(at(k, 80) - 1).empty()) << "epoch " << k << " before its deadline";
    const auto outputs = aggregator.poll(at(k, 80));
    ASSERT_EQ(outputs.size(), 1U) << "epoch " << k;
    EXPECT_EQ(outputs[0].epoch, E(k));
    EXPECT_FALSE(outputs[0].late);
    EXPECT_TRUE(globalOf(outputs[0]).map.objects.empty());
    EXPECT_TRUE(globalOf(outputs[0]).header.contributing_nodes.empty());
    EXPECT_EQ(globalOf(outputs[0]).header.missing_nodes, (std::vector<std::uint32_t>{1, 2}));
  }
  // A map that comes after its silent epoch was published makes a revision, flagged late.
  std::mt19937_64 rng(21);
  Streams streams;
  accept(aggregator, streams, mapMessage(1, E(5), randomLocalMap(rng, 1, E(5), 2)), at(5, 90), Arrival::kLate);
  const auto revision = aggregator.poll(at(5, 91));
  ASSERT_EQ(revision.size(), 1U);
  EXPECT_EQ(revision[0].revision, 1U);
  EXPECT_TRUE(revision[0].late);
  // After a stall of the root (it polls next at epoch 25), every epoch it missed is published, in
  // order, those more than a period past their deadline flagged late.
  const auto after_stall = aggregator.poll(at(25, 80));
  ASSERT_EQ(after_stall.size(), 20U);
  for (std::size_t i = 0; i < after_stall.size(); ++i) {
    EXPECT_EQ(after_stall[i].epoch, E(6 + static_cast<std::int64_t>(i)));
    EXPECT_EQ(after_stall[i].revision, 0U);
    EXPECT_EQ(after_stall[i].late, after_stall[i].epoch < E(24)) << "epoch +" << i;
  }
  EXPECT_LE(aggregator.pendingEpochs() + aggregator.retainedEpochs(), aggregator.windowEpochs());
  EXPECT_EQ(aggregator.counters().dropped_epochs, 0U);
  EXPECT_EQ(aggregator.counters().caught_up, 18U) << "epochs 6 to 23 were opened after their deadline + a period";
  EXPECT_EQ(aggregator.counters().longest_poll_gap_ns, at(25, 80) - at(5, 91));
  // A stall beyond max_pending_epochs (64 periods): the newest 64 are published, the older ones
  // are counted as dropped, never silently left out.
  const auto after_long_stall = aggregator.poll(at(205, 80));
  ASSERT_EQ(after_long_stall.size(), 64U);
  EXPECT_EQ(after_long_stall.front().epoch, E(142));
  EXPECT_EQ(after_long_stall.back().epoch, E(205));
  EXPECT_EQ(aggregator.counters().dropped_epochs, 116U);
  EXPECT_EQ(aggregator.counters().caught_up, 18U + 62U);
  EXPECT_LE(aggregator.pendingEpochs() + aggregator.retainedEpochs(), aggregator.windowEpochs());
}

TEST(MergeAggregator, TheRootPublishesEveryEpochInOrderUnderAnySchedule) {
  // Random arrival schedules (children skipping epochs, maps a period ahead or after the deadline,
  // polls at random instants with gaps of up to a second): the first emission of every epoch
  // from the first poll's due epoch on comes exactly once, in epoch order, and is flagged late
  // exactly when it came more than a period after its deadline.
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    std::mt19937_64 rng(seed);
    Streams streams;
    auto aggregator = makeAggregator(starConfig({1, 2, 3}));
    connectAll(aggregator, {1, 2, 3});
    std::uniform_int_distribution<int> step_ms(1, 120);
    std::uniform_int_distribution<int> coin(0, 9);
    std::int64_t now = at(0, 0);
    std::vector<std::pair<std::uint64_t, bool>> first;  // (epoch, late) of first emissions
    ASSERT_TRUE(aggregator.poll(now).empty());  // the first poll: the root publishes from here on
    std::int64_t last_poll = now;
    std::set<std::pair<std::uint32_t, std::uint64_t>> sent;
    for (int i = 0; i < 400; ++i) {
      now += step_ms(rng) * kMs * (coin(rng) == 0 ? 8 : 1);
      const auto epoch_now = static_cast<std::int64_t>(static_cast<std::uint64_t>(now / kPeriodNs) - kE0);
      for (std::uint32_t child = 1; child <= 3; ++child) {
        // A map of this epoch, the last one or the next one, now and then; some epochs never.
        const std::int64_t k = epoch_now + (coin(rng) % 3) - 1;
        if (coin(rng) < 4 || !sent.emplace(child, E(k)).second) continue;
        (void)send(aggregator, streams, child, mapMessage(child, E(k), randomLocalMap(rng, child, E(k), 2)), now);
      }
      for (const auto& out : aggregator.poll(now)) {
        if (out.revision != 0) continue;
        first.emplace_back(out.epoch, out.late);
        const std::int64_t deadline = static_cast<std::int64_t>(out.epoch) * kPeriodNs + 80 * kMs;
        EXPECT_EQ(out.late, now > deadline + kPeriodNs) << "seed " << seed;
      }
      last_poll = now;
    }
    ASSERT_FALSE(first.empty());
    for (std::size_t i = 1; i < first.size(); ++i) {
      ASSERT_EQ(first[i].first, first[i - 1].first + 1) << "seed " << seed << ": epoch after " << first[i - 1].first;
    }
    // At least up to the last poll's due epoch (later ones when complete early).
    EXPECT_GE(first.back().first, static_cast<std::uint64_t>((last_poll - 80 * kMs) / kPeriodNs)) << "seed " << seed;
    EXPECT_EQ(aggregator.counters().dropped_epochs, 0U);
  }
}

TEST(MergeAggregator, AnEpochCompleteEarlyWaitsForTheOlderOneSoEpochsAreEmittedInOrder) {
  std::mt19937_64 rng(12);
  Streams streams;
  // A deadline longer than the period (as at a root over several levels): epoch 2 can be complete
  // while epoch 1 is not yet due.
  auto config = starConfig({1, 2});
  config.deadline_ms = 250.0;
  auto aggregator = makeAggregator(config);
  connectAll(aggregator, {1, 2});
  // Child 2 skips epoch 1 (behind its schedule) and sends epoch 2 at once: epoch 2 is complete
  // before epoch 1 is due, but it is not emitted before it.
  accept(aggregator, streams, mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 2)), at(1, 10));
  accept(aggregator, streams, mapMessage(1, E(2), randomLocalMap(rng, 1, E(2), 2)), at(2, 5));
  accept(aggregator, streams, mapMessage(2, E(2), randomLocalMap(rng, 2, E(2), 2)), at(2, 6));
  EXPECT_TRUE(aggregator.poll(at(2, 7)).empty()) << "epoch 2 waits for epoch 1 (due at +250 ms)";
  auto outputs = aggregator.poll(at(1, 250));  // epoch 1's deadline
  std::erase_if(outputs, [](const EpochOutput& o) { return o.epoch < E(1); });  // silent epoch 0
  ASSERT_EQ(outputs.size(), 2U);
  EXPECT_EQ(outputs[0].epoch, E(1));
  EXPECT_FALSE(outputs[0].complete);
  EXPECT_EQ(outputs[1].epoch, E(2));
  EXPECT_TRUE(outputs[1].complete);
}

TEST(MergeAggregator, AnIntermediateInventsNoEpochs) {
  auto aggregator = makeAggregator(starConfig({1, 2}, Mode::kMadc, /*is_root=*/false));
  connectAll(aggregator, {1, 2});
  EXPECT_TRUE(aggregator.poll(at(0, 90)).empty());
  EXPECT_TRUE(aggregator.poll(at(3, 90)).empty());
}

TEST(MergeAggregator, EmitsDueEpochsOldestFirst) {
  std::mt19937_64 rng(13);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  accept(aggregator, streams, mapMessage(1, E(7), randomLocalMap(rng, 1, E(7), 2)), at(7, 10));
  accept(aggregator, streams, mapMessage(1, E(6), randomLocalMap(rng, 1, E(6), 2)), at(7, 11));
  accept(aggregator, streams, mapMessage(1, E(8), randomLocalMap(rng, 1, E(8), 2)), at(7, 50));
  const auto outputs = aggregator.poll(at(7, 81));
  ASSERT_EQ(outputs.size(), 2U) << "epoch 8 is not due yet";
  EXPECT_EQ(outputs[0].epoch, E(6));
  EXPECT_EQ(outputs[1].epoch, E(7));
  EXPECT_EQ(aggregator.pendingEpochs(), 1U);
}

TEST(MergeAggregator, TreeOfThreeLevelsNeverDropsAnOnTimeMap) {
  // root (3 levels) over {mid (2 levels) over leaf (1 level) over edges 1 and 2, edge 3}. Edge 2
  // is connected and silent, so the leaf waits out its deadline; each hop then takes almost a
  // whole deadline. With deadlines counted from each aggregator's first arrival the root emitted
  // at edge 3's arrival + 80 ms and refused the mid's on-time map as late.
  std::mt19937_64 rng(30);
  Streams streams;
  constexpr std::uint32_t kLeaf = 10;
  constexpr std::uint32_t kMid = 20;
  AggregatorConfig leaf_config = starConfig({1, 2}, Mode::kMadc, /*is_root=*/false);
  leaf_config.node = kLeaf;
  AggregatorConfig mid_config = starConfig({}, Mode::kMadc, /*is_root=*/false);
  mid_config.node = kMid;
  mid_config.levels = 2;
  mid_config.children = {{kLeaf, {1, 2}, "leaf"}};
  AggregatorConfig root_config = starConfig({}, Mode::kMadc, /*is_root=*/true);
  root_config.levels = 3;
  root_config.children = {{kMid, {1, 2}, "mid"}, {3, {3}, "edge-3"}};
  auto leaf = makeAggregator(leaf_config);
  auto mid = makeAggregator(mid_config);
  auto root = makeAggregator(root_config);
  connectAll(leaf, {1, 2});
  connectAll(mid, {kLeaf});
  connectAll(root, {kMid, 3});

  const Map edge1 = randomLocalMap(rng, 1, E(1), 5);
  const Map edge3 = randomLocalMap(rng, 3, E(1), 5);
  accept(root, streams, mapMessage(3, E(1), edge3), at(1, 5));
  accept(leaf, streams, mapMessage(1, E(1), edge1), at(1, 5));
  EXPECT_TRUE(root.poll(at(1, 86)).empty()) << "the root waits for the mid until its own deadline";

  EXPECT_TRUE(leaf.poll(at(1, 79)).empty());
  auto from_leaf = leaf.poll(at(1, 80));
  ASSERT_EQ(from_leaf.size(), 1U);
  EXPECT_FALSE(from_leaf[0].complete) << "edge 2 never reported";
  const auto& leaf_map = std::get<MapMessage>(from_leaf[0].message);
  accept(mid, streams, leaf_map, at(1, 159));  // one hop of 79 ms
  auto from_mid = mid.poll(at(1, 159));
  ASSERT_EQ(from_mid.size(), 1U);
  EXPECT_TRUE(from_mid[0].complete);
  const auto& mid_map = std::get<MapMessage>(from_mid[0].message);
  EXPECT_TRUE(forEpoch(root.poll(at(1, 238)), E(1)).empty());
  accept(root, streams, mid_map, at(1, 239));  // another hop of 80 ms: still on time
  const auto outputs = forEpoch(root.poll(at(1, 239)), E(1));
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_TRUE(outputs[0].complete);
  EXPECT_FALSE(outputs[0].late);
  const auto& global = globalOf(outputs[0]);
  EXPECT_EQ(global.header.contributing_nodes, (std::vector<std::uint32_t>{1, 3}));
  EXPECT_EQ(global.header.missing_nodes, (std::vector<std::uint32_t>{2}));
  const std::vector<Map> maps{edge1, edge3};
  EXPECT_EQ(global.map, mergeAll(maps).map);
  EXPECT_EQ(root.counters().late, 0U);
}

TEST(MergeAggregator, EarlyMapCannotEmitItsEpochBeforeTheEpochBegins) {
  std::mt19937_64 rng(31);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  // Both children report epoch 1 in epoch 0 (within the admission window; a clock ahead).
  accept(aggregator, streams, mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 3)), at(0, 50));
  accept(aggregator, streams, mapMessage(2, E(1), randomLocalMap(rng, 2, E(1), 3)), at(0, 60));
  EXPECT_TRUE(aggregator.poll(at(0, 99)).empty());
  const auto outputs = aggregator.poll(at(1, 0));
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_TRUE(outputs[0].complete);
}

TEST(MergeAggregator, DrainEmitsEveryOpenEpoch) {
  std::mt19937_64 rng(32);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  accept(aggregator, streams, mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 3)), at(1, 5));
  accept(aggregator, streams, mapMessage(1, E(2), randomLocalMap(rng, 1, E(2), 3)), at(1, 50));
  const auto outputs = aggregator.drain(at(1, 60));
  ASSERT_EQ(outputs.size(), 2U) << "shutdown abandons no accepted map";
  EXPECT_EQ(outputs[0].epoch, E(1));
  EXPECT_EQ(outputs[1].epoch, E(2));
  EXPECT_FALSE(outputs[0].complete);
  EXPECT_EQ(globalOf(outputs[1]).header.contributing_nodes, (std::vector<std::uint32_t>{1}));
  EXPECT_EQ(aggregator.pendingEpochs(), 0U);
}

TEST(MergeAggregator, LateMapIsMergedIntoARevisionFlaggedLate) {
  std::mt19937_64 rng(11);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  const auto first = mapMessage(1, E(4), randomLocalMap(rng, 1, E(4), 4));
  const auto second = mapMessage(2, E(4), randomLocalMap(rng, 2, E(4), 4));
  accept(aggregator, streams, first, at(4, 5));
  const auto on_time = aggregator.poll(at(4, 80));
  ASSERT_EQ(on_time.size(), 1U);
  EXPECT_EQ(globalOf(on_time[0]).header.missing_nodes, (std::vector<std::uint32_t>{2}));

  // Child 2's map arrives after the emission (say, re-sent after a reconnect): not lost.
  accept(aggregator, streams, second, at(4, 120), Arrival::kLate);
  EXPECT_EQ(aggregator.counters().late, 1U);
  EXPECT_EQ(aggregator.pendingEpochs(), 0U) << "a late map opens no epoch";
  const auto revisions = aggregator.poll(at(4, 121));
  ASSERT_EQ(revisions.size(), 1U);
  EXPECT_EQ(revisions[0].epoch, E(4));
  EXPECT_EQ(revisions[0].revision, 1U);
  EXPECT_TRUE(revisions[0].late);
  const auto& revised = globalOf(revisions[0]);
  EXPECT_EQ(revised.revision, 1U);
  EXPECT_TRUE(revised.late);
  EXPECT_EQ(revised.header.contributing_nodes, (std::vector<std::uint32_t>{1, 2}));
  const std::vector<Map> maps{first.map, second.map};
  EXPECT_EQ(revised.map, mergeAll(maps).map);
  EXPECT_EQ(aggregator.counters().revisions, 1U);
  EXPECT_EQ(aggregator.counters().late_emits, 1U);
  EXPECT_EQ(aggregator.latestGlobalMap()->revision, 0U) << "geofences answer on on-time maps";
  EXPECT_TRUE(forEpoch(aggregator.poll(at(4, 200)), E(4)).empty()) << "one revision per batch of late maps";

  // Past the admission window the epoch is forgotten: a stale re-send is refused, counted.
  expectRefused(aggregator, streams, 2, second, at(8, 0), Refusal::kClockSkew);
  EXPECT_TRUE(forEpoch(aggregator.poll(at(8, 0)), E(4)).empty());
  EXPECT_EQ(aggregator.counters().revisions, 1U);
}

TEST(MergeAggregator, StallEmitsStaleEpochsFlaggedLate) {
  std::mt19937_64 rng(33);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  accept(aggregator, streams, mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 3)), at(1, 5));
  accept(aggregator, streams, mapMessage(1, E(2), randomLocalMap(rng, 1, E(2), 3)), at(2, 5));
  // The aggregator stalls (SIGSTOP, a long GC of the host) and polls again at epoch 3 + 70 ms:
  // epoch 1's deadline + one period passed, so it is stale; epoch 2 is merely due.
  const auto outputs = aggregator.poll(at(3, 70));
  ASSERT_EQ(outputs.size(), 2U);
  EXPECT_TRUE(outputs[0].late) << "emitted more than a period after its deadline";
  EXPECT_FALSE(outputs[1].late);
  EXPECT_EQ(aggregator.latestGlobalMap()->header.epoch, E(2));
  EXPECT_EQ(aggregator.counters().late_emits, 1U);
}

TEST(MergeAggregator, DropsTheOldestEpochBeyondMaxPendingAndSaysSo) {
  std::mt19937_64 rng(14);
  Streams streams;
  auto config = starConfig({1, 2});
  config.max_pending_epochs = 2;
  auto aggregator = makeAggregator(config);
  connectAll(aggregator, {1, 2});
  for (std::int64_t k = 1; k <= 3; ++k) {
    accept(aggregator, streams, mapMessage(1, E(k), randomLocalMap(rng, 1, E(k), 2)), at(1, 0));
  }
  EXPECT_EQ(aggregator.pendingEpochs(), 2U);
  EXPECT_EQ(aggregator.counters().dropped_epochs, 1U);
  const auto outputs = aggregator.poll(at(2, 80));
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_EQ(outputs[0].epoch, E(2));
  EXPECT_EQ(globalOf(outputs[0]).header.dropped_uploads, 1U) << "the dropped epoch shows in the header";
}

TEST(MergeAggregator, DroppedUploadsOfTheSubtreeAppearInTheHeader) {
  std::mt19937_64 rng(34);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}, Mode::kMadc, /*is_root=*/false));
  connectAll(aggregator, {1, 2});
  auto first = mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 2));
  first.header.dropped_uploads = 7;
  auto second = mapMessage(2, E(1), randomLocalMap(rng, 2, E(1), 2));
  second.header.dropped_uploads = 2;
  accept(aggregator, streams, first, at(1, 5));
  accept(aggregator, streams, second, at(1, 5));
  aggregator.setLinkDrops(3);  // this node's own link to its parent
  const auto outputs = aggregator.poll(at(1, 6));
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_EQ(std::get<MapMessage>(outputs[0].message).header.dropped_uploads, 12U);
}

TEST(MergeAggregator, FailedFrameCompletesTheChildButDoesNotContribute) {
  std::mt19937_64 rng(35);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  accept(aggregator, streams, mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 3)), at(1, 5));
  MapMessage failed = mapMessage(2, E(1), {});
  failed.header.contributing_nodes.clear();
  failed.header.failed_nodes = {2};
  accept(aggregator, streams, failed, at(1, 6));
  const auto outputs = aggregator.poll(at(1, 7));
  ASSERT_EQ(outputs.size(), 1U) << "the failed frame answered for child 2: no wait for the deadline";
  EXPECT_TRUE(outputs[0].complete);
  const auto& header = globalOf(outputs[0]).header;
  EXPECT_EQ(header.contributing_nodes, (std::vector<std::uint32_t>{1}));
  EXPECT_EQ(header.missing_nodes, (std::vector<std::uint32_t>{2}));
  EXPECT_EQ(header.failed_nodes, (std::vector<std::uint32_t>{2}));
}

TEST(MergeAggregator, ResolvesStreamsToDirectChildrenInATree) {
  AggregatorConfig config;
  config.node = kRoot;
  config.is_root = true;
  config.mode = Mode::kBaseline;
  config.children = {{10, {1, 2}, "agg-10"}, {11, {3, 4}, "agg-11"}, {5, {5}, "edge-5"}};
  auto aggregator = makeAggregator(config);
  EXPECT_EQ(aggregator.sensors(), (std::vector<std::uint32_t>{1, 2, 3, 4, 5}));
  // An intermediate's own id, a sensor relayed through it, and an edge child.
  EXPECT_EQ(*aggregator.childConnected(10), 10U);
  EXPECT_EQ(*aggregator.childConnected(4), 11U);
  EXPECT_EQ(*aggregator.childConnected(5), 5U);
  const auto unknown = aggregator.childConnected(42);
  ASSERT_FALSE(unknown.ok());
  EXPECT_EQ(unknown.error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(aggregator.counters().refused.at(Refusal::kUnknownNode), 1U);
  EXPECT_EQ(aggregator.liveChildren(at(0, 0)), 3U);
  aggregator.childDisconnected(11, at(0, 0));
  EXPECT_EQ(aggregator.liveChildren(at(2, 0)), 2U);
}

TEST(MergeAggregator, CertificateNameFixesTheStreamsChild) {
  AggregatorConfig config = starConfig({});
  config.children = {{10, {1, 2}, "agg-10"}, {11, {3, 4}, "agg-11"}, {5, {5}, "edge-5"}};
  auto aggregator = makeAggregator(config);
  EXPECT_EQ(aggregator.peerConnected("agg-11"), 11U);
  EXPECT_EQ(aggregator.peerConnected("edge-5"), 5U);
  // A sensor below a child is not a child: with TLS it cannot speak to the root directly.
  EXPECT_EQ(aggregator.peerConnected("edge-1"), std::nullopt);
  EXPECT_EQ(aggregator.peerConnected("sink"), std::nullopt);
  EXPECT_EQ(aggregator.peerConnected(""), std::nullopt);
  EXPECT_EQ(aggregator.liveChildren(at(0, 0)), 2U);
  EXPECT_TRUE(aggregator.counters().refused.empty()) << "unknown peers are counted per refused upload, not per stream";
  aggregator.childDisconnected(11, at(0, 0));
  EXPECT_EQ(aggregator.liveChildren(at(2, 0)), 1U);
}

TEST(MergeAggregator, RejectsInvalidConfig) {
  EXPECT_FALSE(MergeAggregator::create(starConfig({1, 1})).ok());
  auto no_deadline = starConfig({1});
  no_deadline.deadline_ms = 0.0;
  EXPECT_FALSE(MergeAggregator::create(no_deadline).ok());
  auto no_period = starConfig({1});
  no_period.period_ms = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(MergeAggregator::create(no_period).ok());
  AggregatorConfig shared_sensor = starConfig({});
  shared_sensor.children = {{10, {1}, "agg-10"}, {11, {1}, "agg-11"}};
  EXPECT_FALSE(MergeAggregator::create(shared_sensor).ok());
  auto no_window = starConfig({1});
  no_window.admission.window_periods = 0.0;
  EXPECT_FALSE(MergeAggregator::create(no_window).ok());
}

TEST(MergeAggregator, AggregatorConfigForDerivesChildrenLevelsAndSchedule) {
  TopologyConfig topology;
  topology.name = "t";
  topology.period_ms = 50.0;
  topology.deadline_ms = 20.0;
  topology.admission.max_ellipsoids_per_map = 77;
  using test_support::node;
  topology.nodes = {node(100, "root", Role::kAggregator, ""), node(20, "mid", Role::kAggregator, "root"),
                    node(10, "leaf", Role::kAggregator, "mid"), node(1, "e1", Role::kEdge, "leaf"),
                    node(2, "e2", Role::kEdge, "leaf"), node(3, "e3", Role::kEdge, "root")};
  const auto root = aggregatorConfigFor(topology, "root");
  ASSERT_TRUE(root.ok()) << root.error().message;
  EXPECT_TRUE(root->is_root);
  EXPECT_EQ(root->node, 100U);
  EXPECT_EQ(root->levels, 3);
  EXPECT_EQ(root->period_ms, 50.0);
  EXPECT_EQ(root->deadline_ms, 20.0);
  EXPECT_EQ(root->admission.max_ellipsoids_per_map, 77U);
  ASSERT_EQ(root->children.size(), 2U);
  std::map<std::uint32_t, std::vector<std::uint32_t>> children;
  for (const auto& child : root->children) children[child.id] = child.sensors;
  EXPECT_EQ(children.at(20), (std::vector<std::uint32_t>{1, 2}));
  EXPECT_EQ(children.at(3), (std::vector<std::uint32_t>{3}));
  const auto leaf = aggregatorConfigFor(topology, "leaf");
  ASSERT_TRUE(leaf.ok());
  EXPECT_FALSE(leaf->is_root);
  EXPECT_EQ(leaf->levels, 1);
  EXPECT_EQ(aggregatorConfigFor(topology, "mid")->levels, 2);
  EXPECT_FALSE(aggregatorConfigFor(topology, "e1").ok()) << "an edge is not an aggregator";
  EXPECT_FALSE(aggregatorConfigFor(topology, "nobody").ok());
}

// ---------------------------------------------------------------------------------------------
// Admission: what a hostile or broken child cannot do.

TEST(MergeAggregator, RefusesEpochsOutsideTheAdmissionWindow) {
  std::mt19937_64 rng(40);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}));  // window: 3 periods
  connectAll(aggregator, {1, 2});
  const std::int64_t now = at(0, 0);
  // 500 ms ahead: it would start that epoch's clock early and be published partial.
  expectRefused(aggregator, streams, 1, mapMessage(1, E(5), randomLocalMap(rng, 1, E(5), 2)), now, Refusal::kClockSkew);
  // The last epoch there is: it would freeze the latest global map for good.
  const std::uint64_t last = std::numeric_limits<std::uint64_t>::max();
  expectRefused(aggregator, streams, 1, mapMessage(1, last, randomLocalMap(rng, 1, last, 2)), now, Refusal::kClockSkew);
  // Long past: a stale re-send, or a clock far behind.
  expectRefused(aggregator, streams, 1, mapMessage(1, E(-10), randomLocalMap(rng, 1, E(-10), 2)), now,
                Refusal::kClockSkew);
  EXPECT_EQ(aggregator.pendingEpochs(), 0U);
  EXPECT_EQ(aggregator.counters().refused.at(Refusal::kClockSkew), 3U);
  // The edges of the window are admitted: 3 periods ahead, and a deadline 3 periods ago.
  accept(aggregator, streams, mapMessage(1, E(3), randomLocalMap(rng, 1, E(3), 2)), now);
  accept(aggregator, streams, mapMessage(1, E(-4), randomLocalMap(rng, 1, E(-4), 2)), at(-1, 80));
}

TEST(MergeAggregator, FloodOfDistinctEpochsCannotJamTheRoot) {
  std::mt19937_64 rng(41);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  const Map junk = randomLocalMap(rng, 1, 0, 2);
  for (std::uint64_t i = 0; i < 5000; ++i) {
    const Outcome outcome = send(aggregator, streams, 1, mapMessage(1, (1ULL << 62) + i, junk), at(0, 0));
    ASSERT_FALSE(outcome.ok());
  }
  EXPECT_EQ(aggregator.counters().refused.at(Refusal::kClockSkew), 5000U);
  EXPECT_EQ(aggregator.pendingEpochs(), 0U);
  EXPECT_EQ(aggregator.retainedEpochs(), 0U);
  // The honest maps of the next epochs are published as if nothing happened.
  for (std::int64_t k = 1; k <= 3; ++k) {
    accept(aggregator, streams, mapMessage(1, E(k), randomLocalMap(rng, 1, E(k), 3)), at(k, 5));
    accept(aggregator, streams, mapMessage(2, E(k), randomLocalMap(rng, 2, E(k), 3)), at(k, 6));
    const auto outputs = aggregator.poll(at(k, 7));
    ASSERT_EQ(outputs.size(), 1U);
    EXPECT_TRUE(outputs[0].complete);
    EXPECT_FALSE(outputs[0].late);
    EXPECT_EQ(aggregator.latestGlobalMap()->header.epoch, E(k));
  }
}

// What the core holds (open epochs, emitted epochs kept for late maps) stays within the admission
// window however many distinct epochs are offered: 200,000 uploads, each for an epoch never
// offered before, inside the window, just outside it either way, and absurdly far (2^63 and up,
// 0 and up), under a clock that advances one period every 1,000 uploads and is polled as the
// emitter polls it. Each upload is admitted exactly when an independent window check says so;
// everything else is refused and counted as clock skew.
TEST(MergeAggregator, FloodOfDistinctEpochsHoldsNoMoreThanTheAdmissionWindow) {
  constexpr std::uint64_t kUploads = 200'000;
  constexpr std::int64_t kTick = kPeriodNs / 1000;  // the clock's advance per upload
  constexpr std::uint64_t kPollEvery = 10;          // uploads between polls
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  const std::int64_t window = 3 * kPeriodNs;  // starConfig: window_periods 3, one level, deadline 80 ms
  const std::int64_t deadline = 80 * kMs;
  EXPECT_EQ(aggregator.windowEpochs(), 7U) << "(2 x 300 + 80) / 100 + 1";
  // The oracle, from the rule as documented: the epoch starts at most W after now and its deadline
  // passed at most W before now. Epochs beyond int64 time are never admitted.
  const auto admissible = [&](std::uint64_t epoch, std::int64_t now) {
    if (epoch > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max() / kPeriodNs) - 1) return false;
    const std::int64_t start = static_cast<std::int64_t>(epoch) * kPeriodNs;
    return start - now <= window && now - (start + deadline) <= window;
  };

  Streams streams;
  std::set<std::uint64_t> offered;
  std::uint64_t admitted = 0;
  std::uint64_t refused = 0;
  std::size_t most_held = 0;
  // Cursors over the epochs not offered yet: ahead beyond the run's last window, behind the window
  // (moving away as they are used), from 0 up, and from 2^63 up.
  std::uint64_t ahead = E(1000);
  std::uint64_t behind = std::numeric_limits<std::uint64_t>::max();
  std::uint64_t low = 0;
  std::uint64_t far = 1ULL << 63;
  for (std::uint64_t i = 0; i < kUploads; ++i) {
    const std::int64_t now = kT0 + static_cast<std::int64_t>(i) * kTick;
    const std::uint64_t current = static_cast<std::uint64_t>(now / kPeriodNs);
    std::uint64_t epoch = 0;
    switch (i % 5) {
      case 0:  // the window's epochs (and the one just behind it), each once; then far
        epoch = far;
        for (std::uint64_t k = current - 4; k <= current + 3; ++k) {
          if (!offered.contains(k)) {
            epoch = k;
            break;
          }
        }
        if (epoch == far) ++far;
        break;
      case 1:  // just ahead of the window in odd epochs (even ones are left to enter it), else beyond the run
        if ((current + 4) % 2 == 1 && !offered.contains(current + 4)) {
          epoch = current + 4;
        } else {
          while (offered.contains(ahead)) ++ahead;
          epoch = ahead++;
        }
        break;
      case 2:
        behind = std::min(behind, current - 5);
        while (offered.contains(behind)) --behind;
        epoch = behind;
        break;
      case 3: epoch = far++; break;
      default:
        while (offered.contains(low)) ++low;
        epoch = low;
        break;
    }
    ASSERT_TRUE(offered.insert(epoch).second) << "epoch " << epoch << " offered twice";
    const std::uint32_t node = 1 + static_cast<std::uint32_t>(i % 2);
    const auto message = mapMessage(node, epoch, localMap({ball(node, epoch, 0, {1, 2, 1})}));
    const Outcome outcome = send(aggregator, streams, node, message, now);
    const bool expected = admissible(epoch, now);
    ASSERT_EQ(outcome.ok(), expected) << "upload " << i << ", epoch " << static_cast<std::int64_t>(epoch - current)
                                      << " from now: " << (outcome.ok() ? "admitted" : outcome.refused->message);
    if (outcome.ok()) {
      ++admitted;
    } else {
      ASSERT_EQ(outcome.refused->reason, Refusal::kClockSkew) << outcome.refused->message;
      ++refused;
    }
    if (i % kPollEvery == kPollEvery - 1) {
      (void)aggregator.poll(now);
      const std::size_t held = aggregator.pendingEpochs() + aggregator.retainedEpochs();
      ASSERT_LE(held, aggregator.windowEpochs()) << "after upload " << i;
      most_held = std::max(most_held, held);
    }
  }
  EXPECT_EQ(admitted + refused, kUploads);
  EXPECT_GE(admitted, 90U) << "the window's epochs were offered and taken";
  EXPECT_EQ(aggregator.counters().refused.at(Refusal::kClockSkew), refused);
  EXPECT_EQ(aggregator.counters().refusedTotal(), refused);
  EXPECT_EQ(aggregator.counters().accepted + aggregator.counters().late, admitted);
  EXPECT_EQ(aggregator.counters().dropped_epochs, 0U) << "the window, not max_pending_epochs, bounds the epochs";
  EXPECT_LE(aggregator.rememberedUploads(), 2 * MergeAggregator::kUploadHistory);
  std::printf("%llu uploads of distinct epochs: %llu admitted, %llu refused (clock_skew); at most %zu epochs held "
              "(bound %zu)\n",
              static_cast<unsigned long long>(kUploads), static_cast<unsigned long long>(admitted),
              static_cast<unsigned long long>(refused), most_held, aggregator.windowEpochs());
}

TEST(MergeAggregator, SequenceHistoryIsBoundedPerChildAndRecentResendsAreStillRecognised) {
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1}));
  connectAll(aggregator, {1});
  const std::uint64_t uploads = 3 * MergeAggregator::kUploadHistory;
  for (std::uint64_t i = 0; i < uploads; ++i) {
    const std::int64_t now = at(0, 0) + static_cast<std::int64_t>(i) * kMs / 10;
    const std::uint64_t epoch = static_cast<std::uint64_t>(now / kPeriodNs);
    ASSERT_TRUE(aggregator.onMap(1, {i + 1, i + 1}, mapMessage(1, epoch, {}), kWireBytes, now).ok());
    if (i % 100 == 0) (void)aggregator.poll(now);
  }
  EXPECT_EQ(aggregator.rememberedUploads(), MergeAggregator::kUploadHistory);
  // The newest are remembered: a re-sent copy is a duplicate, the same sequence with other
  // content a conflict.
  const std::int64_t now = at(0, 0) + static_cast<std::int64_t>(uploads) * kMs / 10;
  const auto epoch = static_cast<std::uint64_t>(now / kPeriodNs);
  const std::uint64_t duplicates = aggregator.counters().duplicates;
  EXPECT_TRUE(aggregator.onMap(1, {uploads, uploads}, mapMessage(1, epoch, {}), kWireBytes, now).ok());
  EXPECT_EQ(aggregator.counters().duplicates, duplicates + 1);
  const Outcome conflict = aggregator.onMap(1, {uploads, 7}, mapMessage(1, epoch, {}), kWireBytes, now);
  ASSERT_FALSE(conflict.ok());
  EXPECT_EQ(conflict.refused->reason, Refusal::kSequenceConflict);
}

TEST(MergeAggregator, OneSensorsEllipsoidsInAnEpochAreBoundedLikeOneMap) {
  Streams streams;
  AggregatorConfig config = starConfig({1, 2});
  config.admission.max_ellipsoids_per_map = 10;
  auto aggregator = makeAggregator(config);
  connectAll(aggregator, {1, 2});
  // Maps of four new ids each, under new sequences: the third would bring node 1 to 12.
  const auto part = [&](std::uint32_t node, std::uint32_t first) {
    std::vector<Ellipsoid> ellipsoids;
    for (std::uint32_t k = first; k < first + 4; ++k) ellipsoids.push_back(ball(node, E(1), k, {3.0 * k, 0, 1}));
    return mapMessage(node, E(1), localMap(std::move(ellipsoids)));
  };
  accept(aggregator, streams, part(1, 0), at(1, 5));
  accept(aggregator, streams, part(1, 4), at(1, 5));
  expectRefused(aggregator, streams, 1, part(1, 8), at(1, 5), Refusal::kTooLarge);
  // Ids already held do not count again (a re-sent map), and the bound is per sensor.
  accept(aggregator, streams, part(1, 4), at(1, 6));
  accept(aggregator, streams, part(2, 0), at(1, 6));
  accept(aggregator, streams, part(2, 4), at(1, 6));
  const auto outputs = aggregator.poll(at(1, 7));
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_EQ(globalOf(outputs[0]).map.ellipsoidCount(), 16U);
}

TEST(MergeAggregator, StreamSpeaksForOneNodeOnly) {
  std::mt19937_64 rng(42);
  Streams streams;
  AggregatorConfig config = starConfig({1, 2});
  config.children.push_back({10, {5, 6}, "agg-10"});  // an intermediate over sensors 5 and 6
  auto aggregator = makeAggregator(config);
  connectAll(aggregator, {1, 2, 10});
  // On child 1's stream: a map claiming to be node 2's.
  expectRefused(aggregator, streams, 1, mapMessage(2, E(1), randomLocalMap(rng, 2, E(1), 2)), at(1, 5),
                Refusal::kForgedNode);
  // Node 1's own header, but speaking for node 2's sensor, or carrying its ellipsoids.
  auto contributing = mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 2));
  contributing.header.contributing_nodes = {1, 2};
  expectRefused(aggregator, streams, 1, contributing, at(1, 5), Refusal::kForgedNode);
  auto failed = mapMessage(1, E(1), {});
  failed.header.failed_nodes = {2};
  expectRefused(aggregator, streams, 1, failed, at(1, 5), Refusal::kForgedNode);
  expectRefused(aggregator, streams, 1, mapMessage(1, E(1), randomLocalMap(rng, 2, E(1), 2)), at(1, 5),
                Refusal::kForgedNode);
  // The intermediate may carry its sensors' ellipsoids, not another child's.
  auto relayed = mapMessage(10, E(1), randomLocalMap(rng, 5, E(1), 2));
  relayed.header.contributing_nodes = {5, 6};
  accept(aggregator, streams, relayed, at(1, 5));
  auto foreign = mapMessage(10, E(1), randomLocalMap(rng, 1, E(1), 2));
  foreign.header.contributing_nodes = {5};
  expectRefused(aggregator, streams, 10, foreign, at(1, 5), Refusal::kForgedNode);
  EXPECT_EQ(aggregator.counters().refused.at(Refusal::kForgedNode), 5U);
  EXPECT_EQ(aggregator.counters().accepted, 1U);
}

TEST(MergeAggregator, RefusesMapsBeyondSizeAndValueBounds) {
  std::mt19937_64 rng(43);
  Streams streams;
  AggregatorConfig config = starConfig({1});
  config.admission.max_ellipsoids_per_map = 10;
  auto aggregator = makeAggregator(config);
  connectAll(aggregator, {1});
  const std::int64_t now = at(1, 5);
  expectRefused(aggregator, streams, 1, mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 11)), now, Refusal::kTooLarge);
  const auto bytes = aggregator.onMap(1, streams.next(1), mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 2)),
                                      config.admission.max_map_bytes + 1, now);
  ASSERT_FALSE(bytes.ok());
  EXPECT_EQ(bytes.refused->reason, Refusal::kTooLarge);

  const auto with = [&](const Eigen::Vector3d& centre, const Eigen::Matrix3d& shape) {
    Map map = randomLocalMap(rng, 1, E(1), 2);
    std::vector<Ellipsoid> ellipsoids{map.objects[0].ellipsoids[0]};
    ellipsoids[0].center = centre;
    ellipsoids[0].shape = shape;
    return mapMessage(1, E(1), localMap(std::move(ellipsoids)));
  };
  const Eigen::Matrix3d unit = Eigen::Matrix3d::Identity();
  expectRefused(aggregator, streams, 1, with({1e30, 0, 0}, unit), now, Refusal::kOutOfWorld);
  expectRefused(aggregator, streams, 1, with({0, 0, 2e4}, unit), now, Refusal::kOutOfWorld);
  const Eigen::Matrix3d needle = Eigen::Vector3d(1e30, 1e-30, 1e-30).asDiagonal();  // condition 1e60
  expectRefused(aggregator, streams, 1, with({0, 0, 0}, needle), now, Refusal::kBadShape);
  const Eigen::Matrix3d thin = Eigen::Vector3d(1e7, 1, 1e-6).asDiagonal();  // in bounds, condition 1e13
  expectRefused(aggregator, streams, 1, with({0, 0, 0}, thin), now, Refusal::kBadShape);
  const Eigen::Matrix3d flat = Eigen::Vector3d(1, 1, 1e-20).asDiagonal();
  expectRefused(aggregator, streams, 1, with({0, 0, 0}, flat), now, Refusal::kBadShape);
  EXPECT_EQ(aggregator.pendingEpochs(), 0U) << "nothing refused opened an epoch";
  accept(aggregator, streams, with({3, 4, 1}, unit), now);
}

TEST(MergeAggregator, SameSequenceWithOtherContentIsRefused) {
  std::mt19937_64 rng(44);
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  const auto first = mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 3));
  const auto other = mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 5));
  const UploadKey key{42, 1111};
  ASSERT_TRUE(aggregator.onMap(1, key, first, kWireBytes, at(1, 5)).ok());
  const Outcome resent = aggregator.onMap(1, key, first, kWireBytes, at(1, 6));
  ASSERT_TRUE(resent.ok()) << "a re-sent copy is harmless";
  EXPECT_EQ(aggregator.counters().duplicates, 1U);
  const Outcome conflict = aggregator.onMap(1, UploadKey{42, 2222}, other, kWireBytes, at(1, 7));
  ASSERT_FALSE(conflict.ok());
  EXPECT_EQ(conflict.refused->reason, Refusal::kSequenceConflict);

  // Only the first was merged.
  Streams streams;
  accept(aggregator, streams, mapMessage(2, E(1), {}), at(1, 8));
  const auto outputs = aggregator.poll(at(1, 9));
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_EQ(globalOf(outputs[0]).map, first.map);
}

TEST(MergeAggregator, SameEllipsoidIdWithOtherGeometryIsRefused) {
  std::mt19937_64 rng(45);
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  const auto first = mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 3));
  accept(aggregator, streams, first, at(1, 5));
  // A restarted edge re-sends the same map under a new sequence: the same ids, same geometry.
  accept(aggregator, streams, first, at(1, 6));
  // The same ids with other geometry: one of them is wrong, and MERGE must not pick silently.
  expectRefused(aggregator, streams, 1, mapMessage(1, E(1), randomLocalMap(rng, 1, E(1), 3)), at(1, 7),
                Refusal::kEllipsoidConflict);
  accept(aggregator, streams, mapMessage(2, E(1), {}), at(1, 8));
  const auto outputs = aggregator.poll(at(1, 9));
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_EQ(globalOf(outputs[0]).map, first.map);
}

TEST(MergeAggregator, RefusesUploadsOfTheWrongModeOrFromStrangers) {
  Streams streams;
  auto madc = makeAggregator(starConfig({1}));
  expectRefused(madc, streams, 9, mapMessage(9, E(1), {}), at(1, 0), Refusal::kUnknownNode);
  PointChunk chunk;
  chunk.header.node = 1;
  chunk.header.epoch = E(1);
  const Outcome points = madc.onPoints(1, streams.next(1), chunk, kWireBytes, at(1, 0));
  ASSERT_FALSE(points.ok());
  EXPECT_EQ(points.refused->reason, Refusal::kWrongMode);
  auto baseline = makeAggregator(starConfig({1}, Mode::kBaseline));
  expectRefused(baseline, streams, 1, mapMessage(1, E(1), {}), at(1, 0), Refusal::kWrongMode);
  EXPECT_EQ(baseline.pendingEpochs(), 0U);
  EXPECT_EQ(madc.refuse(Refusal::kMalformed, "a message that does not convert").reason, Refusal::kMalformed);
  EXPECT_EQ(madc.counters().refused.at(Refusal::kMalformed), 1U);
  EXPECT_EQ(madc.counters().refusedTotal(), 3U);
}

// ---------------------------------------------------------------------------------------------
// Baseline and ext: points.

// Gaussian blobs of `per_blob` points (sigma 0.1 m) at the given centres, plus scattered noise.
Cloud blobs(std::mt19937_64& rng, const std::vector<Eigen::Vector3f>& centres, int per_blob, int noise) {
  std::normal_distribution<float> jitter(0.0F, 0.1F);
  std::uniform_real_distribution<float> anywhere(-40.0F, 40.0F);
  Cloud cloud;
  for (const auto& c : centres) {
    for (int i = 0; i < per_blob; ++i) cloud.push_back({c.x() + jitter(rng), c.y() + jitter(rng), c.z() + jitter(rng), 0.0F});
  }
  for (int i = 0; i < noise; ++i) cloud.push_back({anywhere(rng), anywhere(rng), 30.0F, 0.0F});
  std::shuffle(cloud.begin(), cloud.end(), rng);
  return cloud;
}

// Two sensors that both see blobs 2 and 3, so central clustering joins points across sensors.
std::vector<Cloud> twoSensorScene(std::mt19937_64& rng) {
  const std::vector<Eigen::Vector3f> centres{{0, 0, 1}, {4, 0, 1}, {8, 0, 1}, {12, 0, 1}, {16, 0, 1}, {20, 0, 1}};
  return {blobs(rng, {centres[0], centres[1], centres[2], centres[3]}, 40, 5),
          blobs(rng, {centres[2], centres[3], centres[4], centres[5]}, 30, 5)};
}

// Splits a scan into `parts` chunks.
std::vector<PointChunk> chunksOf(std::uint32_t node, std::uint64_t epoch, const Cloud& cloud, std::uint32_t parts,
                                 const std::vector<std::int32_t>& labels = {}) {
  std::vector<PointChunk> chunks;
  const std::size_t per = (cloud.size() + parts - 1) / parts;
  for (std::uint32_t k = 0; k < parts; ++k) {
    PointChunk chunk;
    chunk.header.node = node;
    chunk.header.epoch = epoch;
    chunk.header.sensor_time_ns = kT0;
    chunk.header.contributing_nodes = {node};
    chunk.chunk = k;
    chunk.chunk_count = parts;
    const std::size_t begin = std::min(cloud.size(), k * per);
    const std::size_t end = std::min(cloud.size(), begin + per);
    chunk.first_point = static_cast<std::uint32_t>(begin);
    chunk.total_points = static_cast<std::uint32_t>(cloud.size());
    chunk.points.assign(cloud.begin() + static_cast<std::ptrdiff_t>(begin), cloud.begin() + static_cast<std::ptrdiff_t>(end));
    if (!labels.empty()) {
      chunk.labels.assign(labels.begin() + static_cast<std::ptrdiff_t>(begin), labels.begin() + static_cast<std::ptrdiff_t>(end));
    }
    chunks.push_back(std::move(chunk));
  }
  return chunks;
}

void acceptChunk(MergeAggregator& aggregator, Streams& streams, std::uint32_t child, PointChunk chunk,
                 std::int64_t now_ns) {
  const Outcome outcome = aggregator.onPoints(child, streams.next(child), std::move(chunk), kWireBytes, now_ns);
  ASSERT_TRUE(outcome.ok()) << outcome.refused->message;
  EXPECT_EQ(outcome.arrival, Arrival::kAccepted);
}

TEST(MergeAggregator, BaselineRootLeavesTheClusteringToTheCallerAndLabelsEveryPoint) {
  std::mt19937_64 rng(21);
  Streams streams;
  const auto clouds = twoSensorScene(rng);
  auto aggregator = makeAggregator(starConfig({1, 2}, Mode::kBaseline));
  connectAll(aggregator, {1, 2});
  // Sensor 2 first and chunks out of order: the result must still follow sensor-id order.
  auto chunks2 = chunksOf(2, E(3), clouds[1], 3);
  auto chunks1 = chunksOf(1, E(3), clouds[0], 4);
  for (int k : {2, 0, 1}) acceptChunk(aggregator, streams, 2, chunks2[static_cast<std::size_t>(k)], at(3, 5));
  for (int k : {3, 1, 0}) acceptChunk(aggregator, streams, 1, chunks1[static_cast<std::size_t>(k)], at(3, 5));
  EXPECT_TRUE(aggregator.poll(at(3, 6)).empty()) << "sensor 1's scan is incomplete";
  const UploadKey key = streams.next(1);
  ASSERT_TRUE(aggregator.onPoints(1, key, chunks1[2], kWireBytes, at(3, 7)).ok());
  ASSERT_TRUE(aggregator.onPoints(1, key, chunks1[2], kWireBytes, at(3, 7)).ok()) << "a re-sent chunk is harmless";
  EXPECT_EQ(aggregator.counters().duplicates, 1U);

  const auto outputs = aggregator.poll(at(3, 8));
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_TRUE(outputs[0].complete);
  // The core hands out the job; the clustering runs outside the lock, and published() records it.
  ASSERT_TRUE(std::holds_alternative<BaselineJob>(outputs[0].message));
  EXPECT_FALSE(aggregator.latestGlobalMap().has_value());
  const GlobalMapMessage global = clusterCentrally(std::get<BaselineJob>(outputs[0].message));
  aggregator.published(global);
  ASSERT_TRUE(aggregator.latestGlobalMap().has_value());
  EXPECT_EQ(aggregator.latestGlobalMap()->header.epoch, E(3));

  Cloud all = clouds[0];
  all.insert(all.end(), clouds[1].begin(), clouds[1].end());
  const MadcParams params;
  const Clustering central = euclideanClusters(all, params.clustering);
  ASSERT_EQ(central.cluster_count, 6) << "the scene: six blobs, two of them seen by both sensors";
  ASSERT_EQ(global.map.objects.size(), 6U);
  const auto summaries = summarizeClusters(all, central);
  for (std::size_t k = 0; k < summaries.size(); ++k) {
    ASSERT_EQ(global.map.objects[k].ellipsoids.size(), 1U);
    const EllipsoidId id{kRoot, E(3), static_cast<std::uint32_t>(k)};
    EXPECT_EQ(global.map.objects[k].ellipsoids[0], ellipsoidFromSummary(summaries[k], id, params.ellipsoidParams()));
  }
  ASSERT_EQ(global.point_labels.size(), 2U);
  EXPECT_EQ(global.point_labels[0].node, 1U);
  EXPECT_EQ(global.point_labels[1].node, 2U);
  const std::vector<std::int32_t> first(central.labels.begin(), central.labels.begin() + static_cast<std::ptrdiff_t>(clouds[0].size()));
  const std::vector<std::int32_t> second(central.labels.begin() + static_cast<std::ptrdiff_t>(clouds[0].size()), central.labels.end());
  EXPECT_EQ(global.point_labels[0].labels, first);
  EXPECT_EQ(global.point_labels[1].labels, second);
  EXPECT_EQ(global.header.contributing_nodes, (std::vector<std::uint32_t>{1, 2}));
  EXPECT_EQ(global.mode, Mode::kBaseline);
}

TEST(MergeAggregator, ABaselineRootOfWholeScansPreprocessesEachAsAnEdgeWouldThenClustersThem) {
  // Whole scans: the six blobs plus far points the crop box cuts away and a dense voxel-sized pair.
  std::mt19937_64 rng(23);
  auto clouds = twoSensorScene(rng);
  for (Cloud& cloud : clouds) {
    cloud.push_back({90.0F, 0.0F, 1.0F, 0.0F});
    cloud.push_back({90.1F, 0.0F, 1.0F, 0.0F});
  }
  PreprocessConfig preprocess;
  preprocess.crop = CropBox{};                 // +-50 m: the far points go
  preprocess.voxel_leaf_m = 0.05;
  BaselineJob whole;
  whole.node = kRoot;
  whole.preprocess = preprocess;
  BaselineJob prepared = whole;
  prepared.preprocess.reset();
  for (std::uint32_t sensor : {1U, 2U}) {
    const Cloud& scan = clouds[sensor - 1];
    whole.scans.emplace_back(sensor, scan);
    const auto cut = preprocessScan(scan, preprocess);
    ASSERT_TRUE(cut.ok());
    ASSERT_LT(cut->size(), scan.size());
    prepared.scans.emplace_back(sensor, *cut);
  }
  // The oracle: the same clustering of scans pre-processed beforehand.
  const GlobalMapMessage expected = clusterCentrally(prepared);
  const GlobalMapMessage actual = clusterCentrally(whole);
  EXPECT_EQ(actual.map, expected.map);
  ASSERT_EQ(actual.point_labels.size(), 2U);
  for (std::size_t i = 0; i < 2; ++i) EXPECT_EQ(actual.point_labels[i].labels, expected.point_labels[i].labels);
  EXPECT_EQ(actual.map.objects.size(), 6U);

  // The topology decides: a raw baseline's root gets the topology's pre-processing, no transform.
  TopologyConfig topology = makeStarTopology(2, "scans", 51000);
  topology.mode = Mode::kBaseline;
  topology.preprocess.voxel_leaf_m = 0.1;
  EXPECT_FALSE(aggregatorConfigFor(topology, "sink")->preprocess.has_value());
  topology.baseline_ships_raw = true;
  const auto config = aggregatorConfigFor(topology, "sink");
  ASSERT_TRUE(config.ok() && config->preprocess.has_value());
  EXPECT_EQ(config->preprocess->voxel_leaf_m, 0.1);
  EXPECT_TRUE(config->preprocess->sensor_to_common.isApprox(Eigen::Isometry3d::Identity()));
}

TEST(MergeAggregator, BaselineRootSkipsSensorsUnderDeadChildren) {
  std::mt19937_64 rng(22);
  Streams streams;
  const auto clouds = twoSensorScene(rng);
  AggregatorConfig config = starConfig({}, Mode::kBaseline);
  // An intermediate over sensors 1 and 2, and edge 3.
  config.children = {{10, {1, 2}, "agg-10"}, {3, {3}, "edge-3"}};
  auto aggregator = makeAggregator(config);
  const auto child = aggregator.childConnected(1);  // the intermediate's stream, named by a relayed chunk
  ASSERT_TRUE(child.ok());
  ASSERT_EQ(*child, 10U);
  for (auto& chunk : chunksOf(1, E(2), clouds[0], 2)) acceptChunk(aggregator, streams, 10, chunk, at(2, 5));
  EXPECT_TRUE(aggregator.poll(at(2, 6)).empty()) << "sensor 2 is below a live child";
  for (auto& chunk : chunksOf(2, E(2), clouds[1], 2)) acceptChunk(aggregator, streams, 10, chunk, at(2, 7));
  const auto outputs = aggregator.poll(at(2, 8));
  ASSERT_EQ(outputs.size(), 1U) << "edge 3 never connected: not waited for";
  EXPECT_TRUE(outputs[0].complete);
  const auto& job = std::get<BaselineJob>(outputs[0].message);
  EXPECT_EQ(job.message.header.missing_nodes, (std::vector<std::uint32_t>{3}));
  EXPECT_EQ(job.scans.size(), 2U);
}

TEST(MergeAggregator, BaselineChunksSpeakForTheirStreamsSensorsOnly) {
  std::mt19937_64 rng(25);
  Streams streams;
  const auto clouds = twoSensorScene(rng);
  auto aggregator = makeAggregator(starConfig({1, 2}, Mode::kBaseline));
  connectAll(aggregator, {1, 2});
  const auto chunk = chunksOf(2, E(1), clouds[1], 2)[0];
  const Outcome forged = aggregator.onPoints(1, streams.next(1), chunk, kWireBytes, at(1, 5));
  ASSERT_FALSE(forged.ok());
  EXPECT_EQ(forged.refused->reason, Refusal::kForgedNode);
  auto far = chunksOf(1, E(1), clouds[0], 1)[0];
  far.points[3].x = 1e30F;
  const Outcome out_of_world = aggregator.onPoints(1, streams.next(1), far, kWireBytes, at(1, 5));
  ASSERT_FALSE(out_of_world.ok());
  EXPECT_EQ(out_of_world.refused->reason, Refusal::kOutOfWorld);
  const Outcome future = aggregator.onPoints(1, streams.next(1), chunksOf(1, E(9), clouds[0], 1)[0], kWireBytes,
                                             at(1, 5));
  ASSERT_FALSE(future.ok());
  EXPECT_EQ(future.refused->reason, Refusal::kClockSkew);
  EXPECT_EQ(aggregator.pendingEpochs(), 0U);
}

// A sensor's chunks of an epoch hold at most its scan's points: chunks that cannot tile it (more
// chunks than points, empty chunks of a non-empty scan, more points than the scan) are refused
// before they are stored, so no stream of distinct chunk indices grows the epoch.
TEST(MergeAggregator, ChunksCannotStoreMoreThanTheirScan) {
  std::mt19937_64 rng(27);
  Streams streams;
  const auto clouds = twoSensorScene(rng);
  auto aggregator = makeAggregator(starConfig({1, 2}, Mode::kBaseline));
  connectAll(aggregator, {1, 2});
  const auto chunks = chunksOf(1, E(1), clouds[0], 2);
  const auto refusedAs = [&](PointChunk chunk, Refusal reason) {
    const Outcome outcome = aggregator.onPoints(1, streams.next(1), std::move(chunk), kWireBytes, at(1, 5));
    ASSERT_FALSE(outcome.ok());
    EXPECT_EQ(outcome.refused->reason, reason) << outcome.refused->message;
  };
  PointChunk many = chunks[0];
  many.chunk_count = many.total_points + 1;
  refusedAs(many, Refusal::kMalformed);
  PointChunk empty = chunks[1];
  empty.chunk = 7;
  empty.chunk_count = 8;
  empty.points.clear();
  refusedAs(empty, Refusal::kMalformed);
  acceptChunk(aggregator, streams, 1, chunks[0], at(1, 5));
  PointChunk again = chunks[0];  // the whole scan under the second index: the first chunk twice
  again.chunk = 1;
  again.points = clouds[0];
  refusedAs(again, Refusal::kInconsistentChunks);
  acceptChunk(aggregator, streams, 1, chunks[0], at(1, 6));  // an identical re-send is harmless
  acceptChunk(aggregator, streams, 1, chunks[1], at(1, 6));
  EXPECT_EQ(aggregator.counters().refused.at(Refusal::kMalformed), 2U);
  EXPECT_EQ(aggregator.counters().refused.at(Refusal::kInconsistentChunks), 1U);
}

TEST(MergeAggregator, IntermediateRelaysPointChunksAtOnce) {
  std::mt19937_64 rng(23);
  Streams streams;
  const auto clouds = twoSensorScene(rng);
  auto aggregator = makeAggregator(starConfig({1, 2}, Mode::kBaseline, /*is_root=*/false));
  connectAll(aggregator, {1, 2});
  const auto chunk = chunksOf(1, E(2), clouds[0], 2)[1];
  const Outcome outcome = aggregator.onPoints(1, streams.next(1), chunk, kWireBytes, at(2, 5));
  ASSERT_TRUE(outcome.ok());
  EXPECT_EQ(outcome.arrival, Arrival::kRelay);
  ASSERT_TRUE(outcome.relay.has_value());
  EXPECT_EQ(*outcome.relay, chunk);
  EXPECT_EQ(aggregator.pendingEpochs(), 0U);
  EXPECT_TRUE(aggregator.poll(at(5, 0)).empty());
  EXPECT_EQ(aggregator.counters().relayed, 1U);
}

TEST(MergeAggregator, ExtRootLabelsPointsWithTheirGlobalObjects) {
  std::mt19937_64 rng(24);
  Streams streams;
  const auto clouds = twoSensorScene(rng);
  const MadcParams params;
  const std::uint64_t epoch = E(6);
  auto aggregator = makeAggregator(starConfig({1, 2}, Mode::kExt));
  connectAll(aggregator, {1, 2});
  std::vector<LocalMapResult> locals;
  std::vector<Map> maps;
  for (std::uint32_t s = 0; s < 2; ++s) {
    locals.push_back(genLocalMap(clouds[s], s + 1, epoch, params).value());
    maps.push_back(locals.back().map);
    accept(aggregator, streams, mapMessage(s + 1, epoch, locals.back().map), at(6, 5));
  }
  EXPECT_TRUE(aggregator.poll(at(6, 6)).empty()) << "ext waits for the points too";
  for (std::uint32_t s = 0; s < 2; ++s) {
    for (auto& chunk : chunksOf(s + 1, epoch, clouds[s], 3, locals[s].clustering.labels)) {
      acceptChunk(aggregator, streams, s + 1, chunk, at(6, 7));
    }
  }
  const auto outputs = aggregator.poll(at(6, 8));
  ASSERT_EQ(outputs.size(), 1U);
  const auto& global = globalOf(outputs[0]);
  const Map expected = mergeAll(maps).map;
  ASSERT_EQ(global.map, expected);
  ASSERT_EQ(global.point_labels.size(), 2U);

  std::set<std::int32_t> shared_objects[2];
  for (std::uint32_t s = 0; s < 2; ++s) {
    const auto& labels = global.point_labels[s];
    ASSERT_EQ(labels.node, s + 1);
    ASSERT_EQ(labels.labels.size(), clouds[s].size());
    for (std::size_t i = 0; i < labels.labels.size(); ++i) {
      const std::int32_t local = locals[s].clustering.labels[i];
      if (local < 0) {
        EXPECT_EQ(labels.labels[i], -1);
        continue;
      }
      const std::int32_t object = labels.labels[i];
      ASSERT_GE(object, 0);
      ASSERT_LT(static_cast<std::size_t>(object), expected.objects.size());
      const auto& ellipsoids = expected.objects[static_cast<std::size_t>(object)].ellipsoids;
      const EllipsoidId id{s + 1, epoch, static_cast<std::uint32_t>(local)};
      EXPECT_TRUE(std::any_of(ellipsoids.begin(), ellipsoids.end(), [&](const Ellipsoid& e) { return e.id == id; }))
          << "point " << i << " of sensor " << s + 1;
      shared_objects[s].insert(object);
    }
  }
  std::vector<std::int32_t> common;
  std::set_intersection(shared_objects[0].begin(), shared_objects[0].end(), shared_objects[1].begin(),
                        shared_objects[1].end(), std::back_inserter(common));
  EXPECT_EQ(common.size(), 2U) << "the two blobs both sensors see are one object each";
}

// ---------------------------------------------------------------------------------------------
// Geofences.

TEST(MergeAggregator, GeofencesAreSetReplacedAndQueriedOnTheLatestGlobalMap) {
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1}));
  connectAll(aggregator, {1});
  EXPECT_EQ(*aggregator.setGeofence(boxGeofence("zone", {-1, -1, -1}, {1, 1, 1})), 1U);
  const auto before = aggregator.queryGeofences("");
  ASSERT_TRUE(before.ok());
  EXPECT_EQ(before->epoch, 0U);
  EXPECT_TRUE(before->intrusions.empty()) << "no global map yet";

  accept(aggregator, streams, mapMessage(1, E(1), localMap({ball(1, E(1), 0, {0, 0, 0}), ball(1, E(1), 1, {10, 0, 0})})),
         at(1, 5));
  ASSERT_EQ(aggregator.poll(at(1, 6)).size(), 1U);
  const auto inside = aggregator.queryGeofences("zone");
  ASSERT_TRUE(inside.ok());
  EXPECT_EQ(inside->epoch, E(1));
  ASSERT_EQ(inside->intrusions.size(), 1U);
  EXPECT_EQ(inside->intrusions[0].geofence, "zone");
  EXPECT_EQ(inside->intrusions[0].object_index, 0U);
  EXPECT_EQ(inside->intrusions[0].containment, Containment::kInside);
  EXPECT_EQ(inside->intrusions[0].ellipsoids, (std::vector<EllipsoidId>{{1, E(1), 0}}));

  // Same name: replaced, not added. The new zone cuts the second ball.
  EXPECT_EQ(*aggregator.setGeofence(boxGeofence("zone", {10, -1, -1}, {11, 1, 1})), 1U);
  const auto crossing = aggregator.queryGeofences("zone");
  ASSERT_EQ(crossing->intrusions.size(), 1U);
  EXPECT_EQ(crossing->intrusions[0].object_index, 1U);
  EXPECT_EQ(crossing->intrusions[0].containment, Containment::kCrossing);

  EXPECT_EQ(*aggregator.setGeofence(boxGeofence("everything", {-50, -50, -50}, {50, 50, 50})), 2U);
  EXPECT_EQ(aggregator.queryGeofences("")->intrusions.size(), 3U);
  const auto missing = aggregator.queryGeofences("nowhere");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kNotFound);
  const auto invalid = aggregator.setGeofence(Geofence{"empty", {}});
  ASSERT_FALSE(invalid.ok());
  EXPECT_EQ(invalid.error().code, ErrorCode::kInvalidArgument);

  auto intermediate = makeAggregator(starConfig({1}, Mode::kMadc, /*is_root=*/false));
  EXPECT_FALSE(intermediate.setGeofence(boxGeofence("zone", {-1, -1, -1}, {1, 1, 1})).ok());
}

TEST(MergeAggregator, GeofencesAreBoundedInNumberAndSize) {
  auto aggregator = makeAggregator(starConfig({1}));
  for (std::size_t i = 0; i < MergeAggregator::kMaxGeofences; ++i) {
    ASSERT_TRUE(aggregator.setGeofence(boxGeofence("zone-" + std::to_string(i), {-1, -1, -1}, {1, 1, 1})).ok());
  }
  const auto one_more = aggregator.setGeofence(boxGeofence("one-more", {-1, -1, -1}, {1, 1, 1}));
  ASSERT_FALSE(one_more.ok());
  EXPECT_EQ(one_more.error().code, ErrorCode::kResourceExhausted) << one_more.error().message;
  const auto replaced = aggregator.setGeofence(boxGeofence("zone-0", {-2, -2, -2}, {2, 2, 2}));
  ASSERT_TRUE(replaced.ok()) << "replacing one by name is always possible";
  EXPECT_EQ(*replaced, MergeAggregator::kMaxGeofences);
  Geofence facets = boxGeofence("facets", {-1, -1, -1}, {1, 1, 1});
  while (facets.half_spaces.size() <= kMaxHalfSpaces) facets.half_spaces.push_back(facets.half_spaces.front());
  const auto too_many = aggregator.setGeofence(facets);
  ASSERT_FALSE(too_many.ok());
  EXPECT_EQ(too_many.error().code, ErrorCode::kInvalidArgument);
  const std::string long_name_text(kMaxGeofenceNameBytes + 1, 'z');
  const auto long_name = aggregator.setGeofence(boxGeofence(long_name_text, {-1, -1, -1}, {1, 1, 1}));
  ASSERT_FALSE(long_name.ok());
  EXPECT_EQ(long_name.error().code, ErrorCode::kInvalidArgument);
}

TEST(MergeAggregator, GeofencesAnswerOnTheNewestOnTimeEpochOnly) {
  Streams streams;
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  ASSERT_TRUE(aggregator.setGeofence(boxGeofence("zone", {-1, -1, -1}, {1, 1, 1})).ok());
  accept(aggregator, streams, mapMessage(1, E(2), localMap({ball(1, E(2), 0, {0, 0, 0})})), at(2, 5));
  ASSERT_EQ(aggregator.poll(at(2, 80)).size(), 1U);
  // A late revision of an older epoch, and an older epoch emitted after a newer one, change nothing.
  accept(aggregator, streams, mapMessage(2, E(2), localMap({ball(2, E(2), 0, {30, 0, 0})})), at(2, 90), Arrival::kLate);
  ASSERT_EQ(aggregator.poll(at(2, 91)).size(), 1U);
  GlobalMapMessage older;
  older.header.epoch = E(1);
  aggregator.published(older);
  const auto report = aggregator.queryGeofences("zone");
  ASSERT_TRUE(report.ok());
  EXPECT_EQ(report->epoch, E(2));
  EXPECT_EQ(aggregator.latestGlobalMap()->revision, 0U);
  EXPECT_EQ(report->intrusions.size(), 1U);
}

}  // namespace
}  // namespace fogmap
