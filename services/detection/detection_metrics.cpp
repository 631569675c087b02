#include "services/detection/detection_metrics.hpp"

#include <prometheus/registry.h>

#include "common/topology.hpp"

namespace fogmap {

DetectionMetrics::DetectionMetrics(Metrics& metrics, const std::string& node) : metrics_(metrics) {
  prometheus::Registry& r = metrics.registry();
  const prometheus::Labels c{{"service", serviceName(Role::kDetection)}, {"node", node}};
  auto& frames = prometheus::BuildCounter()
                     .Name("fogmap_camera_frames_total")
                     .Help("Camera frames by outcome: read (queued for the detector), dropped (by the queue for a "
                           "newer one), detected (detections sent on), unreadable (skipped).")
                     .Labels(c)
                     .Register(r);
  frames_read_ = &frames.Add({{"outcome", "read"}});
  frames_dropped_ = &frames.Add({{"outcome", "dropped"}});
  frames_detected_ = &frames.Add({{"outcome", "detected"}});
  frames_unreadable_ = &frames.Add({{"outcome", "unreadable"}});
  detections_ = &prometheus::BuildCounter()
                     .Name("fogmap_detections_total")
                     .Help("2D detections in the detected frames.")
                     .Labels(c)
                     .Register(r)
                     .Add({});
  // HOG on a KITTI image takes tens to hundreds of milliseconds; a network on a CPU up to seconds.
  detection_seconds_ = &prometheus::BuildHistogram()
                            .Name("fogmap_detection_seconds")
                            .Help("Time to detect on one frame.")
                            .Labels(c)
                            .Register(r)
                            .Add({}, prometheus::Histogram::BucketBoundaries{0.001, 0.0025, 0.005, 0.01, 0.025, 0.05,
                                                                              0.1, 0.25, 0.5, 1, 2.5, 5});
  frames_sent_ = &prometheus::BuildCounter()
                      .Name("fogmap_detection_frames_sent_total")
                      .Help("Detection frames written to the stream to the tracker.")
                      .Labels(c)
                      .Register(r)
                      .Add({});
  auto& dropped = prometheus::BuildCounter()
                      .Name("fogmap_detection_frames_dropped_total")
                      .Help("Frames that never reached the tracker, by reason: queue (an image dropped before "
                            "detection for a newer one), link (detections dropped while the tracker was slow or down).")
                      .Labels(c)
                      .Register(r);
  dropped_queue_ = &dropped.Add({{"reason", "queue"}});
  dropped_link_ = &dropped.Add({{"reason", "link"}});
}

void DetectionMetrics::frameRead() { frames_read_->Increment(); }

void DetectionMetrics::frameUnreadable() { frames_unreadable_->Increment(); }

void DetectionMetrics::framesDropped(std::uint64_t frames) {
  frames_dropped_->Increment(static_cast<double>(frames));
  dropped_queue_->Increment(static_cast<double>(frames));
}

void DetectionMetrics::frameDetected(std::size_t detections, double seconds) {
  frames_detected_->Increment();
  detections_->Increment(static_cast<double>(detections));
  detection_seconds_->Observe(seconds);
}

void DetectionMetrics::frameSent(const std::string& peer, std::size_t bytes) {
  frames_sent_->Increment();
  metrics_.bytesSent(peer, "detections", bytes);
}

void DetectionMetrics::linkDropped() { dropped_link_->Increment(); }

void DetectionMetrics::reconnected() { metrics_.reconnects(); }

}  // namespace fogmap
