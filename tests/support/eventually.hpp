#pragma once
// Bounded polling, for a condition that has no notification to wait on (state inside another
// object, the server side of a call).
#include <chrono>
#include <thread>

namespace fogmap::test_support {

// True as soon as `condition()` holds; false when it still does not after `timeout`.
template <class Condition>
bool eventually(Condition condition, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (condition()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return condition();
}

}  // namespace fogmap::test_support
