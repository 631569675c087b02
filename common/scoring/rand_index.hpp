#pragma once
// Agreement of two partitions of the same elements: Rand index and adjusted Rand index
// (Hubert and Arabie 1985). A negative label marks noise: each noise element is its own singleton.
#include <cstdint>
#include <span>

#include "common/base/status.hpp"

namespace fogmap {

struct RandScores {
  double rand_index = 1.0;           // fraction of element pairs on which the partitions agree
  double adjusted_rand_index = 1.0;  // corrected for chance; 1 for identical partitions
};

// Errors when the label vectors differ in length.
Expected<RandScores> randScores(std::span<const std::int64_t> a, std::span<const std::int64_t> b);

}  // namespace fogmap
