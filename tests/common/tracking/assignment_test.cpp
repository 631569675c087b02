// Global assignment against brute force: the most pairs, then the least total cost, never a gated pair.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <random>

#include "common/tracking/assignment.hpp"

namespace fogmap::tracking {
namespace {

constexpr double kGated = std::numeric_limits<double>::infinity();

struct Score {
  std::size_t pairs = 0;
  double cost = 0.0;
};

// Every partial matching, the best by (most pairs, least cost).
Score bruteForce(const std::vector<std::vector<double>>& cost) {
  const std::size_t rows = cost.size();
  const std::size_t cols = rows == 0 ? 0 : cost[0].size();
  Score best;
  std::vector<char> taken(cols, 0);
  std::function<void(std::size_t, Score)> visit = [&](std::size_t r, Score s) {
    if (r == rows) {
      if (s.pairs > best.pairs || (s.pairs == best.pairs && s.cost < best.cost - 1e-9)) best = s;
      return;
    }
    visit(r + 1, s);  // row r unmatched
    for (std::size_t c = 0; c < cols; ++c) {
      if (taken[c] || !std::isfinite(cost[r][c])) continue;
      taken[c] = 1;
      visit(r + 1, Score{s.pairs + 1, s.cost + cost[r][c]});
      taken[c] = 0;
    }
  };
  visit(0, Score{});
  return best;
}

Score scoreOf(const std::vector<std::vector<double>>& cost, const std::vector<std::optional<std::size_t>>& match) {
  Score s;
  std::vector<char> used(cost.empty() ? 0 : cost[0].size(), 0);
  for (std::size_t r = 0; r < match.size(); ++r) {
    if (!match[r]) continue;
    EXPECT_TRUE(std::isfinite(cost[r][*match[r]])) << "a gated pair was matched";
    EXPECT_FALSE(used[*match[r]]) << "a column matched twice";
    used[*match[r]] = 1;
    ++s.pairs;
    s.cost += cost[r][*match[r]];
  }
  return s;
}

TEST(Assignment, AgreesWithBruteForceOnRandomGatedProblems) {
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> size(0, 5);
  std::uniform_real_distribution<double> value(-3.0, 10.0);
  // Half the problems gated densely enough to fall apart into several components.
  std::bernoulli_distribution gated_some(0.35);
  std::bernoulli_distribution gated_most(0.8);
  for (int trial = 0; trial < 400; ++trial) {
    auto& gated = trial % 2 == 0 ? gated_some : gated_most;
    const std::size_t rows = static_cast<std::size_t>(size(rng));
    const std::size_t cols = static_cast<std::size_t>(size(rng));
    std::vector<std::vector<double>> cost(rows, std::vector<double>(cols));
    for (auto& row : cost) {
      for (double& c : row) c = gated(rng) ? kGated : value(rng);
    }
    const auto match = assignMinCost(cost);
    ASSERT_EQ(match.size(), rows);
    const Score got = scoreOf(cost, match);
    const Score best = bruteForce(cost);
    EXPECT_EQ(got.pairs, best.pairs) << "trial " << trial;
    EXPECT_NEAR(got.cost, best.cost, 1e-9) << "trial " << trial;
  }
}

TEST(Assignment, PrefersTheGloballyCheapestOverTheGreedyChoice) {
  // Greedy takes (0,0) = 1 and leaves row 1 the 10; the optimum is 2 + 2.
  const std::vector<std::vector<double>> cost = {{1.0, 2.0}, {2.0, 10.0}};
  const auto match = assignMinCost(cost);
  ASSERT_TRUE(match[0] && match[1]);
  EXPECT_EQ(*match[0], 1U);
  EXPECT_EQ(*match[1], 0U);
}

TEST(Assignment, GatedPairsStayUnmatchedAndEmptyProblemsAreFine) {
  EXPECT_TRUE(assignMinCost({}).empty());
  const auto none = assignMinCost({{kGated, kGated}, {kGated, kGated}});
  EXPECT_FALSE(none[0] || none[1]);
  const auto one = assignMinCost({{kGated, 4.0}, {kGated, 1.0}});
  EXPECT_FALSE(one[0]);
  ASSERT_TRUE(one[1]);
  EXPECT_EQ(*one[1], 1U);
}

}  // namespace
}  // namespace fogmap::tracking
