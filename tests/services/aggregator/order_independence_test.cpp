// Order independence of collect-merge-emit: over a star and trees of 2, 4 and 8 leaf aggregators,
// 1,000 seeded delivery schedules each (a random order, 10 % of uploads delivered twice, 10 %
// held back and delivered last) give the same global map, byte for byte on the wire, and it is
// the specification's (all-pairs connected components without the objects below min_points), not
// whatever MERGE happens to compute. The edges' maps hold fragments (clusters below min_points):
// some join others into objects, some stay alone and are not published.
#include <gtest/gtest.h>

#include <algorithm>
#include <deque>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "common/geometry/map.hpp"
#include "services/common/proto_convert.hpp"
#include "services/merge_aggregator/aggregator_core.hpp"
#include "tests/support/epoch_times.hpp"
#include "tests/support/topology_builders.hpp"

namespace fogmap {
namespace {

using test_support::kE0;
using test_support::kMs;
using test_support::kRoot;
using test_support::startOf;

constexpr std::int64_t kNow = startOf(kE0) + 5 * kMs;  // before any deadline
constexpr std::uint32_t kEdges = 8;
constexpr int kSchedules = 1000;

// Eight edges' local maps over one 12 m square: dense enough that objects span nodes.
std::vector<Map> scene(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> pos(-6.0, 6.0);
  std::uniform_real_distribution<double> axis(0.2, 1.2);
  std::uniform_int_distribution<std::uint64_t> points(1, 16);  // below 10: a fragment
  std::vector<Map> maps;
  for (std::uint32_t node = 1; node <= kEdges; ++node) {
    std::vector<Ellipsoid> ellipsoids;
    for (std::uint32_t k = 0; k < 6; ++k) {
      Ellipsoid e;
      e.id = {node, kE0, k};
      e.center = {pos(rng), pos(rng), 1.0};
      e.shape = Eigen::Vector3d(axis(rng), axis(rng), axis(rng)).cwiseAbs2().asDiagonal();
      e.point_count = points(rng);
      ellipsoids.push_back(e);
    }
    maps.push_back(localMap(std::move(ellipsoids)));
  }
  return maps;
}

// The aggregators of one shape: the root and `leaves` aggregators below it (0: a star).
struct Cluster {
  std::map<std::uint32_t, MergeAggregator> aggregators;  // by node id
  std::map<std::uint32_t, std::uint32_t> parent;         // node -> its parent aggregator
};

Cluster makeCluster(std::uint32_t leaves) {
  Cluster cluster;
  AggregatorConfig root;
  root.node = kRoot;
  root.is_root = true;
  root.levels = leaves == 0 ? 1 : 2;
  if (leaves == 0) {
    for (std::uint32_t edge = 1; edge <= kEdges; ++edge) {
      root.children.push_back({edge, {edge}, {}});
      cluster.parent[edge] = kRoot;
    }
  } else {
    const std::uint32_t per_leaf = kEdges / leaves;
    for (std::uint32_t leaf = 0; leaf < leaves; ++leaf) {
      AggregatorConfig config;
      config.node = kRoot + 1 + leaf;
      std::vector<std::uint32_t> sensors;
      for (std::uint32_t edge = 1 + leaf * per_leaf; edge <= (leaf + 1) * per_leaf; ++edge) {
        config.children.push_back({edge, {edge}, {}});
        cluster.parent[edge] = config.node;
        sensors.push_back(edge);
      }
      root.children.push_back({config.node, sensors, {}});
      cluster.parent[config.node] = kRoot;
      cluster.aggregators.emplace(config.node, std::move(MergeAggregator::create(config)).value());
    }
  }
  cluster.aggregators.emplace(kRoot, std::move(MergeAggregator::create(root)).value());
  for (auto& [id, aggregator] : cluster.aggregators) {
    for (const auto& child : aggregator.config().children) EXPECT_TRUE(aggregator.childConnected(child.id).ok());
  }
  return cluster;
}

struct Delivery {
  std::uint32_t from = 0;
  UploadKey key;
  MapMessage message;
  bool held = false;  // already lost once
};

// Runs one schedule; returns the root's first global map of the epoch (its wire bytes).
std::string runSchedule(std::uint32_t leaves, const std::vector<Map>& maps, std::uint64_t seed, Map& published) {
  std::mt19937_64 rng(seed);
  Cluster cluster = makeCluster(leaves);
  std::deque<Delivery> pending;
  std::map<std::uint32_t, std::uint64_t> sequences;
  const auto upload = [&](std::uint32_t from, MapMessage message) {
    const std::uint64_t sequence = ++sequences[from];
    pending.push_back({from, {sequence, sequence * 31 + from}, std::move(message), false});
  };
  for (std::uint32_t node = 1; node <= kEdges; ++node) {
    MapMessage message;
    message.header.node = node;
    message.header.epoch = kE0;
    message.header.sensor_time_ns = kNow;
    message.header.contributing_nodes = {node};
    message.map = maps[node - 1];
    upload(node, std::move(message));
  }
  std::uniform_real_distribution<double> chance(0.0, 1.0);
  std::vector<GlobalMapMessage> globals;
  std::deque<Delivery> later;  // lost on the way, re-delivered after everything else
  for (int step = 0; step < 10'000 && !(pending.empty() && later.empty()); ++step) {
    if (pending.empty()) std::swap(pending, later);
    const std::size_t pick = std::uniform_int_distribution<std::size_t>(0, pending.size() - 1)(rng);
    Delivery delivery = pending[pick];
    pending.erase(pending.begin() + static_cast<std::ptrdiff_t>(pick));
    const double roll = chance(rng);
    if (roll < 0.1 && !delivery.held) {
      delivery.held = true;
      later.push_back(std::move(delivery));
      continue;
    }
    if (roll < 0.2) pending.push_back(delivery);  // delivered twice
    MergeAggregator& to = cluster.aggregators.at(cluster.parent.at(delivery.from));
    const Outcome outcome = to.onMap(delivery.from, delivery.key, delivery.message, 1000, kNow);
    EXPECT_TRUE(outcome.ok()) << outcome.refused->message;
    for (auto& output : to.poll(kNow)) {
      if (auto* up = std::get_if<MapMessage>(&output.message)) {
        upload(to.config().node, std::move(*up));
      } else {
        globals.push_back(std::get<GlobalMapMessage>(output.message));
      }
    }
  }
  EXPECT_TRUE(pending.empty() && later.empty());
  // The root publishes in order: over a tree (deadline 2 x 80 ms) the epoch before, which it
  // opened at its first poll and nobody reports, is published at its deadline (60 ms after the
  // epoch began), and the complete epoch right after it, before its own deadline.
  MergeAggregator& root = cluster.aggregators.at(kRoot);
  const std::int64_t previous_due = startOf(kE0 - 1) + root.config().levels * 80 * kMs;
  for (auto& output : root.poll(std::max(kNow, previous_due))) {
    EXPECT_TRUE(output.complete || output.epoch < kE0);
    globals.push_back(std::get<GlobalMapMessage>(output.message));
  }
  std::erase_if(globals, [](const GlobalMapMessage& g) { return g.header.epoch != kE0; });
  EXPECT_EQ(globals.size(), 1U) << "one emission, no revision: duplicates change nothing";
  if (globals.empty()) return {};
  EXPECT_TRUE(globals[0].header.missing_nodes.empty());
  published = globals[0].map;
  MapMessage canonical{globals[0].header, globals[0].map};
  return toProto(canonical).SerializeAsString();
}

TEST(OrderIndependence, EveryScheduleOverStarAndTreesGivesTheSpecificationsMap) {
  for (std::uint64_t scene_seed = 1; scene_seed <= 4; ++scene_seed) {
    const std::vector<Map> maps = scene(scene_seed);
    std::vector<Ellipsoid> all;
    for (const Map& map : maps) {
      for (const auto& object : map.objects) all.insert(all.end(), object.ellipsoids.begin(), object.ellipsoids.end());
    }
    const Map merged = mergeSpecification(all);
    ASSERT_LT(merged.objects.size(), all.size()) << "the scene must join objects across nodes";
    const std::uint64_t min_points = MadcParams{}.clustering.min_points;  // the root's
    const Map specification = mergeSpecification(all, min_points);
    ASSERT_LT(specification.objects.size(), merged.objects.size()) << "some fragments must stay alone";
    const auto joined_fragment = [&](const MapObject& o) {
      return o.ellipsoids.size() > 1 &&
             std::any_of(o.ellipsoids.begin(), o.ellipsoids.end(), [&](const Ellipsoid& e) { return e.point_count < min_points; });
    };
    ASSERT_TRUE(std::any_of(specification.objects.begin(), specification.objects.end(), joined_fragment))
        << "some fragments must be published as parts of objects";
    std::string reference;
    for (const std::uint32_t leaves : {0U, 2U, 4U, 8U}) {
      for (int s = 0; s < kSchedules / 4; ++s) {
        Map published;
        const std::string bytes = runSchedule(leaves, maps, scene_seed * 1'000'003 + leaves * 7919 + static_cast<std::uint64_t>(s), published);
        ASSERT_EQ(published, specification) << "scene " << scene_seed << ", " << leaves << " leaves, schedule " << s;
        if (reference.empty()) reference = bytes;
        ASSERT_EQ(bytes, reference) << "scene " << scene_seed << ", " << leaves << " leaves, schedule " << s;
      }
    }
  }
}

}  // namespace
}  // namespace fogmap
