#include "common/perception/madc.hpp"

#include <utility>

namespace fogmap {

Expected<LocalMapResult> genLocalMap(std::span<const Point> points, std::uint32_t node, std::uint64_t frame,
                                     const MadcParams& params) {
  LocalMapResult result;
  if (params.sensor_links) {
    auto clustering = sensorAwareClusters(points, SensorClusteringParams{params.clustering, *params.sensor_links});
    if (!clustering) return clustering.error();
    result.clustering = std::move(*clustering);
  } else {
    result.clustering = euclideanClusters(points, params.clustering);
  }
  const auto summaries = summarizeClusters(points, result.clustering);
  std::vector<Ellipsoid> ellipsoids;
  ellipsoids.reserve(summaries.size());
  const EllipsoidParams ellipsoid_params = params.ellipsoidParams();
  for (std::size_t k = 0; k < summaries.size(); ++k) {
    ellipsoids.push_back(ellipsoidFromSummary(summaries[k], {node, frame, static_cast<std::uint32_t>(k)}, ellipsoid_params));
  }
  result.map = localMap(std::move(ellipsoids));
  return result;
}

}  // namespace fogmap
