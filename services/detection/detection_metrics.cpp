#include "services/detection/detection_metrics.hpp"

#include <prometheus/counter.h>
#include <prometheus/gauge.h>
#include <prometheus/registry.h>

#include "common/config/topology.hpp"

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
  failures_ = &prometheus::BuildCounter()
                   .Name("fogmap_detection_failures_total")
                   .Help("Frames that gave no detections, by stage and reason. stage frame: the source could not "
                         "give the frame (unreadable, unknown_format, bad_header, too_large: above the camera's "
                         "max_image_pixels, refused before decoding; decode_failed, not_colour, grab_failed). "
                         "stage detector: the detector refused it (bad_image, too_large, model_failed, "
                         "model_output_mismatch, opencv_failed, truth_replay_failed).")
                   .Labels(c)
                   .Register(r);
  // Every reason from the start, so a rate over a reason that has not happened yet reads 0.
  for (FrameFailure f : kFrameFailures) {
    frame_failures_[frameFailureName(f)] = &failures_->Add({{"stage", "frame"}, {"reason", frameFailureName(f)}});
  }
  for (camera::DetectFailure f : camera::kDetectFailures) {
    const std::string reason = camera::detectFailureName(f);
    detector_failures_[reason] = &failures_->Add({{"stage", "detector"}, {"reason", reason}});
  }
  detector_failures_["truth_replay_failed"] = &failures_->Add({{"stage", "detector"}, {"reason", "truth_replay_failed"}});
  detecting_ = &prometheus::BuildGauge()
                    .Name("fogmap_detection_in_progress")
                    .Help("1 while the detector works on a frame: a detector stuck at 1 is one slow frame.")
                    .Labels(c)
                    .Register(r)
                    .Add({});
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
  detections_capped_ = &prometheus::BuildCounter()
                            .Name("fogmap_detections_capped_total")
                            .Help("Detections left out of frames that had more than the tracker takes "
                                  "(the least confident).")
                            .Labels(c)
                            .Register(r)
                            .Add({});
  dropped_queue_ = &dropped.Add({{"reason", "queue"}});
  dropped_link_ = &dropped.Add({{"reason", "link"}});
}

void DetectionMetrics::frameRead() { frames_read_->Increment(); }

void DetectionMetrics::frameUnreadable(FrameFailure failure) {
  frames_unreadable_->Increment();
  frame_failures_.at(frameFailureName(failure))->Increment();
}

void DetectionMetrics::detectFailed(const std::string& reason) {
  auto it = detector_failures_.find(reason);
  if (it == detector_failures_.end()) {
    // A reason not listed up front still counts; only the detector thread adds series.
    it = detector_failures_.emplace(reason, &failures_->Add({{"stage", "detector"}, {"reason", reason}})).first;
  }
  it->second->Increment();
}

void DetectionMetrics::detecting(bool busy) { detecting_->Set(busy ? 1.0 : 0.0); }

void DetectionMetrics::framesDropped(std::uint64_t frames) {
  frames_dropped_->Increment(static_cast<double>(frames));
  dropped_queue_->Increment(static_cast<double>(frames));
}

void DetectionMetrics::frameDetected(std::size_t detections, double seconds) {
  frames_detected_->Increment();
  detections_->Increment(static_cast<double>(detections));
  detection_seconds_->Observe(seconds);
}

void DetectionMetrics::detectionsCapped(std::size_t left_out) {
  detections_capped_->Increment(static_cast<double>(left_out));
}

void DetectionMetrics::frameSent(const std::string& peer, std::size_t bytes) {
  frames_sent_->Increment();
  metrics_.bytesSent(peer, "detections", bytes);
}

void DetectionMetrics::linkDropped() { dropped_link_->Increment(); }

void DetectionMetrics::reconnected() { metrics_.reconnects(); }

}  // namespace fogmap
