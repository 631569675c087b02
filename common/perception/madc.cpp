#include "common/perception/madc.hpp"

#include <utility>

namespace fogmap {

LocalMapper::LocalMapper(MadcParams params) : params_(std::move(params)) {
  if (params_.sensor_links) {
    clusterer_.emplace(SensorClusterer::create(SensorClusteringParams{params_.clustering, *params_.sensor_links}));
  }
}

Expected<Clustering> LocalMapper::cluster(std::span<const Point> points) const {
  if (!clusterer_) return euclideanClusters(points, params_.clustering);
  if (!*clusterer_) return clusterer_->error();
  return (*clusterer_)->cluster(points);
}

Map LocalMapper::summarise(std::span<const Point> points, const Clustering& clustering, std::uint32_t node,
                           std::uint64_t frame) const {
  return localMap(clusterEllipsoids(points, clustering, node, frame, params_.ellipsoidParams()));
}

Expected<LocalMapResult> LocalMapper::map(std::span<const Point> points, std::uint32_t node, std::uint64_t frame) const {
  auto clustering = cluster(points);
  if (!clustering) return clustering.error();
  LocalMapResult result;
  result.map = summarise(points, *clustering, node, frame);
  result.clustering = std::move(*clustering);
  return result;
}

Expected<LocalMapResult> genLocalMap(std::span<const Point> points, std::uint32_t node, std::uint64_t frame,
                                     const MadcParams& params) {
  return LocalMapper(params).map(points, node, frame);
}

std::vector<Ellipsoid> clusterEllipsoids(std::span<const Point> points, const Clustering& clustering, std::uint32_t node,
                                         std::uint64_t frame, const EllipsoidParams& params) {
  const std::vector<ClusterSummary> summaries = summarizeClusters(points, clustering);
  std::vector<Ellipsoid> ellipsoids;
  ellipsoids.reserve(summaries.size());
  if (!params.reaches()) {
    for (std::size_t k = 0; k < summaries.size(); ++k) {
      ellipsoids.push_back(ellipsoidFromSummary(summaries[k], {node, frame, static_cast<std::uint32_t>(k)}, params));
    }
    return ellipsoids;
  }
  std::vector<ClusterReach> reaches;
  reaches.reserve(summaries.size());
  for (const ClusterSummary& summary : summaries) reaches.emplace_back(summary);
  for (std::size_t i = 0; i < points.size() && i < clustering.labels.size(); ++i) {
    const auto label = clustering.labels[i];
    if (label >= 0) reaches[static_cast<std::size_t>(label)].add(points[i]);
  }
  for (std::size_t k = 0; k < reaches.size(); ++k) {
    ellipsoids.push_back(reaches[k].ellipsoid({node, frame, static_cast<std::uint32_t>(k)}, params));
  }
  return ellipsoids;
}

}  // namespace fogmap
