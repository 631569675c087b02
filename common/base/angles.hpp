#pragma once
// Degrees and radians: configuration, beam tables and reports speak degrees, the geometry radians.
#include <cmath>
#include <numbers>

namespace fogmap {

inline constexpr double kDegToRad = std::numbers::pi / 180.0;
inline constexpr double kRadToDeg = 180.0 / std::numbers::pi;

// An angle (radians) turned by whole turns into (-pi, pi].
inline double wrapToPi(double radians) {
  const double a = std::remainder(radians, 2.0 * std::numbers::pi);  // [-pi, pi]
  return a <= -std::numbers::pi ? a + 2.0 * std::numbers::pi : a;
}

}  // namespace fogmap
