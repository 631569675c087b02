#pragma once
// What a camera detector reports (DESIGN.md 2.5): an image box with a class label and a score,
// stamped with the camera and the capture time. Plain types with no OpenCV, so the tracker and the
// wire conversions use them without linking the detectors.
#include <algorithm>
#include <cstdint>
#include <string>

namespace fogmap::camera {

// An axis-aligned image box; left <= right and top <= bottom for a well-formed box.
struct Box2d {
  double left = 0.0, top = 0.0, right = 0.0, bottom = 0.0;  // pixels

  double width() const { return right - left; }
  double height() const { return bottom - top; }
  double area() const { return std::max(0.0, width()) * std::max(0.0, height()); }
};

struct Detection {
  Box2d box;                      // in the pixels of the image that was detected on
  std::string label;              // the class, e.g. "person"
  // Higher is more confident. Comparable within one detector: a probability in [0, 1] for the dnn
  // detector, the SVM margin for HOG, the number of merged neighbours for a cascade.
  double score = 0.0;
  std::string camera;             // the camera's id
  std::int64_t capture_time_ns = 0;
};

// Intersection over union of two boxes: 0 when they do not overlap (or both are empty), 1 when
// equal. The one overlap measure of detections (non-maximum suppression, tests against labels).
inline double iou(const Box2d& a, const Box2d& b) {
  const Box2d overlap{std::max(a.left, b.left), std::max(a.top, b.top), std::min(a.right, b.right),
                      std::min(a.bottom, b.bottom)};
  const double inter = overlap.area();
  const double united = a.area() + b.area() - inter;
  return united > 0.0 ? inter / united : 0.0;
}

}  // namespace fogmap::camera
