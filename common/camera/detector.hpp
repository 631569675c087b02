#pragma once
// 2D object detection in camera images (DESIGN.md 2.5) with OpenCV, three ways behind one
// interface: the built-in HOG people detector (no model file), Haar/LBP cascades, and a network
// through OpenCV's dnn module (SSD- or YOLO-style outputs). Pure: a detector service feeds it
// frames and publishes what it returns.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "common/camera/detection.hpp"
#include "common/camera/detector_config.hpp"
#include "common/status.hpp"

namespace fogmap::camera {



class Detector {
 public:
  virtual ~Detector() = default;

  // The objects in one 8-bit, 3-channel BGR image: boxes in its pixels, best first, stamped with
  // `camera` and `capture_time_ns`. An empty or differently typed image is an error. Not
  // thread-safe (OpenCV's detectors keep buffers): one detector per thread.
  virtual Expected<std::vector<Detection>> detect(const cv::Mat& image_bgr, const std::string& camera,
                                                  std::int64_t capture_time_ns) = 0;
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
