#include "services/edge_cluster/edge_metrics.hpp"

#include "services/common/proto_convert.hpp"

namespace fogmap {

void MetricsObserver::scanProcessed(const EdgeOutput& output) {
  metrics_.framesProcessed();
  metrics_.pointsIn(output.points_in);
  metrics_.pointsOut(output.points_out);
  if (output.map) metrics_.clusteringSeconds(output.clustering_seconds);
}

void MetricsObserver::shipped(const EdgeOutput& output) {
  if (output.map) metrics_.mapsOut();
  const MapHeader* header = output.map ? &output.map->header
                                       : (output.chunks.empty() ? nullptr : &output.chunks.front().header);
  if (header != nullptr) {
    metrics_.baselineBytes(baselineUploadBytes(*header, output.points_out, max_points_per_chunk_, header->epoch));
  }
}

void MetricsObserver::failedFrame() { metrics_.failedFrames(); }

void MetricsObserver::malformed(const std::string& what) { metrics_.malformed(what); }

void MetricsObserver::droppedPoints(const std::string& reason, std::size_t points) {
  metrics_.droppedPoints(reason, points);
}

void MetricsObserver::paddedScan() { metrics_.paddedScans(); }

}  // namespace fogmap
