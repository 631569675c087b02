#include "common/scoring/rand_index.hpp"

#include <cstdint>
#include <map>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

namespace fogmap {
namespace {

using Labels = std::vector<std::int64_t>;

RandScores scoresOf(const Labels& a, const Labels& b) {
  const Expected<RandScores> scores = randScores(a, b);
  EXPECT_TRUE(scores.ok()) << scores.error().message;
  return scores.ok() ? scores.value() : RandScores{-1.0, -1.0};
}

// Pair counts by looking at every pair: together in a, together in b. Noise (negative) is never
// together with anything.
struct PairCounts {
  double both = 0;     // together in a and in b
  double only_a = 0;   // together in a, apart in b
  double only_b = 0;   // apart in a, together in b
  double neither = 0;  // apart in both
};

PairCounts countPairs(const Labels& a, const Labels& b) {
  PairCounts c;
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (std::size_t j = i + 1; j < a.size(); ++j) {
      const bool same_a = a[i] >= 0 && a[i] == a[j];
      const bool same_b = b[i] >= 0 && b[i] == b[j];
      if (same_a && same_b) c.both += 1;
      else if (same_a) c.only_a += 1;
      else if (same_b) c.only_b += 1;
      else c.neither += 1;
    }
  }
  return c;
}

double bruteForceRandIndex(const Labels& a, const Labels& b) {
  const PairCounts c = countPairs(a, b);
  return (c.both + c.neither) / (c.both + c.only_a + c.only_b + c.neither);
}

// ARI from the pair counts (the 2x2 pair-confusion form), independent of the contingency table.
double pairCountAdjustedRandIndex(const Labels& a, const Labels& b) {
  const PairCounts c = countPairs(a, b);
  const double num = 2.0 * (c.both * c.neither - c.only_a * c.only_b);
  const double den = (c.both + c.only_a) * (c.only_a + c.neither) +
                     (c.both + c.only_b) * (c.only_b + c.neither);
  return num / den;
}

// ARI straight from Hubert and Arabie's contingency-table formula, noise relabelled to fresh
// singleton labels first.
double directAdjustedRandIndex(Labels a, Labels b) {
  std::int64_t fresh = 1'000'000;
  for (auto& l : a) if (l < 0) l = fresh++;
  for (auto& l : b) if (l < 0) l = fresh++;
  std::map<std::pair<std::int64_t, std::int64_t>, double> table;
  std::map<std::int64_t, double> rows;
  std::map<std::int64_t, double> cols;
  for (std::size_t i = 0; i < a.size(); ++i) {
    table[{a[i], b[i]}] += 1;
    rows[a[i]] += 1;
    cols[b[i]] += 1;
  }
  auto choose2 = [](double n) { return n * (n - 1) / 2; };
  double index = 0;
  for (const auto& [key, n] : table) index += choose2(n);
  double sum_rows = 0;
  for (const auto& [key, n] : rows) sum_rows += choose2(n);
  double sum_cols = 0;
  for (const auto& [key, n] : cols) sum_cols += choose2(n);
  const double expected = sum_rows * sum_cols / choose2(static_cast<double>(a.size()));
  const double max_index = (sum_rows + sum_cols) / 2;
  return (index - expected) / (max_index - expected);
}

Labels randomLabels(std::mt19937_64& rng, std::size_t n, int clusters, double noise_fraction) {
  std::uniform_int_distribution<int> label(0, clusters - 1);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::uniform_int_distribution<int> noise_label(-3, -1);  // any negative value means noise
  Labels labels(n);
  for (auto& l : labels) l = unit(rng) < noise_fraction ? noise_label(rng) : label(rng);
  return labels;
}

// ---------------------------------------------------------------------------------------------

TEST(RandIndex, HandComputedSmallExample) {
  // Pairs: 6. Together in a: {01, 23}; together in b: {01}. Disagreement: only 23.
  // RI = 5/6. ARI: expected = 2 * 1 / 6 = 1/3, max = 3/2, so (1 - 1/3) / (3/2 - 1/3) = 4/7.
  const RandScores s = scoresOf({0, 0, 1, 1}, {0, 0, 1, 2});
  EXPECT_NEAR(s.rand_index, 5.0 / 6.0, 1e-15);
  EXPECT_NEAR(s.adjusted_rand_index, 4.0 / 7.0, 1e-15);
  EXPECT_NEAR(s.adjusted_rand_index, 0.5714285714285714, 1e-15);
}

TEST(RandIndex, HandComputedSixElementExample) {
  // Together in a: 3 + 3 = 6 pairs; in b: 1 + 1 + 1 = 3; in both: {01, 45} = 2. Of 15 pairs,
  // 4 + 1 disagree: RI = 10/15. ARI = (2 - 6*3/15) / ((6+3)/2 - 6*3/15) = 0.8 / 3.3 = 8/33.
  const RandScores s = scoresOf({0, 0, 0, 1, 1, 1}, {0, 0, 1, 1, 2, 2});
  EXPECT_NEAR(s.rand_index, 2.0 / 3.0, 1e-15);
  EXPECT_NEAR(s.adjusted_rand_index, 8.0 / 33.0, 1e-15);
}

TEST(RandIndex, IdenticalPartitionsUnderRelabellingScoreOne) {
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 50; ++trial) {
    const Labels a = randomLabels(rng, 300, 1 + trial % 12, trial % 3 == 0 ? 0.2 : 0.0);
    Labels b = a;
    for (auto& l : b) if (l >= 0) l = 7'000'000'000LL - 13 * l;  // bijective relabelling
    const RandScores s = scoresOf(a, b);
    EXPECT_EQ(s.rand_index, 1.0) << trial;
    EXPECT_EQ(s.adjusted_rand_index, 1.0) << trial;
  }
}

TEST(RandIndex, FewerThanTwoElementsScoreOne) {
  const RandScores empty = scoresOf({}, {});
  EXPECT_EQ(empty.rand_index, 1.0);
  EXPECT_EQ(empty.adjusted_rand_index, 1.0);
  const RandScores one = scoresOf({4}, {-1});
  EXPECT_EQ(one.rand_index, 1.0);
  EXPECT_EQ(one.adjusted_rand_index, 1.0);
}

TEST(RandIndex, LengthMismatchIsAnError) {
  const Labels a = {0, 1, 2};
  const Labels b = {0, 1};
  const Expected<RandScores> s = randScores(a, b);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kInvalidArgument);
  EXPECT_FALSE(randScores(b, a).ok());
}

TEST(RandIndex, NoiseElementsAreSingletons) {
  // Two noise points with the same negative label are NOT a cluster: a = {7, 8, 0, 0} in effect.
  const RandScores s = scoresOf({-1, -1, 0, 0}, {5, 5, 0, 0});
  EXPECT_NEAR(s.rand_index, 5.0 / 6.0, 1e-15);
  EXPECT_NEAR(s.adjusted_rand_index, 4.0 / 7.0, 1e-15);
  // The same noise in both partitions is agreement.
  const RandScores same = scoresOf({-1, -1, 0, 0, -2}, {-1, -5, 3, 3, -1});
  EXPECT_EQ(same.rand_index, 1.0);
  EXPECT_EQ(same.adjusted_rand_index, 1.0);
}

TEST(RandIndex, NoiseEqualsFreshSingletonLabels) {
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 100; ++trial) {
    const Labels a = randomLabels(rng, 80, 4, 0.3);
    const Labels b = randomLabels(rng, 80, 3, 0.3);
    Labels a_fresh = a;
    Labels b_fresh = b;
    std::int64_t fresh = 100;
    for (auto& l : a_fresh) if (l < 0) l = fresh++;
    for (auto& l : b_fresh) if (l < 0) l = fresh++;
    const RandScores noisy = scoresOf(a, b);
    const RandScores singletons = scoresOf(a_fresh, b_fresh);
    EXPECT_NEAR(noisy.rand_index, singletons.rand_index, 1e-14) << trial;
    EXPECT_NEAR(noisy.adjusted_rand_index, singletons.adjusted_rand_index, 1e-14) << trial;
  }
}

TEST(RandIndex, DegeneratePartitions) {
  // All singletons in both (noise everywhere): identical, so 1 and 1.
  const RandScores singletons = scoresOf({-1, -1, -1, -1}, {0, 1, 2, 3});
  EXPECT_EQ(singletons.rand_index, 1.0);
  EXPECT_EQ(singletons.adjusted_rand_index, 1.0);
  // One cluster in both.
  const RandScores one_cluster = scoresOf({2, 2, 2}, {9, 9, 9});
  EXPECT_EQ(one_cluster.rand_index, 1.0);
  EXPECT_EQ(one_cluster.adjusted_rand_index, 1.0);
  // One cluster against all singletons: every pair disagrees; ARI 0 (no better than chance).
  const RandScores opposite = scoresOf({0, 0, 0, 0}, {-1, -1, -1, -1});
  EXPECT_EQ(opposite.rand_index, 0.0);
  EXPECT_EQ(opposite.adjusted_rand_index, 0.0);
  const RandScores two = scoresOf({-1, -1}, {0, 0});
  EXPECT_EQ(two.rand_index, 0.0);
  EXPECT_EQ(two.adjusted_rand_index, 0.0);
}

TEST(RandIndex, RandIndexMatchesBruteForcePairCounting) {
  std::mt19937_64 rng(20240611);
  std::uniform_int_distribution<std::size_t> size(2, 200);
  std::uniform_int_distribution<int> clusters(1, 10);
  std::uniform_real_distribution<double> noise(0.0, 0.5);
  for (int trial = 0; trial < 300; ++trial) {
    const std::size_t n = size(rng);
    const Labels a = randomLabels(rng, n, clusters(rng), trial % 2 == 0 ? 0.0 : noise(rng));
    const Labels b = randomLabels(rng, n, clusters(rng), trial % 3 == 0 ? 0.0 : noise(rng));
    const RandScores s = scoresOf(a, b);
    EXPECT_NEAR(s.rand_index, bruteForceRandIndex(a, b), 1e-12) << "trial " << trial;
  }
}

TEST(RandIndex, AdjustedRandIndexMatchesDirectFormulas) {
  std::mt19937_64 rng(99);
  std::uniform_int_distribution<std::size_t> size(2, 200);
  std::uniform_int_distribution<int> clusters(1, 10);
  std::uniform_real_distribution<double> noise(0.0, 0.5);
  int checked = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const std::size_t n = size(rng);
    const Labels a = randomLabels(rng, n, clusters(rng), trial % 2 == 0 ? 0.0 : noise(rng));
    // Half the trials compare against a perturbed copy so that high ARI values are covered too.
    Labels b = a;
    if (trial % 2 == 0) {
      b = randomLabels(rng, n, clusters(rng), trial % 3 == 0 ? 0.0 : noise(rng));
    } else {
      std::uniform_int_distribution<std::size_t> index(0, n - 1);
      for (int k = 0; k < 5; ++k) b[index(rng)] = static_cast<std::int64_t>(index(rng) % 4);
    }
    const PairCounts c = countPairs(a, b);
    const bool degenerate = (c.only_a + c.only_b == 0) &&
                            (c.both == 0 || c.neither == 0);  // identical: all or no pairs together
    if (degenerate) continue;
    const RandScores s = scoresOf(a, b);
    EXPECT_NEAR(s.adjusted_rand_index, directAdjustedRandIndex(a, b), 1e-12) << "trial " << trial;
    EXPECT_NEAR(s.adjusted_rand_index, pairCountAdjustedRandIndex(a, b), 1e-12) << "trial " << trial;
    EXPECT_LE(s.adjusted_rand_index, 1.0 + 1e-15);
    ++checked;
  }
  EXPECT_GT(checked, 250);
}

TEST(RandIndex, ScoresAreSymmetric) {
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 200; ++trial) {
    const Labels a = randomLabels(rng, 150, 1 + trial % 9, 0.1 * (trial % 4));
    const Labels b = randomLabels(rng, 150, 1 + trial % 7, 0.1 * (trial % 3));
    const RandScores ab = scoresOf(a, b);
    const RandScores ba = scoresOf(b, a);
    EXPECT_DOUBLE_EQ(ab.rand_index, ba.rand_index) << trial;
    EXPECT_DOUBLE_EQ(ab.adjusted_rand_index, ba.adjusted_rand_index) << trial;
  }
}

TEST(RandIndex, IndependentRandomLabelingsHaveAdjustedIndexNearZero) {
  std::mt19937_64 rng(8);
  const Labels a = randomLabels(rng, 20000, 5, 0.0);
  const Labels b = randomLabels(rng, 20000, 5, 0.0);
  const RandScores s = scoresOf(a, b);
  EXPECT_NEAR(s.adjusted_rand_index, 0.0, 2e-3);
  EXPECT_GT(s.rand_index, 0.6);  // the unadjusted index is high even for chance agreement
}

TEST(RandIndex, LargeInputsDoNotOverflowPairCounts) {
  // One cluster of n against two halves: together-in-b pairs are all together in a.
  // RI = 2 C(n/2, 2) / C(n, 2); ARI = (T sb - T sb) / ... = 0.
  const std::size_t n = 1'000'000;
  Labels a(n, 0);
  Labels b(n, 0);
  for (std::size_t i = n / 2; i < n; ++i) b[i] = 1;
  const RandScores s = scoresOf(a, b);
  const double half = n / 2.0;
  const double expected_ri = 2 * half * (half - 1) / (static_cast<double>(n) * (n - 1));
  EXPECT_NEAR(s.rand_index, expected_ri, 1e-12);
  EXPECT_NEAR(s.adjusted_rand_index, 0.0, 1e-12);
}

}  // namespace
}  // namespace fogmap
