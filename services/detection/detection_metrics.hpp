#pragma once
// A detection node's Prometheus families, added to the service's Metrics registry: camera frames
// by outcome, failures by stage and reason, detections, detection time and whether one is running,
// and the frames the tracker link sent and dropped. Bytes sent and reconnects go to the shared
// families of Metrics.
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>

#include "services/common/metrics.hpp"
#include "services/detection/detection_runner.hpp"

namespace fogmap {

class DetectionMetrics final : public DetectionObserver {
 public:
  // Registers the families in `metrics` (which must outlive this) with the service's constant
  // labels; `node` is the detection node's name.
  DetectionMetrics(Metrics& metrics, const std::string& node);

  void frameRead() override;
  void frameUnreadable(FrameFailure failure) override;
  void detectFailed(const std::string& reason) override;
  void detecting(bool busy) override;
  void framesDropped(std::uint64_t frames) override;
  void frameDetected(std::size_t detections, double seconds) override;
  void detectionsCapped(std::size_t left_out) override;

  // The tracker link wrote a frame of `bytes` serialised bytes to `peer` (the tracker's name).
  void frameSent(const std::string& peer, std::size_t bytes);
  // The tracker link dropped a frame (queue full while the tracker was slow or down, or a failed write).
  void linkDropped();
  void reconnected();

 private:
  Metrics& metrics_;
  prometheus::Counter* frames_read_;
  prometheus::Counter* detections_capped_;
  prometheus::Counter* frames_dropped_;
  prometheus::Counter* frames_detected_;
  prometheus::Counter* frames_unreadable_;
  prometheus::Family<prometheus::Counter>* failures_;
  std::map<std::string, prometheus::Counter*> frame_failures_;     // by reason
  std::map<std::string, prometheus::Counter*> detector_failures_;  // by reason
  prometheus::Gauge* detecting_;
  prometheus::Counter* detections_;
  prometheus::Histogram* detection_seconds_;
  prometheus::Counter* frames_sent_;
  prometheus::Counter* dropped_queue_;
  prometheus::Counter* dropped_link_;
};

}  // namespace fogmap
