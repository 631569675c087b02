#pragma once
// How much slower than a Release build the processes under test run: the environment variable
// FOGMAP_TEST_TIME_SCALE, a number in [1, 50] (default 1). tools/tsan.sh sets it: its instrumented
// services run 5 to 15 times slower, so an edge clustering a whole KITTI scan cannot keep 10 Hz.
// A test whose oracle needs the cluster to keep its schedule (complete epochs) stretches the
// schedule by it; nothing else changes, so the oracle is the same.
#include <cstdio>
#include <cstdlib>
#include <string>

namespace fogmap::test_support {

inline double testTimeScale() {
  const char* text = std::getenv("FOGMAP_TEST_TIME_SCALE");
  if (text == nullptr || *text == '\0') return 1.0;
  char* end = nullptr;
  const double scale = std::strtod(text, &end);
  if (end == text || *end != '\0' || !(scale >= 1.0 && scale <= 50.0)) {
    std::fprintf(stderr, "FOGMAP_TEST_TIME_SCALE=%s is not a number in [1, 50]; using 1\n", text);
    return 1.0;
  }
  return scale;
}

}  // namespace fogmap::test_support
