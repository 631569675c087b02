// Object-level agreement against hand-made partitions whose answer is known, and per object
// against the definitions counted out by brute force on random labelings.
#include "common/scoring/object_match.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>
#include <vector>

namespace fogmap {
namespace {

constexpr std::int64_t kAnyCluster = -1000000;  // bruteForceOutcome: a point of the object in any cluster

// `n` points of true object `object` put in cluster `cluster`.
void add(std::vector<std::int64_t>& truth, std::vector<std::int64_t>& clusters, std::int64_t object,
         std::int64_t cluster, int n) {
  truth.insert(truth.end(), n, object);
  clusters.insert(clusters.end(), n, cluster);
}

TEST(ObjectMatch, CountsWholeSplitMergedAndMissedObjects) {
  std::vector<std::int64_t> truth, clusters;
  add(truth, clusters, 1, 10, 100);  // whole
  add(truth, clusters, 2, 20, 60);   // split: 60 % and 40 % in two clusters (found: 60 %)
  add(truth, clusters, 2, 21, 40);
  add(truth, clusters, 3, 30, 50);   // merged with 4 in cluster 30
  add(truth, clusters, 4, 30, 50);
  add(truth, clusters, 5, -1, 80);   // missed: noise ...
  add(truth, clusters, 5, 50, 20);   // ... but for 20 % in one cluster
  add(truth, clusters, 6, 60, 5);    // too small to count
  add(truth, clusters, -1, 10, 500);  // ground points in cluster 10 do not make object 1 merged
  const auto m = matchObjects(truth, clusters);
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->objects_true, 5U);
  EXPECT_EQ(m->found_whole, 1U);
  EXPECT_EQ(m->split, 1U);
  EXPECT_EQ(m->merged, 2U);  // objects 3 and 4, each found in the shared cluster
  EXPECT_EQ(m->missed, 1U);
}

TEST(ObjectMatch, IdenticalPartitionsFindEveryObjectWholeAndLengthsMustAgree) {
  std::vector<std::int64_t> truth, clusters;
  for (int o = 0; o < 20; ++o) add(truth, clusters, o, 100 + o, 15 + o);
  const auto m = matchObjects(truth, clusters);
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->objects_true, 20U);
  EXPECT_EQ(m->found_whole, 20U);
  EXPECT_EQ(m->split + m->merged + m->missed, 0U);
  clusters.pop_back();
  EXPECT_FALSE(matchObjects(truth, clusters).ok());
}

const ObjectOutcome* outcomeOf(const std::vector<ObjectOutcome>& outcomes, std::int64_t object) {
  for (const auto& o : outcomes) {
    if (o.true_object == object) return &o;
  }
  return nullptr;
}

TEST(ObjectMatch, EachObjectGetsTheOutcomeItWasCountedUnder) {
  std::vector<std::int64_t> truth, clusters;
  add(truth, clusters, 1, 10, 100);  // whole
  add(truth, clusters, 2, 20, 60);   // split
  add(truth, clusters, 2, 21, 40);
  add(truth, clusters, 3, 30, 50);   // merged with 4
  add(truth, clusters, 4, 30, 50);
  add(truth, clusters, 5, -1, 80);   // missed
  add(truth, clusters, 5, 50, 20);
  add(truth, clusters, 6, 60, 5);    // too small: no outcome
  add(truth, clusters, -1, 10, 500);
  const auto each = matchEachObject(truth, clusters);
  ASSERT_TRUE(each.ok());
  ASSERT_EQ(each->size(), 5U);
  for (std::size_t i = 0; i < each->size(); ++i) EXPECT_EQ((*each)[i].true_object, static_cast<std::int64_t>(i + 1));
  const auto expect = [&](std::int64_t object, std::size_t points, bool whole, bool split, bool merged, bool missed) {
    const ObjectOutcome* o = outcomeOf(*each, object);
    ASSERT_NE(o, nullptr) << "object " << object;
    EXPECT_EQ(o->points, points) << "object " << object;
    EXPECT_EQ(o->found_whole, whole) << "object " << object;
    EXPECT_EQ(o->split, split) << "object " << object;
    EXPECT_EQ(o->merged, merged) << "object " << object;
    EXPECT_EQ(o->missed, missed) << "object " << object;
  };
  expect(1, 100, true, false, false, false);
  expect(2, 100, false, true, false, false);
  expect(3, 50, false, false, true, false);
  expect(4, 50, false, false, true, false);
  expect(5, 100, false, false, false, true);
  EXPECT_EQ(outcomeOf(*each, 6), nullptr);
}

TEST(ObjectMatch, AnObjectCanBeSplitAndMergedOrSplitAndMissed) {
  std::vector<std::int64_t> truth, clusters;
  add(truth, clusters, 1, 10, 45);  // 45 % and 45 % in two clusters: no cluster has half of it
  add(truth, clusters, 1, 11, 45);
  add(truth, clusters, 1, -1, 10);
  add(truth, clusters, 2, 20, 60);  // found in 20, 40 % in 21 beside all of object 3
  add(truth, clusters, 2, 21, 40);
  add(truth, clusters, 3, 21, 50);
  add(truth, clusters, 4, 40, 70);  // found in 40 with all of object 5, 30 % in 41
  add(truth, clusters, 4, 41, 30);
  add(truth, clusters, 5, 40, 100);
  const auto each = matchEachObject(truth, clusters);
  ASSERT_TRUE(each.ok());
  ASSERT_EQ(each->size(), 5U);
  const auto flags = [&](std::int64_t object) {
    const ObjectOutcome* o = outcomeOf(*each, object);
    return o == nullptr ? std::vector<bool>{} : std::vector<bool>{o->found_whole, o->split, o->merged, o->missed};
  };
  // found whole, split, merged, missed
  EXPECT_EQ(flags(1), (std::vector<bool>{false, true, false, true}));
  EXPECT_EQ(flags(2), (std::vector<bool>{false, true, false, false}));  // its best cluster holds only it
  EXPECT_EQ(flags(3), (std::vector<bool>{false, false, true, false}));
  EXPECT_EQ(flags(4), (std::vector<bool>{false, true, true, false}));
  EXPECT_EQ(flags(5), (std::vector<bool>{false, false, true, false}));
  const auto m = matchObjects(truth, clusters);
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->objects_true, 5U);
  EXPECT_EQ(m->found_whole, 0U);
  EXPECT_EQ(m->split, 3U);
  EXPECT_EQ(m->merged, 3U);
  EXPECT_EQ(m->missed, 1U);
}

TEST(ObjectMatch, EachObjectNeedsLabelsOfTheSameLength) {
  const std::vector<std::int64_t> truth = {1, 1, 1};
  const std::vector<std::int64_t> clusters = {0, 0};
  EXPECT_FALSE(matchEachObject(truth, clusters).ok());
}

// ObjectMatchParams' definitions for one true object, counted out over every point: the clusters
// that hold it, its best cluster (most of its points; the lowest cluster id among equals) and the
// counted true objects that cluster holds.
ObjectOutcome bruteForceOutcome(const std::vector<std::int64_t>& truth, const std::vector<std::int64_t>& clusters,
                                std::int64_t object, const ObjectMatchParams& params) {
  const auto pointsOf = [&](std::int64_t t, std::int64_t c) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < truth.size(); ++i) n += truth[i] == t && (c == kAnyCluster || clusters[i] == c) ? 1 : 0;
    return n;
  };
  std::set<std::int64_t> cluster_ids(clusters.begin(), clusters.end());
  std::set<std::int64_t> objects(truth.begin(), truth.end());
  const auto holds = [&](std::int64_t c, std::int64_t t) {
    const double size = static_cast<double>(pointsOf(t, kAnyCluster));
    return t >= 0 && size >= static_cast<double>(params.min_points) && pointsOf(t, c) > 0 &&
           static_cast<double>(pointsOf(t, c)) >= params.share * size;
  };
  ObjectOutcome out;
  out.true_object = object;
  out.points = pointsOf(object, kAnyCluster);
  std::size_t holding = 0;
  std::int64_t best = -1;
  std::size_t best_points = 0;
  for (const auto c : cluster_ids) {
    if (c < 0) continue;
    if (holds(c, object)) ++holding;
    if (pointsOf(object, c) > best_points) {
      best_points = pointsOf(object, c);
      best = c;
    }
  }
  const bool found = best >= 0 && static_cast<double>(best_points) >= params.found * static_cast<double>(out.points);
  std::size_t held_by_best = 0;
  for (const auto t : objects) held_by_best += found && holds(best, t) ? 1 : 0;
  out.split = holding >= 2;
  out.merged = found && held_by_best >= 2;
  out.missed = !found;
  out.found_whole = found && !out.split && !out.merged;
  return out;
}

TEST(ObjectMatch, OutcomesFollowTheDefinitionsAndSumToMatchObjectsOnRandomLabelings) {
  const ObjectMatchParams params;
  for (std::uint64_t seed = 1; seed <= 40; ++seed) {
    std::mt19937_64 rng(seed);
    std::uniform_int_distribution<int> objects_of(3, 12);
    const int objects = objects_of(rng);
    // Every object mostly in a home cluster of its own or of a neighbour, the rest strayed or noise.
    std::vector<std::int64_t> truth, clusters;
    std::uniform_int_distribution<int> size_of(2, 60);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::uniform_int_distribution<std::int64_t> any_cluster(0, objects);
    for (int o = -1; o < objects; ++o) {
      const std::int64_t home = u(rng) < 0.3 ? any_cluster(rng) : o + 1;
      const double stray = u(rng) * 0.6;
      for (int i = size_of(rng); i > 0; --i) {
        truth.push_back(o);
        const double r = u(rng);
        clusters.push_back(r < stray / 2 ? -1 : r < stray ? any_cluster(rng) : home);
      }
    }
    std::vector<std::size_t> order(truth.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::shuffle(order.begin(), order.end(), rng);
    std::vector<std::int64_t> t(truth.size()), c(truth.size());
    for (std::size_t i = 0; i < order.size(); ++i) {
      t[i] = truth[order[i]];
      c[i] = clusters[order[i]];
    }
    const auto each = matchEachObject(t, c, params);
    const auto m = matchObjects(t, c, params);
    ASSERT_TRUE(each.ok());
    ASSERT_TRUE(m.ok());
    ObjectMatch sum;
    std::int64_t previous = -1;
    for (const auto& o : *each) {
      EXPECT_GT(o.true_object, previous) << "seed " << seed << ": outcomes in increasing object order";
      previous = o.true_object;
      const ObjectOutcome want = bruteForceOutcome(t, c, o.true_object, params);
      EXPECT_EQ(o.points, want.points) << "seed " << seed << ", object " << o.true_object;
      EXPECT_EQ(o.found_whole, want.found_whole) << "seed " << seed << ", object " << o.true_object;
      EXPECT_EQ(o.split, want.split) << "seed " << seed << ", object " << o.true_object;
      EXPECT_EQ(o.merged, want.merged) << "seed " << seed << ", object " << o.true_object;
      EXPECT_EQ(o.missed, want.missed) << "seed " << seed << ", object " << o.true_object;
      ++sum.objects_true;
      sum.found_whole += o.found_whole ? 1 : 0;
      sum.split += o.split ? 1 : 0;
      sum.merged += o.merged ? 1 : 0;
      sum.missed += o.missed ? 1 : 0;
    }
    // Every true object with enough points has its outcome, and no other.
    std::map<std::int64_t, std::size_t> sizes;
    for (const auto l : t) {
      if (l >= 0) ++sizes[l];
    }
    std::size_t counted = 0;
    for (const auto& [object, size] : sizes) counted += size >= params.min_points ? 1 : 0;
    EXPECT_EQ(each->size(), counted) << "seed " << seed;
    EXPECT_EQ(m->objects_true, sum.objects_true) << "seed " << seed;
    EXPECT_EQ(m->found_whole, sum.found_whole) << "seed " << seed;
    EXPECT_EQ(m->split, sum.split) << "seed " << seed;
    EXPECT_EQ(m->merged, sum.merged) << "seed " << seed;
    EXPECT_EQ(m->missed, sum.missed) << "seed " << seed;
    const ObjectMatch counted_out = countOutcomes(*each);
    EXPECT_EQ(counted_out.objects_true, sum.objects_true);
    EXPECT_EQ(counted_out.missed, sum.missed);
  }
}

}  // namespace
}  // namespace fogmap
