#include "common/tracking/centroid_merge.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <utility>
#include <numeric>

namespace fogmap::tracking {

std::vector<CloudObservation> mergeCentroids(std::span<const DisplacementCentroid> centroids, double radius_m,
                                             std::span<const DisplacementCentroid> located) {
  const std::size_t n = centroids.size();
  std::vector<std::size_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  const auto root = [&](std::size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  // Pairs closer than the radius lie in the same or neighbouring cells of a grid of that size, so
  // the linkage looks there only: linear in the centroids (an epoch may bring tens of thousands),
  // the same groups as comparing all pairs.
  if (radius_m > 0.0) {
    const auto cellOf = [&](const Eigen::Vector3d& p) {
      return std::pair<std::int64_t, std::int64_t>{static_cast<std::int64_t>(std::floor(p.x() / radius_m)),
                                                   static_cast<std::int64_t>(std::floor(p.y() / radius_m))};
    };
    std::map<std::pair<std::int64_t, std::int64_t>, std::vector<std::size_t>> cells;
    for (std::size_t i = 0; i < n; ++i) cells[cellOf(centroids[i].position)].push_back(i);
    for (std::size_t i = 0; i < n; ++i) {
      const auto [cx, cy] = cellOf(centroids[i].position);
      for (std::int64_t dx = -1; dx <= 1; ++dx) {
        for (std::int64_t dy = -1; dy <= 1; ++dy) {
          const auto cell = cells.find({cx + dx, cy + dy});
          if (cell == cells.end()) continue;
          for (const std::size_t j : cell->second) {
            if (j <= i) continue;
            if ((centroids[i].position.head<2>() - centroids[j].position.head<2>()).norm() < radius_m) {
              parent[root(i)] = root(j);
            }
          }
        }
      }
    }
  }
  // Groups in the order of their first member.
  std::vector<std::vector<std::size_t>> groups;
  std::vector<std::size_t> group_of_root(n, n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t r = root(i);
    if (group_of_root[r] == n) {
      group_of_root[r] = groups.size();
      groups.emplace_back();
    }
    groups[group_of_root[r]].push_back(i);
  }
  // Grouped as seen, placed as located.
  const std::span<const DisplacementCentroid> place = located.size() == n ? located : centroids;
  std::vector<CloudObservation> out;
  out.reserve(groups.size());
  for (const auto& members : groups) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const std::size_t i : members) mean += place[i].position;
    mean /= static_cast<double>(members.size());
    Eigen::Matrix3d pooled = Eigen::Matrix3d::Zero();
    double weight = 0.0;
    std::size_t points = 0;
    for (const std::size_t i : members) {
      points += place[i].point_count;
      const Eigen::Vector3d d = place[i].position - mean;
      const auto w = static_cast<double>(place[i].point_count);
      pooled += w * (place[i].covariance + d * d.transpose());
      weight += w;
    }
    out.push_back({mean, weight > 0.0 ? Eigen::Matrix3d(pooled / weight) : place[members.front()].covariance, points});
  }
  return out;
}

DisplacementCentroid visibleSideCorrected(const DisplacementCentroid& centroid, const Eigen::Vector3d& sensor,
                                          double max_radius_m) {
  const Eigen::Vector2d sight = centroid.position.head<2>() - sensor.head<2>();
  const double distance = sight.norm();
  if (max_radius_m <= 0.0 || distance <= 0.0 || !std::isfinite(distance)) return centroid;
  const Eigen::Vector2d along = sight / distance;
  const Eigen::Vector2d across(-along.y(), along.x());
  const double variance_across = std::max(0.0, across.dot(centroid.covariance.topLeftCorner<2, 2>() * across));
  const double radius = std::sqrt(3.0 * variance_across);
  if (!(radius <= max_radius_m)) return centroid;
  DisplacementCentroid corrected = centroid;
  corrected.position.head<2>() += along * (M_PI / 4.0 * radius);
  return corrected;
}

}  // namespace fogmap::tracking
