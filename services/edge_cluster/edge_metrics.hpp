#pragma once
// The edge runner's observations as Prometheus metrics (the edge's one Metrics object): frames,
// points, clustering time, failed frames, malformed inputs, padded scans, dropped points, and the
// bytes each shipped frame would have cost in baseline mode; with displacement, the detector's time,
// the centroids found and the centroid frames the tracker link sent and dropped.
#include <cstddef>
#include <string>

#include <prometheus/counter.h>
#include <prometheus/histogram.h>

#include "services/common/metrics.hpp"
#include "services/edge_cluster/edge_runner.hpp"

namespace fogmap {

class MetricsObserver final : public EdgeObserver {
 public:
  // `metrics` must outlive the observer; `max_points_per_chunk` is the edge's (EdgeConfig), for
  // what its frames would cost in baseline mode; `node` is the edge's name (the families' labels).
  MetricsObserver(Metrics& metrics, std::size_t max_points_per_chunk, const std::string& node);
  void scanProcessed(const EdgeOutput& output) override;
  void shipped(const EdgeOutput& output) override;
  void failedFrame() override;
  void malformed(const std::string& what) override;
  void droppedPoints(const std::string& reason, std::size_t points) override;
  void paddedScan() override;

  // The centroid link wrote a frame of `bytes` serialised bytes to `peer` (the tracker's name).
  void centroidFrameSent(const std::string& peer, std::size_t bytes);
  // The centroid link dropped a frame (queue full while the tracker was slow or down, or a failed write).
  void centroidFrameDropped();

 private:
  Metrics& metrics_;
  std::size_t max_points_per_chunk_;
  prometheus::Histogram* displacement_seconds_;
  prometheus::Counter* centroids_;
  prometheus::Counter* vehicle_parts_joined_;
  prometheus::Counter* centroid_frames_sent_;
  prometheus::Counter* centroid_frames_dropped_;
};

}  // namespace fogmap
