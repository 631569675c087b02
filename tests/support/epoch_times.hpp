#pragma once
// Times for tests of epochs, in nanoseconds of Unix time: a millisecond, the cluster period every
// such test runs at (100 ms), an arbitrary start time and the epoch that holds it, and times
// within the epochs that follow.
#include <cstdint>

namespace fogmap::test_support {

inline constexpr std::int64_t kMs = 1'000'000;
inline constexpr std::int64_t kPeriodNs = 100 * kMs;
inline constexpr std::int64_t kT0 = 1'700'000'000'000'000'000;
inline constexpr std::uint64_t kE0 = kT0 / kPeriodNs;  // 17'000'000'000, which starts at kT0

// Epoch kE0 + k.
inline constexpr std::uint64_t E(std::int64_t k) { return static_cast<std::uint64_t>(static_cast<std::int64_t>(kE0) + k); }
// When `epoch` starts.
inline constexpr std::int64_t startOf(std::uint64_t epoch) { return static_cast<std::int64_t>(epoch) * kPeriodNs; }
// `offset_ms` into epoch kE0 + k.
inline constexpr std::int64_t at(std::int64_t k, double offset_ms) {
  return startOf(E(k)) + static_cast<std::int64_t>(offset_ms * kMs);
}

}  // namespace fogmap::test_support
