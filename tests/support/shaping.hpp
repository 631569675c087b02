#pragma once
// What the shaped-link tests share (tests/harness/shaped_links_test.cpp, the links; and
// tests/integration/shaped_cluster_test.cpp, clusters behind them): the skip, with its reason,
// where shaped links cannot be made (no root, no ip/tc, namespaces refused), and the link rate.
#include <gtest/gtest.h>

#include "harness/shaped_links.hpp"

#define SKIP_UNLESS_SHAPING_IS_POSSIBLE()                                                \
  if (const auto available = ::fogmap::harness::shapingAvailable(); !available) {          \
    GTEST_SKIP() << "shaped links cannot be made here: " << available.error().message; \
  }

namespace fogmap::test_support {

inline constexpr double kShapedRateMbitPerS = 10.0;  // the MAD-C paper's sensor links

}  // namespace fogmap::test_support
