#include "common/sim/truth.hpp"

#include <cmath>
#include <limits>
#include <unordered_map>

#include "common/sim/scene.hpp"

namespace fogmap::sim {
namespace {

struct CellKey {
  std::int64_t x, y, z;
  bool operator==(const CellKey&) const = default;
};
struct CellHash {
  std::size_t operator()(const CellKey& k) const {
    return static_cast<std::size_t>((k.x * 73856093) ^ (k.y * 19349663) ^ (k.z * 83492791));
  }
};

}  // namespace

std::vector<std::int64_t> truthOfPoints(std::span<const Point> points, std::span<const Point> returns,
                                        std::span<const std::uint32_t> truth, double reach_m) {
  std::vector<std::int64_t> out(points.size(), -1);
  if (!(reach_m > 0.0) || returns.size() != truth.size()) return out;
  const double inverse = 1.0 / reach_m;
  const auto key = [&](const Point& p) {
    return CellKey{static_cast<std::int64_t>(std::floor(p.x * inverse)), static_cast<std::int64_t>(std::floor(p.y * inverse)),
                   static_cast<std::int64_t>(std::floor(p.z * inverse))};
  };
  std::unordered_map<CellKey, std::vector<std::size_t>, CellHash> cells;
  for (std::size_t i = 0; i < returns.size(); ++i) {
    if (isFinitePoint(returns[i])) cells[key(returns[i])].push_back(i);
  }
  const double reach2 = reach_m * reach_m;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Point& p = points[i];
    if (!isFinitePoint(p)) continue;
    const CellKey c = key(p);
    double best = std::numeric_limits<double>::infinity();
    std::size_t nearest = returns.size();
    // Anything within reach lies in the 27 cells around the point's own.
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        for (std::int64_t dz = -1; dz <= 1; ++dz) {
          const auto found = cells.find({c.x + dx, c.y + dy, c.z + dz});
          if (found == cells.end()) continue;
          for (const std::size_t r : found->second) {
            const double ex = static_cast<double>(returns[r].x) - p.x;
            const double ey = static_cast<double>(returns[r].y) - p.y;
            const double ez = static_cast<double>(returns[r].z) - p.z;
            const double d2 = ex * ex + ey * ey + ez * ez;
            if (d2 < best || (d2 == best && r < nearest)) {
              best = d2;
              nearest = r;
            }
          }
        }
      }
    }
    if (nearest < returns.size() && best <= reach2 && truth[nearest] != kGroundId) out[i] = truth[nearest];
  }
  return out;
}

}  // namespace fogmap::sim
