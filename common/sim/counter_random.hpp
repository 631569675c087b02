#pragma once
// Counter-based random numbers for the simulator: a draw is a pure function of its counters (seed,
// frame, sensor, object, index), so the same scene gives the same draws on any thread and in any
// order.
#include <cstdint>
#include <string>

namespace fogmap::sim {

// SplitMix64's finaliser: one well-mixed 64-bit value per counter.
inline std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

// FNV-1a (64 bit) of a sensor's name, so each sensor draws its own stream.
inline std::uint64_t nameHash(const std::string& name) {
  std::uint64_t h = 0xCBF29CE484222325ULL;
  for (const unsigned char c : name) h = (h ^ c) * 0x100000001B3ULL;
  return h;
}

}  // namespace fogmap::sim
