#pragma once
// The edge runner's observations as Prometheus metrics (the edge's one Metrics object): frames,
// points, clustering time, failed frames, malformed inputs, padded scans and dropped points.
#include <cstddef>
#include <string>

#include "services/common/metrics.hpp"
#include "services/edge_cluster/edge_runner.hpp"

namespace fogmap {

class MetricsObserver final : public EdgeObserver {
 public:
  // `metrics` must outlive the observer.
  explicit MetricsObserver(Metrics& metrics) : metrics_(metrics) {}
  void scanProcessed(const EdgeOutput& output) override;
  void shipped(const EdgeOutput& output) override;
  void failedFrame() override;
  void malformed(const std::string& what) override;
  void droppedPoints(const std::string& reason, std::size_t points) override;
  void paddedScan() override;

 private:
  Metrics& metrics_;
};

}  // namespace fogmap
