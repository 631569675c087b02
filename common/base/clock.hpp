#pragma once
// The one clock of fogmap: unix time in nanoseconds. Sensor timestamps, epoch boundaries and
// deadlines all use it, so end-to-end latency and admission compare like with like. Every unit
// whose behaviour depends on time takes a NowNs, so tests drive time by hand.
#include <cstdint>
#include <functional>

namespace fogmap {

using NowNs = std::function<std::int64_t()>;

// The system clock (unix epoch), in nanoseconds.
std::int64_t systemNowNs();
// A steady clock in nanoseconds (arbitrary origin, never stepped): for measuring durations and
// timeouts within one process, where a stepped unix clock would fake or hide a stall.
std::int64_t steadyNowNs();

// A duration in nanoseconds as milliseconds, for reports.
inline double nsToMs(std::int64_t ns) { return static_cast<double>(ns) / 1e6; }

}  // namespace fogmap
