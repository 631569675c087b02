#include "services/merge_aggregator/aggregator_core.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include <Eigen/Geometry>

#include "common/clustering.hpp"
#include "common/madc.hpp"

namespace fogmap {
namespace {

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kT0 = 1'700'000'000'000'000'000;  // an arbitrary unix time in ns
constexpr std::uint32_t kRoot = 100;

AggregatorConfig starConfig(std::vector<std::uint32_t> edges, Mode mode = Mode::kMadc, bool is_root = true) {
  AggregatorConfig config;
  config.node = kRoot;
  config.mode = mode;
  config.is_root = is_root;
  config.deadline_ms = 80.0;
  for (const auto edge : edges) config.children.push_back({edge, {edge}});
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

Arrival accept(MergeAggregator& aggregator, const MapMessage& message, std::int64_t now_ns) {
  const auto arrival = aggregator.onMap(message, now_ns);
  EXPECT_TRUE(arrival.ok()) << (arrival.ok() ? "" : arrival.error().message);
  return arrival.ok() ? *arrival : Arrival::kAccepted;
}

const GlobalMapMessage& globalOf(const EpochOutput& output) { return std::get<GlobalMapMessage>(output.message); }

TEST(MergeAggregator, EmitsOnceEveryChildReportedAndEqualsMergeAll) {
  std::mt19937_64 rng(7);
  auto aggregator = makeAggregator(starConfig({1, 2, 3}));
  connectAll(aggregator, {1, 2, 3});
  std::vector<Map> maps;
  for (std::uint32_t node = 1; node <= 3; ++node) maps.push_back(randomLocalMap(rng, node, 5, 12));

  EXPECT_EQ(accept(aggregator, mapMessage(2, 5, maps[1], kT0 + 3 * kMs), kT0 + 10 * kMs), Arrival::kAccepted);
  EXPECT_EQ(accept(aggregator, mapMessage(1, 5, maps[0], kT0 + 1 * kMs), kT0 + 11 * kMs), Arrival::kAccepted);
  EXPECT_TRUE(aggregator.poll(kT0 + 12 * kMs).empty()) << "child 3 is live and has not reported";
  EXPECT_EQ(accept(aggregator, mapMessage(3, 5, maps[2], kT0 + 2 * kMs), kT0 + 13 * kMs), Arrival::kAccepted);

  const auto outputs = aggregator.poll(kT0 + 14 * kMs);
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_TRUE(outputs[0].complete);
  const auto& global = globalOf(outputs[0]);
  const auto expected = mergeAll(maps);
  EXPECT_EQ(global.map, expected.map);
  EXPECT_LT(global.map.objects.size(), 36U) << "the scene is dense enough that some objects merge";
  EXPECT_EQ(global.header.node, kRoot);
  EXPECT_EQ(global.header.epoch, 5U);
  EXPECT_EQ(global.header.sensor_time_ns, kT0 + 1 * kMs) << "the earliest contribution";
  EXPECT_EQ(global.header.contributing_nodes, (std::vector<std::uint32_t>{1, 2, 3}));
  EXPECT_TRUE(global.header.missing_nodes.empty());
  EXPECT_EQ(global.mode, Mode::kMadc);
  EXPECT_GT(global.pairs_all, 0U);
  EXPECT_LE(global.pairs_tested, global.pairs_all);
  EXPECT_EQ(global.pairs_tested, outputs[0].stats.pairs_tested);
  EXPECT_TRUE(global.point_labels.empty());

  EXPECT_TRUE(aggregator.poll(kT0 + 1000 * kMs).empty()) << "an epoch is emitted once";
  EXPECT_EQ(aggregator.counters().emitted, 1U);
}

TEST(MergeAggregator, IntermediateSendsItsMergeToTheParentWithItsOwnId) {
  std::mt19937_64 rng(8);
  auto config = starConfig({1, 2}, Mode::kMadc, /*is_root=*/false);
  auto aggregator = makeAggregator(config);
  connectAll(aggregator, {1, 2});
  const std::vector<Map> maps{randomLocalMap(rng, 1, 9, 6), randomLocalMap(rng, 2, 9, 6)};
  accept(aggregator, mapMessage(1, 9, maps[0]), kT0);
  accept(aggregator, mapMessage(2, 9, maps[1]), kT0);
  const auto outputs = aggregator.poll(kT0);
  ASSERT_EQ(outputs.size(), 1U);
  const auto& up = std::get<MapMessage>(outputs[0].message);
  EXPECT_EQ(up.header.node, kRoot);
  EXPECT_EQ(up.header.epoch, 9U);
  EXPECT_EQ(up.header.contributing_nodes, (std::vector<std::uint32_t>{1, 2}));
  EXPECT_EQ(up.map, mergeAll(maps).map);
}

TEST(MergeAggregator, DisconnectedChildIsNotWaitedFor) {
  std::mt19937_64 rng(9);
  auto aggregator = makeAggregator(starConfig({1, 2, 3}));
  connectAll(aggregator, {1, 2, 3});
  aggregator.childDisconnected(3);
  EXPECT_EQ(aggregator.liveChildren(), 2U);
  EXPECT_EQ(aggregator.staleChildren(), 1U);

  accept(aggregator, mapMessage(1, 1, randomLocalMap(rng, 1, 1, 4)), kT0);
  accept(aggregator, mapMessage(2, 1, randomLocalMap(rng, 2, 1, 4)), kT0);
  const auto outputs = aggregator.poll(kT0 + 1 * kMs);  // long before the deadline
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_TRUE(outputs[0].complete);
  EXPECT_EQ(globalOf(outputs[0]).header.missing_nodes, (std::vector<std::uint32_t>{3}));
}

TEST(MergeAggregator, SilentConnectedChildDelaysEmissionUntilTheDeadline) {
  std::mt19937_64 rng(10);
  auto aggregator = makeAggregator(starConfig({1, 2, 3}));
  connectAll(aggregator, {1, 2, 3});
  accept(aggregator, mapMessage(1, 4, randomLocalMap(rng, 1, 4, 4)), kT0);
  accept(aggregator, mapMessage(2, 4, randomLocalMap(rng, 2, 4, 4)), kT0 + 30 * kMs);

  EXPECT_TRUE(aggregator.poll(kT0 + 80 * kMs - 1).empty()) << "deadline = first arrival + 80 ms";
  const auto outputs = aggregator.poll(kT0 + 80 * kMs);
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_FALSE(outputs[0].complete);
  EXPECT_EQ(globalOf(outputs[0]).header.contributing_nodes, (std::vector<std::uint32_t>{1, 2}));
  EXPECT_EQ(globalOf(outputs[0]).header.missing_nodes, (std::vector<std::uint32_t>{3}));
}

TEST(MergeAggregator, LateMapIsCountedAndDropped) {
  std::mt19937_64 rng(11);
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  accept(aggregator, mapMessage(1, 4, randomLocalMap(rng, 1, 4, 4)), kT0);
  ASSERT_EQ(aggregator.poll(kT0 + 80 * kMs).size(), 1U);

  EXPECT_EQ(accept(aggregator, mapMessage(2, 4, randomLocalMap(rng, 2, 4, 4)), kT0 + 81 * kMs), Arrival::kLate);
  EXPECT_EQ(aggregator.counters().late, 1U);
  EXPECT_EQ(aggregator.pendingEpochs(), 0U) << "a late map opens no epoch";
  EXPECT_TRUE(aggregator.poll(kT0 + 1000 * kMs).empty());
  // The next epoch is unaffected.
  EXPECT_EQ(accept(aggregator, mapMessage(2, 5, randomLocalMap(rng, 2, 5, 4)), kT0 + 90 * kMs), Arrival::kAccepted);
}

TEST(MergeAggregator, DuplicateDeliveryAfterReconnectIsHarmless) {
  std::mt19937_64 rng(12);
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  const auto first = mapMessage(1, 3, randomLocalMap(rng, 1, 3, 8));
  const auto second = mapMessage(2, 3, randomLocalMap(rng, 2, 3, 8));
  accept(aggregator, first, kT0);
  // Child 1 reconnects (the new stream opens before the old one is noticed closed) and re-sends.
  ASSERT_TRUE(aggregator.childConnected(1).ok());
  aggregator.childDisconnected(1);
  EXPECT_EQ(aggregator.liveChildren(), 2U) << "the new stream keeps the child live";
  accept(aggregator, first, kT0 + 1 * kMs);
  accept(aggregator, second, kT0 + 2 * kMs);

  const auto outputs = aggregator.poll(kT0 + 3 * kMs);
  ASSERT_EQ(outputs.size(), 1U);
  const std::vector<Map> maps{first.map, second.map};
  EXPECT_EQ(globalOf(outputs[0]).map, mergeAll(maps).map);
}

TEST(MergeAggregator, EmitsDueEpochsOldestFirst) {
  std::mt19937_64 rng(13);
  auto aggregator = makeAggregator(starConfig({1, 2}));
  connectAll(aggregator, {1, 2});
  accept(aggregator, mapMessage(1, 7, randomLocalMap(rng, 1, 7, 2)), kT0);
  accept(aggregator, mapMessage(1, 6, randomLocalMap(rng, 1, 6, 2)), kT0 + 1 * kMs);
  accept(aggregator, mapMessage(1, 8, randomLocalMap(rng, 1, 8, 2)), kT0 + 50 * kMs);
  const auto outputs = aggregator.poll(kT0 + 81 * kMs);
  ASSERT_EQ(outputs.size(), 2U) << "epoch 8 is not due yet";
  EXPECT_EQ(outputs[0].epoch, 6U);
  EXPECT_EQ(outputs[1].epoch, 7U);
  EXPECT_EQ(aggregator.pendingEpochs(), 1U);
}

TEST(MergeAggregator, DropsTheOldestEpochBeyondMaxPending) {
  std::mt19937_64 rng(14);
  auto config = starConfig({1, 2});
  config.max_pending_epochs = 2;
  auto aggregator = makeAggregator(config);
  connectAll(aggregator, {1, 2});
  for (std::uint64_t epoch = 1; epoch <= 3; ++epoch) {
    accept(aggregator, mapMessage(1, epoch, randomLocalMap(rng, 1, epoch, 2)), kT0);
  }
  EXPECT_EQ(aggregator.pendingEpochs(), 2U);
  EXPECT_EQ(aggregator.counters().dropped_epochs, 1U);
  EXPECT_EQ(accept(aggregator, mapMessage(2, 1, randomLocalMap(rng, 2, 1, 2)), kT0), Arrival::kLate);
}

TEST(MergeAggregator, ResolvesStreamsToDirectChildrenInATree) {
  AggregatorConfig config;
  config.node = kRoot;
  config.is_root = true;
  config.mode = Mode::kBaseline;
  config.children = {{10, {1, 2}}, {11, {3, 4}}, {5, {5}}};
  auto aggregator = makeAggregator(config);
  EXPECT_EQ(aggregator.sensors(), (std::vector<std::uint32_t>{1, 2, 3, 4, 5}));
  // An intermediate's own id, a sensor relayed through it, and an edge child.
  EXPECT_EQ(*aggregator.childConnected(10), 10U);
  EXPECT_EQ(*aggregator.childConnected(4), 11U);
  EXPECT_EQ(*aggregator.childConnected(5), 5U);
  const auto unknown = aggregator.childConnected(42);
  ASSERT_FALSE(unknown.ok());
  EXPECT_EQ(unknown.error().code, ErrorCode::kInvalidArgument);
  EXPECT_EQ(aggregator.liveChildren(), 3U);
  aggregator.childDisconnected(11);
  EXPECT_EQ(aggregator.liveChildren(), 2U);
}

TEST(MergeAggregator, RejectsInvalidConfigAndMismatchedUploads) {
  auto duplicate = starConfig({1, 1});
  EXPECT_FALSE(MergeAggregator::create(duplicate).ok());
  auto no_deadline = starConfig({1});
  no_deadline.deadline_ms = 0.0;
  EXPECT_FALSE(MergeAggregator::create(no_deadline).ok());
  AggregatorConfig shared_sensor = starConfig({});
  shared_sensor.children = {{10, {1}}, {11, {1}}};
  EXPECT_FALSE(MergeAggregator::create(shared_sensor).ok());

  auto madc = makeAggregator(starConfig({1}));
  EXPECT_FALSE(madc.onMap(mapMessage(9, 1, {}), kT0).ok()) << "not a child";
  PointChunk chunk;
  chunk.header.node = 1;
  EXPECT_FALSE(madc.onPoints(chunk, kT0).ok()) << "points in madc mode";
  auto baseline = makeAggregator(starConfig({1}, Mode::kBaseline));
  EXPECT_FALSE(baseline.onMap(mapMessage(1, 1, {}), kT0).ok()) << "maps in baseline mode";
  EXPECT_EQ(baseline.pendingEpochs(), 0U);
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

void acceptChunk(MergeAggregator& aggregator, PointChunk chunk, std::int64_t now_ns) {
  const auto arrival = aggregator.onPoints(std::move(chunk), now_ns);
  ASSERT_TRUE(arrival.ok()) << arrival.error().message;
  EXPECT_EQ(arrival->arrival, Arrival::kAccepted);
}

TEST(MergeAggregator, BaselineRootClustersTheUnionAndLabelsEveryPoint) {
  std::mt19937_64 rng(21);
  const auto clouds = twoSensorScene(rng);
  auto aggregator = makeAggregator(starConfig({1, 2}, Mode::kBaseline));
  connectAll(aggregator, {1, 2});
  // Sensor 2 first and chunks out of order: the result must still follow sensor-id order.
  auto chunks2 = chunksOf(2, 3, clouds[1], 3);
  auto chunks1 = chunksOf(1, 3, clouds[0], 4);
  for (int k : {2, 0, 1}) acceptChunk(aggregator, chunks2[static_cast<std::size_t>(k)], kT0);
  for (int k : {3, 1, 0}) acceptChunk(aggregator, chunks1[static_cast<std::size_t>(k)], kT0);
  EXPECT_TRUE(aggregator.poll(kT0 + 1 * kMs).empty()) << "sensor 1's scan is incomplete";
  acceptChunk(aggregator, chunks1[2], kT0 + 2 * kMs);
  acceptChunk(aggregator, chunks1[2], kT0 + 2 * kMs);  // a re-sent chunk changes nothing

  const auto outputs = aggregator.poll(kT0 + 3 * kMs);
  ASSERT_EQ(outputs.size(), 1U);
  EXPECT_TRUE(outputs[0].complete);
  const auto& global = globalOf(outputs[0]);

  Cloud all = clouds[0];
  all.insert(all.end(), clouds[1].begin(), clouds[1].end());
  const MadcParams params;
  const Clustering central = euclideanClusters(all, params.clustering);
  ASSERT_EQ(central.cluster_count, 6) << "the scene: six blobs, two of them seen by both sensors";
  ASSERT_EQ(global.map.objects.size(), 6U);
  const auto summaries = summarizeClusters(all, central);
  for (std::size_t k = 0; k < summaries.size(); ++k) {
    ASSERT_EQ(global.map.objects[k].ellipsoids.size(), 1U);
    const EllipsoidId id{kRoot, 3, static_cast<std::uint32_t>(k)};
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

TEST(MergeAggregator, BaselineRootSkipsSensorsUnderDeadChildren) {
  std::mt19937_64 rng(22);
  const auto clouds = twoSensorScene(rng);
  AggregatorConfig config = starConfig({}, Mode::kBaseline);
  config.children = {{10, {1, 2}}, {3, {3}}};  // an intermediate over sensors 1 and 2, and edge 3
  auto aggregator = makeAggregator(config);
  ASSERT_TRUE(aggregator.childConnected(1).ok());  // the intermediate's stream, named by a relayed chunk
  for (auto& chunk : chunksOf(1, 2, clouds[0], 2)) acceptChunk(aggregator, chunk, kT0);
  EXPECT_TRUE(aggregator.poll(kT0 + 1 * kMs).empty()) << "sensor 2 is below a live child";
  for (auto& chunk : chunksOf(2, 2, clouds[1], 2)) acceptChunk(aggregator, chunk, kT0);
  const auto outputs = aggregator.poll(kT0 + 2 * kMs);
  ASSERT_EQ(outputs.size(), 1U) << "edge 3 never connected: not waited for";
  EXPECT_TRUE(outputs[0].complete);
  EXPECT_EQ(globalOf(outputs[0]).header.missing_nodes, (std::vector<std::uint32_t>{3}));
}

TEST(MergeAggregator, IntermediateRelaysPointChunksAtOnce) {
  std::mt19937_64 rng(23);
  const auto clouds = twoSensorScene(rng);
  auto aggregator = makeAggregator(starConfig({1, 2}, Mode::kBaseline, /*is_root=*/false));
  const auto chunk = chunksOf(1, 2, clouds[0], 2)[1];
  const auto arrival = aggregator.onPoints(chunk, kT0);
  ASSERT_TRUE(arrival.ok());
  EXPECT_EQ(arrival->arrival, Arrival::kRelay);
  ASSERT_TRUE(arrival->relay.has_value());
  // PointChunk's defaulted == is deleted (Point has none), so compare what a relay must keep.
  const PointChunk& relayed = *arrival->relay;
  EXPECT_EQ(relayed.header, chunk.header);
  EXPECT_EQ(relayed.chunk, chunk.chunk);
  EXPECT_EQ(relayed.first_point, chunk.first_point);
  ASSERT_EQ(relayed.points.size(), chunk.points.size());
  for (std::size_t i = 0; i < chunk.points.size(); ++i) EXPECT_EQ(relayed.points[i].xyz(), chunk.points[i].xyz());
  EXPECT_EQ(aggregator.pendingEpochs(), 0U);
  EXPECT_TRUE(aggregator.poll(kT0 + 1000 * kMs).empty());
}

TEST(MergeAggregator, ExtRootLabelsPointsWithTheirGlobalObjects) {
  std::mt19937_64 rng(24);
  const auto clouds = twoSensorScene(rng);
  const MadcParams params;
  const std::uint64_t epoch = 6;
  auto aggregator = makeAggregator(starConfig({1, 2}, Mode::kExt));
  connectAll(aggregator, {1, 2});
  std::vector<LocalMapResult> locals;
  std::vector<Map> maps;
  for (std::uint32_t s = 0; s < 2; ++s) {
    locals.push_back(genLocalMap(clouds[s], s + 1, epoch, params));
    maps.push_back(locals.back().map);
    accept(aggregator, mapMessage(s + 1, epoch, locals.back().map), kT0);
  }
  EXPECT_TRUE(aggregator.poll(kT0 + 1 * kMs).empty()) << "ext waits for the points too";
  for (std::uint32_t s = 0; s < 2; ++s) {
    for (auto& chunk : chunksOf(s + 1, epoch, clouds[s], 3, locals[s].clustering.labels)) acceptChunk(aggregator, chunk, kT0);
  }
  const auto outputs = aggregator.poll(kT0 + 2 * kMs);
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

Ellipsoid ball(std::uint32_t node, std::uint32_t index, const Eigen::Vector3d& centre) {
  Ellipsoid e;
  e.id = {node, 1, index};
  e.center = centre;
  e.shape = Eigen::Matrix3d::Identity() * 0.25;  // radius 0.5 m
  e.point_count = 10;
  return e;
}

TEST(MergeAggregator, GeofencesAreSetReplacedAndQueriedOnTheLatestGlobalMap) {
  auto aggregator = makeAggregator(starConfig({1}));
  connectAll(aggregator, {1});
  EXPECT_EQ(*aggregator.setGeofence(boxGeofence("zone", {-1, -1, -1}, {1, 1, 1})), 1U);
  const auto before = aggregator.queryGeofences("");
  ASSERT_TRUE(before.ok());
  EXPECT_EQ(before->epoch, 0U);
  EXPECT_TRUE(before->intrusions.empty()) << "no global map yet";

  accept(aggregator, mapMessage(1, 1, localMap({ball(1, 0, {0, 0, 0}), ball(1, 1, {10, 0, 0})})), kT0);
  ASSERT_EQ(aggregator.poll(kT0).size(), 1U);
  const auto inside = aggregator.queryGeofences("zone");
  ASSERT_TRUE(inside.ok());
  EXPECT_EQ(inside->epoch, 1U);
  ASSERT_EQ(inside->intrusions.size(), 1U);
  EXPECT_EQ(inside->intrusions[0].geofence, "zone");
  EXPECT_EQ(inside->intrusions[0].object_index, 0U);
  EXPECT_EQ(inside->intrusions[0].containment, Containment::kInside);
  EXPECT_EQ(inside->intrusions[0].ellipsoids, (std::vector<EllipsoidId>{{1, 1, 0}}));

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

}  // namespace
}  // namespace fogmap
