#include "common/tracking/centroid_merge.hpp"

#include <cstddef>
#include <numeric>

namespace fogmap::tracking {

std::vector<CloudObservation> mergeCentroids(std::span<const DisplacementCentroid> centroids, double radius_m) {
  const std::size_t n = centroids.size();
  std::vector<std::size_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0);
  const auto root = [&](std::size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      if ((centroids[i].position.head<2>() - centroids[j].position.head<2>()).norm() < radius_m) parent[root(i)] = root(j);
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
  std::vector<CloudObservation> out;
  out.reserve(groups.size());
  for (const auto& members : groups) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const std::size_t i : members) mean += centroids[i].position;
    mean /= static_cast<double>(members.size());
    Eigen::Matrix3d pooled = Eigen::Matrix3d::Zero();
    double weight = 0.0;
    for (const std::size_t i : members) {
      const Eigen::Vector3d d = centroids[i].position - mean;
      const auto w = static_cast<double>(centroids[i].point_count);
      pooled += w * (centroids[i].covariance + d * d.transpose());
      weight += w;
    }
    out.push_back({mean, weight > 0.0 ? Eigen::Matrix3d(pooled / weight) : centroids[members.front()].covariance});
  }
  return out;
}

}  // namespace fogmap::tracking
