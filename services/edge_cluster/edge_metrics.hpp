#pragma once
// The edge runner's observations as Prometheus metrics (the edge's one Metrics object): frames,
// points, clustering time, failed frames, malformed inputs, padded scans, dropped points, and the
// bytes each shipped frame would have cost in baseline mode.
#include <cstddef>
#include <string>

#include "services/common/metrics.hpp"
#include "services/edge_cluster/edge_runner.hpp"

namespace fogmap {

class MetricsObserver final : public EdgeObserver {
 public:
  // `metrics` must outlive the observer; `max_points_per_chunk` is the edge's (EdgeConfig), for
  // what its frames would cost in baseline mode.
  MetricsObserver(Metrics& metrics, std::size_t max_points_per_chunk)
      : metrics_(metrics), max_points_per_chunk_(max_points_per_chunk) {}
  void scanProcessed(const EdgeOutput& output) override;
  void shipped(const EdgeOutput& output) override;
  void failedFrame() override;
  void malformed(const std::string& what) override;
  void droppedPoints(const std::string& reason, std::size_t points) override;
  void paddedScan() override;

 private:
  Metrics& metrics_;
  std::size_t max_points_per_chunk_;
};

}  // namespace fogmap
