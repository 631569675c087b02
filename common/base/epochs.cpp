#include "common/base/epochs.hpp"

#include <chrono>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "common/base/clock.hpp"

namespace fogmap {
namespace {

constexpr double kMaxMs = 3600.0 * 1000.0;
constexpr std::int64_t kMaxNs = std::numeric_limits<std::int64_t>::max();

std::int64_t saturatingAdd(std::int64_t a, std::int64_t b) { return a > kMaxNs - b ? kMaxNs : a + b; }

}  // namespace

std::int64_t systemNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::int64_t steadyNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

Expected<EpochSchedule> EpochSchedule::create(double period_ms, double deadline_ms) {
  for (const auto& [name, value] : {std::pair{"period_ms", period_ms}, std::pair{"deadline_ms", deadline_ms}}) {
    if (!std::isfinite(value) || value <= 0.0 || value > kMaxMs) {
      return invalidArgument(std::string(name) + " must be a positive number of milliseconds up to one hour, got " +
                             std::to_string(value));
    }
  }
  // At least one nanosecond, so that epochAt never divides by zero.
  const auto ns = [](double ms) { return std::max<std::int64_t>(1, std::llround(ms * 1e6)); };
  return EpochSchedule(ns(period_ms), ns(deadline_ms));
}

std::uint64_t EpochSchedule::epochAt(std::int64_t now_ns) const {
  return now_ns <= 0 ? 0 : static_cast<std::uint64_t>(now_ns / period_ns_);
}

std::int64_t EpochSchedule::startNs(std::uint64_t epoch) const {
  const auto max_epoch = static_cast<std::uint64_t>(kMaxNs / period_ns_);
  return epoch > max_epoch ? kMaxNs : static_cast<std::int64_t>(epoch) * period_ns_;
}

std::int64_t EpochSchedule::deadlineNs(std::uint64_t epoch, int levels) const {
  std::int64_t deadline = startNs(epoch);
  for (int l = 0; l < levels; ++l) deadline = saturatingAdd(deadline, deadline_ns_);
  return deadline;
}

}  // namespace fogmap
