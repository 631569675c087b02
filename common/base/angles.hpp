#pragma once
// Degrees and radians: configuration, beam tables and reports speak degrees, the geometry radians.
#include <numbers>

namespace fogmap {

inline constexpr double kDegToRad = std::numbers::pi / 180.0;
inline constexpr double kRadToDeg = 180.0 / std::numbers::pi;

}  // namespace fogmap
