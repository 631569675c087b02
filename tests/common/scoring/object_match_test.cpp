// Object-level agreement against hand-made partitions whose answer is known.
#include "common/scoring/object_match.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace fogmap {
namespace {

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

}  // namespace
}  // namespace fogmap
