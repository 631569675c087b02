#include "common/scoring/rand_index.hpp"

#include <cstddef>
#include <string>
#include <unordered_map>
#include <utility>

namespace fogmap {
namespace {

// n choose 2 without the intermediate n (n - 1) overflowing: halve the even factor first.
std::uint64_t pairs(std::uint64_t n) {
  return n % 2 == 0 ? (n / 2) * (n - 1) : n * ((n - 1) / 2);
}

struct LabelPairHash {
  std::size_t operator()(const std::pair<std::int64_t, std::int64_t>& p) const {
    const auto a = static_cast<std::uint64_t>(p.first);
    const auto b = static_cast<std::uint64_t>(p.second);
    // Mixed (splitmix64 finaliser) so that small consecutive labels spread over the buckets.
    std::uint64_t h = a * 0x9E3779B97F4A7C15ULL ^ b;
    h ^= h >> 31;
    h *= 0xBF58476D1CE4E5B9ULL;
    h ^= h >> 27;
    return static_cast<std::size_t>(h);
  }
};

template <class Map>
std::uint64_t sumOfPairs(const Map& counts) {
  std::uint64_t sum = 0;
  for (const auto& [label, count] : counts) sum += pairs(count);
  return sum;
}

}  // namespace

Expected<RandScores> randScores(std::span<const std::int64_t> a, std::span<const std::int64_t> b) {
  if (a.size() != b.size()) {
    return invalidArgument("rand index: label vectors differ in length (" +
                           std::to_string(a.size()) + " vs " + std::to_string(b.size()) + ")");
  }
  const std::uint64_t n = a.size();
  if (n < 2) return RandScores{1.0, 1.0};

  // Noise elements are singletons: they add no pair to any row, column or cell, so they are
  // simply left out of the counts (they still count in n).
  std::unordered_map<std::int64_t, std::uint64_t> rows;
  std::unordered_map<std::int64_t, std::uint64_t> cols;
  std::unordered_map<std::pair<std::int64_t, std::int64_t>, std::uint64_t, LabelPairHash> cells;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i] >= 0) ++rows[a[i]];
    if (b[i] >= 0) ++cols[b[i]];
    if (a[i] >= 0 && b[i] >= 0) ++cells[{a[i], b[i]}];
  }
  // Each of these is at most pairs(n), so none overflows.
  const std::uint64_t total = pairs(n);
  const std::uint64_t same_a = sumOfPairs(rows);
  const std::uint64_t same_b = sumOfPairs(cols);
  const std::uint64_t same_both = sumOfPairs(cells);

  RandScores scores;
  // Disagreeing pairs: together in one partition, apart in the other.
  const double disagreements =
      static_cast<double>(same_a - same_both) + static_cast<double>(same_b - same_both);
  scores.rand_index = 1.0 - disagreements / static_cast<double>(total);

  // Hubert-Arabie, multiplied through by total to keep the terms integral as long as possible.
  // max - expected is zero exactly when both partitions are all singletons or both one cluster.
  if (same_a == same_b && (same_a == 0 || same_a == total)) {
    const bool identical = same_both == same_a && same_both == same_b;
    scores.adjusted_rand_index = identical ? 1.0 : 0.0;
    return scores;
  }
  const long double t = static_cast<long double>(total);
  const long double sa = static_cast<long double>(same_a);
  const long double sb = static_cast<long double>(same_b);
  const long double sab = static_cast<long double>(same_both);
  const long double numerator = t * sab - sa * sb;
  const long double denominator = 0.5L * t * (sa + sb) - sa * sb;
  scores.adjusted_rand_index = static_cast<double>(numerator / denominator);
  return scores;
}

}  // namespace fogmap
