#include "services/edge_cluster/edge_metrics.hpp"

#include <prometheus/registry.h>

#include "common/config/topology.hpp"
#include "services/common/proto_convert.hpp"

namespace fogmap {

MetricsObserver::MetricsObserver(Metrics& metrics, std::size_t max_points_per_chunk, const std::string& node)
    : metrics_(metrics), max_points_per_chunk_(max_points_per_chunk) {
  prometheus::Registry& r = metrics.registry();
  const prometheus::Labels c{{"service", serviceName(Role::kEdge)}, {"node", node}};
  // The paper's target is 10 ms a HDL-64E frame; a VLP-16's takes about a millisecond.
  displacement_seconds_ = &prometheus::BuildHistogram()
                               .Name("fogmap_displacement_seconds")
                               .Help("Time of the displacement detector on one cleaned scan: change detection, DBSCAN, z filter.")
                               .Labels(c)
                               .Register(r)
                               .Add({}, prometheus::Histogram::BucketBoundaries{0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025,
                                                                                0.05, 0.1, 0.25});
  centroids_ = &prometheus::BuildCounter()
                    .Name("fogmap_displacement_centroids_total")
                    .Help("Displacement centroids found (moving clusters kept by the z-variance filter).")
                    .Labels(c)
                    .Register(r)
                    .Add({});
  vehicle_parts_joined_ = &prometheus::BuildCounter()
                              .Name("fogmap_vehicle_parts_joined_total")
                              .Help("Local clusters joined into another as parts of one vehicle before they were summarised.")
                              .Labels(c)
                              .Register(r)
                              .Add({});
  centroid_frames_sent_ = &prometheus::BuildCounter()
                               .Name("fogmap_centroid_frames_sent_total")
                               .Help("Centroid frames written to the tracker's stream.")
                               .Labels(c)
                               .Register(r)
                               .Add({});
  centroid_frames_dropped_ = &prometheus::BuildCounter()
                                  .Name("fogmap_centroid_frames_dropped_total")
                                  .Help("Centroid frames dropped: the queue to a slow or absent tracker was full, or a write failed.")
                                  .Labels(c)
                                  .Register(r)
                                  .Add({});
}

void MetricsObserver::scanProcessed(const EdgeOutput& output) {
  metrics_.framesProcessed();
  metrics_.pointsIn(output.points_in);
  metrics_.pointsOut(output.points_out);
  if (output.map) metrics_.clusteringSeconds(output.clustering_seconds);
  if (output.displacement_seconds) displacement_seconds_->Observe(*output.displacement_seconds);
  if (output.centroids) centroids_->Increment(static_cast<double>(output.centroids->centroids.size()));
  vehicle_parts_joined_->Increment(static_cast<double>(output.vehicle_parts_joined));
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

void MetricsObserver::centroidFrameSent(const std::string& peer, std::size_t bytes) {
  centroid_frames_sent_->Increment();
  metrics_.bytesSent(peer, "centroids", bytes);
}

void MetricsObserver::centroidFrameDropped() { centroid_frames_dropped_->Increment(); }

}  // namespace fogmap
