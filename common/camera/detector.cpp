#include "common/camera/detector.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <utility>

#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/objdetect.hpp>

namespace fogmap::camera {
namespace {

DetectResult refuse(DetectFailure reason, Error error) {
  DetectResult r;
  r.refusal = DetectRefusal{reason, std::move(error)};
  return r;
}

DetectResult found(std::vector<Detection> detections) {
  DetectResult r;
  r.detections = std::move(detections);
  return r;
}

Status checkImage(const cv::Mat& image) {
  if (image.empty()) return badField("image_bgr", "is empty");
  if (image.type() != CV_8UC3) {
    return badField("image_bgr", "must be 8-bit with 3 channels (CV_8UC3, BGR), got " + cv::typeToString(image.type()));
  }
  return {};
}

// Every detector ends the same way: boxes clipped to the image (networks and upscaled windows
// reach past it), empty ones dropped, overlaps suppressed, stamped.
std::vector<Detection> finish(std::vector<Detection> raw, const cv::Size& image, double nms_iou, const std::string& camera,
                              std::int64_t capture_time_ns) {
  std::vector<Detection> inside;
  inside.reserve(raw.size());
  for (Detection& d : raw) {
    d.box.left = std::clamp(d.box.left, 0.0, static_cast<double>(image.width));
    d.box.right = std::clamp(d.box.right, 0.0, static_cast<double>(image.width));
    d.box.top = std::clamp(d.box.top, 0.0, static_cast<double>(image.height));
    d.box.bottom = std::clamp(d.box.bottom, 0.0, static_cast<double>(image.height));
    if (d.box.area() <= 0.0) continue;
    d.camera = camera;
    d.capture_time_ns = capture_time_ns;
    inside.push_back(std::move(d));
  }
  return nonMaximumSuppression(std::move(inside), nms_iou);
}

std::string num(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

Box2d boxOf(const cv::Rect& r, double scale) {
  return {r.x / scale, r.y / scale, (r.x + r.width) / scale, (r.y + r.height) / scale};
}

class HogDetector final : public Detector {
 public:
  explicit HogDetector(HogConfig config) : config_(config) {
    hog_.setSVMDetector(cv::HOGDescriptor::getDefaultPeopleDetector());
  }

  DetectResult detectFrame(const cv::Mat& image_bgr, const std::string& camera, std::int64_t capture_time_ns) override {
    if (Status s = checkImage(image_bgr); !s) return refuse(DetectFailure::kBadImage, s.error());
    // The upscaled image is what HOG's buffers and time grow with: bounded before it is made.
    const double search_pixels = static_cast<double>(image_bgr.cols) * image_bgr.rows * config_.upscale * config_.upscale;
    if (search_pixels > static_cast<double>(kMaxHogSearchPixels)) {
      return refuse(DetectFailure::kTooLarge,
                    badField("hog.upscale", "a " + std::to_string(image_bgr.cols) + " x " + std::to_string(image_bgr.rows) +
                                                " image upscaled by " + num(config_.upscale) + " is " +
                                                std::to_string(std::llround(search_pixels)) + " pixels, above the " +
                                                std::to_string(kMaxHogSearchPixels) + " HOG searches"));
    }
    cv::Mat input = image_bgr;
    try {
      if (config_.upscale > 1.0) cv::resize(image_bgr, input, cv::Size(), config_.upscale, config_.upscale, cv::INTER_LINEAR);
    } catch (const cv::Exception& e) {
      return refuse(DetectFailure::kOpenCvFailed, Error{ErrorCode::kInternal, std::string("hog: OpenCV failed to upscale: ") + e.what()});
    }
    // The image must hold one window, or OpenCV has no pyramid level to search.
    if (input.cols < hog_.winSize.width || input.rows < hog_.winSize.height) return found({});

    std::vector<cv::Rect> windows;
    std::vector<double> margins;
    const cv::Size stride(config_.win_stride_px, config_.win_stride_px);
    // OpenCV's own grouping (finalThreshold > 0) drops the margins; group with our NMS instead so
    // every detection keeps its score.
    constexpr double kNoGrouping = 0.0;
    try {
      hog_.detectMultiScale(input, windows, margins, config_.hit_threshold, stride, cv::Size(0, 0), config_.scale,
                            kNoGrouping, false);
    } catch (const cv::Exception& e) {
      return refuse(DetectFailure::kOpenCvFailed, Error{ErrorCode::kInternal, std::string("hog: OpenCV failed: ") + e.what()});
    }
    std::vector<Detection> raw;
    raw.reserve(windows.size());
    for (std::size_t i = 0; i < windows.size(); ++i) {
      Detection d;
      d.box = boxOf(windows[i], config_.upscale);
      if (d.box.height() < config_.min_height_px) continue;
      d.label = "person";
      d.score = i < margins.size() ? margins[i] : 0.0;
      raw.push_back(std::move(d));
    }
    return found(finish(std::move(raw), image_bgr.size(), config_.nms_iou, camera, capture_time_ns));
  }

 private:
  HogConfig config_;
  cv::HOGDescriptor hog_;  // the default: 64 x 128 windows, the detector trained for them
};

class CascadeDetector final : public Detector {
 public:
  CascadeDetector(CascadeConfig config, cv::CascadeClassifier cascade) : config_(std::move(config)), cascade_(std::move(cascade)) {}

  DetectResult detectFrame(const cv::Mat& image_bgr, const std::string& camera, std::int64_t capture_time_ns) override {
    if (Status s = checkImage(image_bgr); !s) return refuse(DetectFailure::kBadImage, s.error());
    cv::Mat gray;
    std::vector<cv::Rect> objects;
    std::vector<int> neighbours;
    try {
      cv::cvtColor(image_bgr, gray, cv::COLOR_BGR2GRAY);
      // Cascades were trained on equalised grey images; without it they miss dim or washed-out objects.
      cv::equalizeHist(gray, gray);
      cascade_.detectMultiScale(gray, objects, neighbours, config_.scale_factor, config_.min_neighbors, 0,
                                cv::Size(config_.min_size_px, config_.min_size_px));
    } catch (const cv::Exception& e) {
      return refuse(DetectFailure::kOpenCvFailed,
                    Error{ErrorCode::kInternal, std::string("cascade: OpenCV failed: ") + e.what()});
    }
    std::vector<Detection> raw;
    raw.reserve(objects.size());
    for (std::size_t i = 0; i < objects.size(); ++i) {
      Detection d;
      d.box = boxOf(objects[i], 1.0);
      d.label = config_.label;
      d.score = i < neighbours.size() ? neighbours[i] : 0.0;
      raw.push_back(std::move(d));
    }
    return found(finish(std::move(raw), image_bgr.size(), config_.nms_iou, camera, capture_time_ns));
  }

 private:
  CascadeConfig config_;
  cv::CascadeClassifier cascade_;
};

std::string shapeOf(const cv::Mat& m) {
  std::string s = "[";
  for (int i = 0; i < m.dims; ++i) s += (i ? ", " : "") + std::to_string(m.size[i]);
  return s + "]";
}

class DnnDetector final : public Detector {
 public:
  DnnDetector(DnnConfig config, cv::dnn::Net net, std::vector<std::string> names)
      : config_(std::move(config)), net_(std::move(net)), names_(std::move(names)), outputs_(net_.getUnconnectedOutLayersNames()) {}

  DetectResult detectFrame(const cv::Mat& image_bgr, const std::string& camera, std::int64_t capture_time_ns) override {
    if (Status s = checkImage(image_bgr); !s) return refuse(DetectFailure::kBadImage, s.error());
    std::vector<cv::Mat> outs;
    try {
      const cv::Mat blob = cv::dnn::blobFromImage(image_bgr, config_.scale, cv::Size(config_.input_width, config_.input_height),
                                                  cv::Scalar(config_.mean[0], config_.mean[1], config_.mean[2]),
                                                  config_.swap_rb, false, CV_32F);
      net_.setInput(blob);
      net_.forward(outs, outputs_);
    } catch (const cv::Exception& e) {
      // Mostly a config that does not fit the model (input size, channels).
      return refuse(DetectFailure::kModelFailed,
                    invalidArgument(std::string("dnn: OpenCV failed to run the network on a ") + std::to_string(image_bgr.cols) +
                                    " x " + std::to_string(image_bgr.rows) + " image: " + e.what()));
    }
    std::vector<Detection> raw;
    for (std::size_t i = 0; i < outs.size(); ++i) {
      const std::string name = i < outputs_.size() ? outputs_[i] : std::to_string(i);
      if (outs[i].depth() != CV_32F || !outs[i].isContinuous()) {
        return refuse(DetectFailure::kModelOutputMismatch,
                      invalidArgument("dnn: output '" + name + "' is not a contiguous float32 tensor"));
      }
      Expected<std::vector<Detection>> parsed = config_.output == DnnOutput::kSsd ? parseSsd(outs[i], name, image_bgr.size())
                                                                                   : parseYolo(outs[i], name, image_bgr.size());
      if (!parsed) return refuse(DetectFailure::kModelOutputMismatch, parsed.error());
      raw.insert(raw.end(), std::make_move_iterator(parsed->begin()), std::make_move_iterator(parsed->end()));
    }
    return found(finish(std::move(raw), image_bgr.size(), config_.nms_threshold, camera, capture_time_ns));
  }

 private:
  Expected<std::string> className(int id) const {
    if (id < 0 || static_cast<std::size_t>(id) >= names_.size()) {
      return invalidArgument("dnn: the network reports class id " + std::to_string(id) + " but " + config_.names_path + " names " +
                             std::to_string(names_.size()) + " class(es)");
    }
    return names_[static_cast<std::size_t>(id)];
  }

  // The detections of one output above the confidence threshold, in the image's pixels.
  Expected<std::vector<Detection>> parseSsd(const cv::Mat& out, const std::string& name, const cv::Size& image) const {
    if (out.dims != 4 || out.size[0] != 1 || out.size[1] != 1 || out.size[3] != 7) {
      return invalidArgument("dnn: output '" + name + "' has shape " + shapeOf(out) + "; output " + dnnOutputName(config_.output) +
                             " expects [1, 1, N, 7]");
    }
    std::vector<Detection> raw;
    const float* row = out.ptr<float>();
    for (int i = 0; i < out.size[2]; ++i, row += 7) {
      // DetectionOutput pads with image_id -1 when it found nothing.
      if (row[0] < 0.0f || row[2] < config_.confidence_threshold) continue;
      Expected<std::string> label = className(static_cast<int>(std::lround(row[1])));
      if (!label) return label.error();
      Detection d;
      d.box = {row[3] * image.width, row[4] * image.height, row[5] * image.width, row[6] * image.height};
      d.label = std::move(*label);
      d.score = row[2];
      raw.push_back(std::move(d));
    }
    return raw;
  }

  Expected<std::vector<Detection>> parseYolo(const cv::Mat& out, const std::string& name, const cv::Size& image) const {
    int rows = 0, cols = 0;
    if (out.dims == 2) {
      rows = out.size[0];
      cols = out.size[1];
    } else if (out.dims == 3 && out.size[0] == 1) {
      rows = out.size[1];
      cols = out.size[2];
    }
    if (cols < 6) {
      return invalidArgument("dnn: output '" + name + "' has shape " + shapeOf(out) + "; output " + dnnOutputName(config_.output) +
                             " expects [N, 5 + classes] or [1, N, 5 + classes]");
    }
    const bool pixels = config_.output == DnnOutput::kYoloExport;
    const double sx = pixels ? static_cast<double>(image.width) / config_.input_width : image.width;
    const double sy = pixels ? static_cast<double>(image.height) / config_.input_height : image.height;
    std::vector<Detection> raw;
    const float* row = out.ptr<float>();
    for (int i = 0; i < rows; ++i, row += cols) {
      const float* classes = row + 5;
      const int best = static_cast<int>(std::max_element(classes, row + cols) - classes);
      const double score = pixels ? static_cast<double>(row[4]) * classes[best] : classes[best];
      if (score < config_.confidence_threshold) continue;
      Expected<std::string> label = className(best);
      if (!label) return label.error();
      const double cx = row[0] * sx, cy = row[1] * sy, w = row[2] * sx, h = row[3] * sy;
      Detection d;
      d.box = {cx - w / 2.0, cy - h / 2.0, cx + w / 2.0, cy + h / 2.0};
      d.label = std::move(*label);
      d.score = score;
      raw.push_back(std::move(d));
    }
    return raw;
  }

  DnnConfig config_;
  cv::dnn::Net net_;
  std::vector<std::string> names_;
  std::vector<std::string> outputs_;  // every unconnected output: Darknet YOLOs have one per scale
};

Expected<std::unique_ptr<Detector>> makeCascade(const CascadeConfig& config) {
  cv::CascadeClassifier cascade;
  bool loaded = false;
  try {
    loaded = cascade.load(config.cascade_path);
  } catch (const cv::Exception& e) {
    return badField("cascade.cascade_path", config.cascade_path + " is not a cascade OpenCV can read: " + e.what());
  }
  if (!loaded || cascade.empty()) {
    return badField("cascade.cascade_path", config.cascade_path + " is not a cascade OpenCV can read");
  }
  return std::unique_ptr<Detector>(std::make_unique<CascadeDetector>(config, std::move(cascade)));
}

Expected<std::unique_ptr<Detector>> makeDnn(const DnnConfig& config) {
  Expected<std::vector<std::string>> names = readClassNames(config.names_path);
  if (!names) return badField("dnn.names_path", names.error().message);
  cv::dnn::Net net;
  try {
    net = cv::dnn::readNet(config.model_path, config.config_path);
  } catch (const cv::Exception& e) {
    return badField("dnn.model_path", "OpenCV cannot read " + config.model_path +
                                          (config.config_path.empty() ? "" : " with " + config.config_path) +
                                          " as a network: " + e.what());
  }
  if (net.empty()) return badField("dnn.model_path", "OpenCV read no layers from " + config.model_path);
  return std::unique_ptr<Detector>(std::make_unique<DnnDetector>(config, std::move(net), std::move(*names)));
}

}  // namespace

const char* detectFailureName(DetectFailure failure) {
  switch (failure) {
    case DetectFailure::kBadImage: return "bad_image";
    case DetectFailure::kTooLarge: return "too_large";
    case DetectFailure::kModelFailed: return "model_failed";
    case DetectFailure::kModelOutputMismatch: return "model_output_mismatch";
    case DetectFailure::kOpenCvFailed: return "opencv_failed";
  }
  return "unknown";
}

Expected<std::vector<Detection>> Detector::detect(const cv::Mat& image_bgr, const std::string& camera,
                                                  std::int64_t capture_time_ns) {
  DetectResult result = detectFrame(image_bgr, camera, capture_time_ns);
  if (result.refusal) return std::move(result.refusal->error);
  return std::move(result.detections);
}

Expected<std::unique_ptr<Detector>> makeDetector(const DetectorConfig& config) {
  if (Status s = validate(config); !s) return s.error();
  switch (config.kind) {
    case DetectorKind::kHog: return std::unique_ptr<Detector>(std::make_unique<HogDetector>(config.hog));
    case DetectorKind::kCascade: return makeCascade(config.cascade);
    case DetectorKind::kDnn: return makeDnn(config.dnn);
  }
  return Error{ErrorCode::kInternal, "makeDetector: unhandled kind"};
}

std::vector<Detection> nonMaximumSuppression(std::vector<Detection> detections, double iou_threshold) {
  std::stable_sort(detections.begin(), detections.end(),
                   [](const Detection& a, const Detection& b) { return a.score > b.score; });
  std::vector<Detection> kept;
  for (Detection& d : detections) {
    const bool suppressed = std::any_of(kept.begin(), kept.end(), [&](const Detection& k) {
      return k.label == d.label && iou(k.box, d.box) > iou_threshold;
    });
    if (!suppressed) kept.push_back(std::move(d));
  }
  return kept;
}

Expected<std::vector<std::string>> readClassNames(const std::string& path) {
  std::ifstream in(path);
  if (!in) return notFound("no such file: " + path);
  std::vector<std::string> names;
  std::string line;
  int line_no = 0;
  int first_blank = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto end = line.find_last_not_of(" \t\r");
    line.erase(end == std::string::npos ? 0 : end + 1);
    if (line.empty()) {
      if (first_blank == 0) first_blank = line_no;
      continue;
    }
    // A blank line between names would silently shift every later class id.
    if (first_blank != 0) return invalidArgument(path + ": line " + std::to_string(first_blank) + " is blank between class names");
    names.push_back(line);
  }
  if (names.empty()) return invalidArgument(path + ": names no class (one name a line)");
  return names;
}

}  // namespace fogmap::camera
