#pragma once
// 2D object detection in camera images (DESIGN.md 2.5) with OpenCV, three ways behind one
// interface: the built-in HOG people detector (no model file), Haar/LBP cascades, and a network
// through OpenCV's dnn module (SSD- or YOLO-style outputs). Pure: a detector service feeds it
// frames and publishes what it returns.
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "common/base/status.hpp"
#include "common/camera/detection.hpp"
#include "common/camera/detector_config.hpp"

namespace fogmap::camera {

// Why a detector refused a frame: the reason label of the service's failure counter.
enum class DetectFailure {
  kBadImage,             // empty, or not 8-bit BGR
  kTooLarge,             // the image asks for more work than the detector's bound (HOG's upscaled image)
  kModelFailed,          // OpenCV could not run the network on the image (input size, channels, layers)
  kModelOutputMismatch,  // the network's outputs are not the configured layout, or name classes the names file lacks
  kOpenCvFailed,         // OpenCV threw inside HOG or a cascade
};
const char* detectFailureName(DetectFailure failure);  // "bad_image", "too_large", ...

// Every failure, for counters that list their reasons up front.
inline constexpr DetectFailure kDetectFailures[] = {DetectFailure::kBadImage, DetectFailure::kTooLarge,
                                                    DetectFailure::kModelFailed, DetectFailure::kModelOutputMismatch,
                                                    DetectFailure::kOpenCvFailed};

// The most pixels HOG searches: the image after `hog.upscale`. 8192 x 4096 holds a KITTI frame
// (1242 x 375) at the largest upscale (8) and a 4096 x 4096 frame at 2; the detector's buffers
// are about 10 bytes a pixel on each pyramid level being searched.
inline constexpr long long kMaxHogSearchPixels = 8192LL * 4096LL;

// A refused frame: the reason for counters, the error (naming the field, shape or size) for people.
struct DetectRefusal {
  DetectFailure reason = DetectFailure::kOpenCvFailed;
  Error error;
};

// One frame's detections, or its refusal.
struct DetectResult {
  std::vector<Detection> detections;     // best first; empty when refused
  std::optional<DetectRefusal> refusal;  // set when the frame was refused
  bool ok() const { return !refusal; }
};

class Detector {
 public:
  virtual ~Detector() = default;

  // The objects in one 8-bit, 3-channel BGR image: boxes in its pixels, best first, stamped with
  // `camera` and `capture_time_ns`; or the refusal of the image (empty or differently typed, too
  // large, a network whose outputs do not fit the config). Not thread-safe (OpenCV's detectors
  // keep buffers): one detector per thread.
  virtual DetectResult detectFrame(const cv::Mat& image_bgr, const std::string& camera, std::int64_t capture_time_ns) = 0;

  // detectFrame with the refusal's error only, for callers that do not count reasons.
  Expected<std::vector<Detection>> detect(const cv::Mat& image_bgr, const std::string& camera,
                                          std::int64_t capture_time_ns);
};

// Validates the config and loads what the kind needs (cascade, network, class names). Errors name
// the bad field or the file that is missing or unreadable.
Expected<std::unique_ptr<Detector>> makeDetector(const DetectorConfig& config);

// Greedy non-maximum suppression: best score first, a detection is dropped when it overlaps a kept
// one of the same label by more than `iou_threshold`. Returns the kept ones, best first.
std::vector<Detection> nonMaximumSuppression(std::vector<Detection> detections, double iou_threshold);

// The class names of a names file (one a line; trailing blanks and a final empty line ignored).
// An empty list is an error, as is a blank line between names (ids would shift).
Expected<std::vector<std::string>> readClassNames(const std::string& path);

}  // namespace fogmap::camera
