#include "common/geometry/map.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "tests/support/geometry_builders.hpp"

namespace fogmap {
namespace {

using test_support::randomShape;

// One local map per node: random ellipsoids over a square scene, ids (node, frame, index).
std::vector<Map> randomLocalMaps(std::mt19937_64& rng, int nodes, int per_node, double extent,
                                 std::uint64_t frame = 1) {
  std::uniform_real_distribution<double> pos(-extent, extent);
  std::vector<Map> maps;
  for (int node = 0; node < nodes; ++node) {
    std::vector<Ellipsoid> ellipsoids;
    for (int k = 0; k < per_node; ++k) {
      Ellipsoid e;
      e.id = {static_cast<std::uint32_t>(node + 1), frame, static_cast<std::uint32_t>(k)};
      e.center = {pos(rng), pos(rng), std::uniform_real_distribution<double>(0.0, 2.0)(rng)};
      e.shape = randomShape(rng, 0.2, 2.0);
      e.point_count = 10 + static_cast<std::uint64_t>(k);
      ellipsoids.push_back(e);
    }
    maps.push_back(localMap(std::move(ellipsoids)));
  }
  return maps;
}

std::vector<Ellipsoid> allEllipsoids(std::span<const Map> maps) {
  std::vector<Ellipsoid> all;
  for (const auto& m : maps) {
    for (const auto& o : m.objects) all.insert(all.end(), o.ellipsoids.begin(), o.ellipsoids.end());
  }
  return all;
}

TEST(DisjointSets, UnionFindBasics) {
  DisjointSets sets(6);
  EXPECT_TRUE(sets.unite(0, 1));
  EXPECT_TRUE(sets.unite(2, 3));
  EXPECT_FALSE(sets.unite(1, 0));
  EXPECT_TRUE(sets.unite(1, 3));
  EXPECT_EQ(sets.find(0), sets.find(2));
  EXPECT_NE(sets.find(0), sets.find(4));
  EXPECT_NE(sets.find(4), sets.find(5));
}

TEST(Merge, EqualsAllPairsSpecificationOnRandomCases) {
  std::mt19937_64 rng(1);
  for (int trial = 0; trial < 1000; ++trial) {
    const int nodes = 2 + trial % 6;
    const auto maps = randomLocalMaps(rng, nodes, 3 + trial % 12, 6.0 + trial % 10);
    const auto merged = mergeAll(maps);
    ASSERT_EQ(merged.map, mergeSpecification(allEllipsoids(maps))) << "trial " << trial;
  }
}

TEST(Merge, IsCommutative) {
  std::mt19937_64 rng(2);
  for (int trial = 0; trial < 1000; ++trial) {
    // Each side may itself be a merge of several nodes.
    const auto maps = randomLocalMaps(rng, 4, 2 + trial % 10, 5.0);
    const Map a = merge(maps[0], maps[1]).map;
    const Map b = merge(maps[2], maps[3]).map;
    ASSERT_EQ(merge(a, b).map, merge(b, a).map) << "trial " << trial;
  }
}

TEST(Merge, IsAssociative) {
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 1000; ++trial) {
    const auto maps = randomLocalMaps(rng, 3, 2 + trial % 10, 5.0);
    const Map left = merge(merge(maps[0], maps[1]).map, maps[2]).map;
    const Map right = merge(maps[0], merge(maps[1], maps[2]).map).map;
    ASSERT_EQ(left, right) << "trial " << trial;
  }
}

TEST(Merge, IsIdempotent) {
  std::mt19937_64 rng(4);
  for (int trial = 0; trial < 1000; ++trial) {
    const auto maps = randomLocalMaps(rng, 3, 2 + trial % 10, 5.0);
    const Map m = mergeAll(maps).map;
    ASSERT_EQ(merge(m, m).map, m) << "trial " << trial;
    // Re-delivering one child's map (a retransmission) changes nothing either.
    ASSERT_EQ(merge(m, maps[1]).map, m) << "trial " << trial;
    ASSERT_EQ(merge(maps[1], m).map, m) << "trial " << trial;
  }
}

TEST(Merge, OverlappingSubtreesGiveTheSpecification) {
  // Maps that share some ellipsoids (a node reported to two aggregators) still merge to the spec.
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 300; ++trial) {
    const auto maps = randomLocalMaps(rng, 4, 2 + trial % 8, 4.0);
    const Map left = merge(maps[0], maps[1]).map;
    const Map right = merge(maps[1], merge(maps[2], maps[3]).map).map;
    ASSERT_EQ(merge(left, right).map, mergeSpecification(allEllipsoids(maps))) << "trial " << trial;
  }
}

TEST(Merge, SameNodeEllipsoidsAreNeverJoinedDirectly) {
  Ellipsoid a;
  a.id = {1, 1, 0};
  a.center = {0, 0, 0};
  Ellipsoid b = a;
  b.id = {1, 1, 1};
  b.center = {0.5, 0, 0};  // overlaps a, but the same node separated them locally
  const Map m = merge(localMap({a}), localMap({b})).map;
  EXPECT_EQ(m.objects.size(), 2U);
  Ellipsoid c = a;
  c.id = {2, 1, 0};
  c.center = {0.25, 0, 0};  // another node's ellipsoid bridges them
  EXPECT_EQ(merge(m, localMap({c})).map.objects.size(), 1U);
}

// Fragments: a merged object is published when its ellipsoids hold min_points points together,
// whatever each holds alone; the filter commutes with the order of the merges.
TEST(Merge, FragmentsJoinedAcrossNodesArePublishedLoneOnesAreNot) {
  Ellipsoid a;
  a.id = {1, 1, 0};
  a.center = {0, 0, 0};
  a.point_count = 4;  // a fragment at node 1
  Ellipsoid b = a;
  b.id = {2, 1, 0};
  b.center = {0.5, 0, 0};  // overlaps a: 4 + 6 = 10 points together
  b.point_count = 6;
  Ellipsoid lone = a;
  lone.id = {3, 1, 0};
  lone.center = {10, 0, 0};
  lone.point_count = 9;
  Ellipsoid whole = a;
  whole.id = {3, 1, 1};
  whole.center = {-10, 0, 0};
  whole.point_count = 10;
  const Map merged = mergeAll(std::vector<Map>{localMap({a}), localMap({b}), localMap({lone, whole})}).map;
  ASSERT_EQ(merged.objects.size(), 3U);
  const Map published = withoutFragments(merged, 10);
  ASSERT_EQ(published.objects.size(), 2U);
  EXPECT_EQ(published.objects[0].pointCount(), 10U);
  EXPECT_EQ(published.objects[0].ellipsoids.size(), 2U);
  EXPECT_EQ(published.objects[1].ellipsoids[0].id, whole.id);
  EXPECT_EQ(published, mergeSpecification(std::vector<Ellipsoid>{lone, b, whole, a}, 10));
  EXPECT_EQ(withoutFragments(merged, 1), merged);
}

// On random scenes whose ellipsoids carry 1 to 15 points, filtering any merge order's result
// equals the all-pairs specification with min_points.
TEST(Merge, WithoutFragmentsOfAnyMergeOrderEqualsTheSpecification) {
  std::mt19937_64 rng(8080);
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<Map> maps = randomLocalMaps(rng, 5, 12, 12.0);
    std::uniform_int_distribution<std::uint64_t> points(1, 15);
    for (Map& m : maps) {
      for (auto& o : m.objects) o.ellipsoids[0].point_count = points(rng);
    }
    const Map spec = mergeSpecification(allEllipsoids(maps), 10);
    std::shuffle(maps.begin(), maps.end(), rng);
    Map folded = maps[0];
    for (std::size_t i = 1; i < maps.size(); ++i) folded = merge(folded, maps[i]).map;
    EXPECT_EQ(withoutFragments(folded, 10), spec) << "trial " << trial;
    EXPECT_EQ(withoutFragments(mergeAll(maps).map, 10), spec) << "trial " << trial;
  }
}

Ellipsoid sphere(std::uint32_t node, const Eigen::Vector3d& center, double radius) {
  Ellipsoid e;
  e.id = {node, 1, 0};
  e.center = center;
  e.shape = radius * radius * Eigen::Matrix3d::Identity();
  return e;
}

// Spheres of radius 1 whose centres are 2 (1 + gap) apart: their boxes are `gap` times 2 apart,
// while the exact test counts a gap within its tolerance (1e-9 relative) as touching.
TEST(Merge, TouchingEllipsoidsMergeAsSpecified) {
  for (const double gap : {0.0, 1e-13, 1e-12, 1e-11, 1e-6}) {
    const Ellipsoid a = sphere(1, {0.1, -3.0, 7.0}, 1.0);
    const Ellipsoid b = sphere(2, a.center + Eigen::Vector3d(2.0 * (1.0 + gap), 0.0, 0.0), 1.0);
    const Map spec = mergeSpecification(std::vector<Ellipsoid>{a, b});
    EXPECT_EQ(spec.objects.size(), gap < 1e-9 ? 1U : 2U) << "gap " << gap;
    EXPECT_EQ(merge(localMap({a}), localMap({b})).map, spec) << "gap " << gap;
    EXPECT_EQ(merge(localMap({b}), localMap({a})).map, spec) << "gap " << gap;
  }
}

// Chains of random ellipsoids from alternating nodes, each placed against the previous one
// (touching at a point with normal n) and then moved along n by a relative gap around the exact
// test's tolerance. Normals along an axis make the boxes touch too, the case where box pruning
// without the tolerance drops pairs the exact test accepts.
TEST(Merge, NearContactEqualsAllPairsSpecification) {
  std::mt19937_64 rng(12);
  const std::vector<double> gaps{-1e-6, -1e-12, 0.0, 1e-13, 1e-12, 1e-11, 1e-10, 3e-10, 1e-9, 1e-8, 1e-6};
  std::uniform_int_distribution<std::size_t> pick_gap(0, gaps.size() - 1);
  std::uniform_int_distribution<int> pick_axis(0, 5);
  std::uniform_real_distribution<double> pos(-50.0, 50.0);
  for (int trial = 0; trial < 500; ++trial) {
    const int nodes = 2 + trial % 3;
    std::vector<std::vector<Ellipsoid>> per_node(static_cast<std::size_t>(nodes));
    Ellipsoid prev;
    for (int k = 0; k < 6; ++k) {
      Ellipsoid e;
      e.id = {static_cast<std::uint32_t>(k % nodes + 1), 1, static_cast<std::uint32_t>(k)};
      e.shape = randomShape(rng, 0.2, 2.0);
      e.center = {pos(rng), pos(rng), pos(rng)};
      if (k > 0) {
        Eigen::Vector3d n = Eigen::Vector3d::Zero();
        if (trial % 4 == 3) {
          n = test_support::randomUnitVector(rng);
        } else {
          const int axis = pick_axis(rng);
          n[axis % 3] = axis < 3 ? 1.0 : -1.0;
        }
        // The boundary point of M with outward normal n is c + M n / sqrt(n^T M n).
        const double reach_prev = std::sqrt(n.dot(prev.shape * n));
        const double reach = std::sqrt(n.dot(e.shape * n));
        const Eigen::Vector3d contact = prev.center + prev.shape * n / reach_prev;
        e.center = contact + e.shape * n / reach + gaps[pick_gap(rng)] * (reach_prev + reach) * n;
      }
      per_node[static_cast<std::size_t>(k % nodes)].push_back(e);
      prev = e;
    }
    std::vector<Map> maps;
    for (auto& es : per_node) maps.push_back(localMap(std::move(es)));
    ASSERT_EQ(mergeAll(maps).map, mergeSpecification(allEllipsoids(maps))) << "trial " << trial;
    ASSERT_EQ(merge(maps[0], maps[1]).map, mergeSpecification(allEllipsoids(std::span(maps).first(2))))
        << "trial " << trial;
  }
}

TEST(Merge, BoxPruningTestsTenTimesFewerPairsOnSevenMapsOfOneHundred) {
  std::mt19937_64 rng(6);
  const auto maps = randomLocalMaps(rng, 7, 100, 25.0);  // 50 x 50 m scene, as in the paper
  const auto merged = mergeAll(maps);
  EXPECT_EQ(merged.map, mergeSpecification(allEllipsoids(maps)));
  EXPECT_EQ(merged.stats.pairs_all, 7U * 6U / 2U * 100U * 100U);
  EXPECT_EQ(merged.stats.pairs_pruned + merged.stats.pairs_tested, merged.stats.pairs_all);
  EXPECT_GE(merged.stats.pairs_all, 10 * merged.stats.pairs_tested)
      << "tested " << merged.stats.pairs_tested << " of " << merged.stats.pairs_all;
}

TEST(Map, CanonicalFormSortsObjectsAndEllipsoidsById) {
  std::mt19937_64 rng(8);
  auto maps = randomLocalMaps(rng, 1, 5, 100.0);
  std::vector<Ellipsoid> es = allEllipsoids(maps);
  std::reverse(es.begin(), es.end());
  const std::vector<std::size_t> groups{0, 1, 0, 1, 2};
  const Map m = mapFromGroups(es, groups);
  ASSERT_EQ(m.objects.size(), 3U);
  for (std::size_t k = 1; k < m.objects.size(); ++k) {
    EXPECT_LT(m.objects[k - 1].ellipsoids.front().id, m.objects[k].ellipsoids.front().id);
  }
  for (const auto& o : m.objects) {
    EXPECT_TRUE(std::is_sorted(o.ellipsoids.begin(), o.ellipsoids.end(),
                               [](const Ellipsoid& a, const Ellipsoid& b) { return a.id < b.id; }));
    Box box;
    for (const auto& e : o.ellipsoids) box.extend(delimitingBox(e));
    EXPECT_EQ(o.box, box);
  }
}

}  // namespace
}  // namespace fogmap
