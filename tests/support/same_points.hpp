#pragma once
// Clouds compared point by point, for tests of what reads, replays or pre-processes them.
#include <algorithm>

#include "common/geometry/cloud.hpp"

namespace fogmap::test_support {

// Whether `a` and `b` hold the same points in the same order. Point has no operator== (cloud.hpp):
// its members, all four, compared exactly.
inline bool samePoints(const Cloud& a, const Cloud& b) {
  return std::equal(a.begin(), a.end(), b.begin(), b.end(), [](const Point& p, const Point& q) {
    return p.x == q.x && p.y == q.y && p.z == q.z && p.intensity == q.intensity;
  });
}

}  // namespace fogmap::test_support
