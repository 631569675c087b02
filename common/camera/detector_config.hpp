#pragma once
// What a camera's detector is (DESIGN.md 2.5): the settings of the HOG people detector, a Haar/LBP
// cascade or a network through OpenCV's dnn module, as plain structs with their checks. No OpenCV
// here, so the topology reads and checks them; common/camera/detector.hpp builds the detectors.
#include <array>
#include <string>

#include "common/base/status.hpp"

namespace fogmap::camera {

enum class DetectorKind { kHog, kCascade, kDnn };
const char* detectorKindName(DetectorKind kind);  // "hog", "cascade", "dnn"
// The kind a config names; an error naming the field for anything else.
Expected<DetectorKind> parseDetectorKind(const std::string& name);

// OpenCV's default people detector: a linear SVM on HOG features of 64 x 128 windows (INRIA
// persons, about 96 px tall inside the window). Label "person"; score the SVM margin.
struct HogConfig {
  double hit_threshold = 0.0;  // SVM margin a window needs; higher finds fewer, surer people
  double scale = 1.05;         // step between pyramid levels, > 1; smaller is slower and finer
  int win_stride_px = 8;       // window step, a multiple of HOG's 8 px block stride
  // Factor the image is enlarged by before detection (>= 1): at 1 the smallest person found is
  // about 96 px tall, at 2 about 48 px (KITTI pedestrians beyond ~15 m), at about 4x the time.
  double upscale = 1.0;
  double min_height_px = 0.0;  // detections shorter than this (in the image's pixels) are dropped
  double nms_iou = 0.4;        // overlapping detections above this IoU keep only the best
};

// A Haar or LBP cascade (OpenCV's XML format, e.g. Debian's opencv-data). Score: the number of
// raw windows merged into the detection.
struct CascadeConfig {
  std::string cascade_path;  // the XML file; required
  std::string label = "face";  // what the cascade finds
  double scale_factor = 1.1;   // step between pyramid levels, > 1
  int min_neighbors = 3;       // raw windows a detection needs (OpenCV's grouping)
  int min_size_px = 24;        // smallest object searched for (both sides)
  double nms_iou = 0.4;        // overlapping detections above this IoU keep only the best
};

// How a network's outputs encode detections.
enum class DnnOutput {
  // [1, 1, N, 7] rows: image_id, class_id, score, x1, y1, x2, y2 normalised to the image (OpenCV's
  // DetectionOutput layer: Caffe and TensorFlow SSDs, Faster R-CNN).
  kSsd,
  // [N, 5 + C] per output layer: cx, cy, w, h normalised to the image, objectness, C class scores
  // that already include the objectness (OpenCV's Region layer: Darknet YOLOs).
  kYoloDarknet,
  // [N, 5 + C] or [1, N, 5 + C]: cx, cy, w, h in the network input's pixels, objectness, C class
  // scores to be multiplied by it (YOLOv5-style ONNX exports).
  kYoloExport,
};
const char* dnnOutputName(DnnOutput output);  // "ssd", "yolo-darknet", "yolo-export"
Expected<DnnOutput> parseDnnOutput(const std::string& name);

// The largest network input accepted: each side at most kMaxDnnInputSidePx, both together at most
// kMaxDnnInputPixels. Common detectors take 300 x 300 (SSD) to 1280 x 1280 (YOLO); the input blob
// alone is 12 bytes a pixel and a network's activations grow with it, so a 100,000 x 100,000 input
// would ask for terabytes before the first layer ran.
inline constexpr int kMaxDnnInputSidePx = 8192;
inline constexpr long long kMaxDnnInputPixels = 2048LL * 2048LL;

// A network read by cv::dnn::readNet (ONNX, Caffe, TensorFlow, Darknet). The image is resized to
// the input size (no letterbox), mean-subtracted then scaled.
struct DnnConfig {
  std::string model_path;   // .onnx, .caffemodel, .pb, .weights; required
  std::string config_path;  // .prototxt, .pbtxt, .cfg; empty when the model file is enough
  std::string names_path;   // class names, one a line: line i names class id i; required
  DnnOutput output = DnnOutput::kSsd;
  int input_width = 300, input_height = 300;  // pixels, within the bounds above
  std::array<double, 3> mean = {0.0, 0.0, 0.0};  // subtracted per channel (after swap_rb)
  double scale = 1.0;       // multiplies the mean-subtracted pixels (1/255 for most YOLOs)
  bool swap_rb = false;     // feed RGB instead of BGR
  double confidence_threshold = 0.5;  // in [0, 1]: detections scoring below are dropped
  double nms_threshold = 0.45;        // in [0, 1]: same-class detections above this IoU keep the best
};

struct DetectorConfig {
  DetectorKind kind = DetectorKind::kHog;
  HogConfig hog;          // read when kind is hog
  CascadeConfig cascade;  // read when kind is cascade
  DnnConfig dnn;          // read when kind is dnn
};

// Checks the section of the chosen kind: numbers in range (the network's input size within
// kMaxDnnInputSidePx and kMaxDnnInputPixels) and files present. Errors name the field
// ("dnn.confidence_threshold: ..."); a missing file is kNotFound and names the path.
Status validate(const DetectorConfig& config);

// The error of a detector setting: "FIELD: WHAT" (what validate and the detectors report).
Error badField(const std::string& field, const std::string& what);

}  // namespace fogmap::camera
