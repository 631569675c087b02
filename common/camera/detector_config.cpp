#include "common/camera/detector_config.hpp"

#include <cmath>
#include <filesystem>
#include <sstream>

namespace fogmap::camera {
namespace {

std::string num(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

Status checkUnitInterval(const std::string& field, double value) {
  if (!(value >= 0.0 && value <= 1.0)) return badField(field, "must be within [0, 1], got " + num(value));
  return {};
}

Status checkFile(const std::string& field, const std::string& path) {
  if (path.empty()) return badField(field, "is required");
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return notFound(field + ": no such file: " + path);
  return {};
}

Status validateHog(const HogConfig& c) {
  if (!std::isfinite(c.hit_threshold)) return badField("hog.hit_threshold", "must be finite");
  if (!(c.scale > 1.0 && c.scale <= 2.0)) return badField("hog.scale", "must be in (1, 2], got " + num(c.scale));
  if (c.win_stride_px < 8 || c.win_stride_px % 8 != 0) {
    return badField("hog.win_stride_px", "must be a positive multiple of 8, got " + std::to_string(c.win_stride_px));
  }
  if (!(c.upscale >= 1.0 && c.upscale <= 8.0)) return badField("hog.upscale", "must be in [1, 8], got " + num(c.upscale));
  if (!(c.min_height_px >= 0.0 && std::isfinite(c.min_height_px))) {
    return badField("hog.min_height_px", "must be a finite number >= 0, got " + num(c.min_height_px));
  }
  return checkUnitInterval("hog.nms_iou", c.nms_iou);
}

Status validateCascade(const CascadeConfig& c) {
  if (Status s = checkFile("cascade.cascade_path", c.cascade_path); !s) return s;
  if (c.label.empty()) return badField("cascade.label", "must not be empty");
  if (!(c.scale_factor > 1.0 && c.scale_factor <= 2.0)) {
    return badField("cascade.scale_factor", "must be in (1, 2], got " + num(c.scale_factor));
  }
  if (c.min_neighbors < 0) return badField("cascade.min_neighbors", "must be >= 0, got " + std::to_string(c.min_neighbors));
  if (c.min_size_px < 0) return badField("cascade.min_size_px", "must be >= 0, got " + std::to_string(c.min_size_px));
  return checkUnitInterval("cascade.nms_iou", c.nms_iou);
}

Status validateDnn(const DnnConfig& c) {
  if (Status s = checkFile("dnn.model_path", c.model_path); !s) return s;
  if (!c.config_path.empty()) {
    if (Status s = checkFile("dnn.config_path", c.config_path); !s) return s;
  }
  if (Status s = checkFile("dnn.names_path", c.names_path); !s) return s;
  const auto checkSide = [](const std::string& field, int px) -> Status {
    if (px < 1 || px > kMaxDnnInputSidePx) {
      return badField(field, "must be in [1, " + std::to_string(kMaxDnnInputSidePx) + "] pixels, got " + std::to_string(px));
    }
    return {};
  };
  if (Status s = checkSide("dnn.input_width", c.input_width); !s) return s;
  if (Status s = checkSide("dnn.input_height", c.input_height); !s) return s;
  const long long pixels = static_cast<long long>(c.input_width) * c.input_height;
  if (pixels > kMaxDnnInputPixels) {
    return badField("dnn.input_width x dnn.input_height",
                    std::to_string(c.input_width) + " x " + std::to_string(c.input_height) + " = " + std::to_string(pixels) +
                        " pixels, above the " + std::to_string(kMaxDnnInputPixels) + " (2048 x 2048) a network input may have");
  }
  for (double m : c.mean) {
    if (!std::isfinite(m)) return badField("dnn.mean", "must be finite");
  }
  if (!(c.scale > 0.0 && std::isfinite(c.scale))) return badField("dnn.scale", "must be a finite number > 0, got " + num(c.scale));
  if (Status s = checkUnitInterval("dnn.confidence_threshold", c.confidence_threshold); !s) return s;
  return checkUnitInterval("dnn.nms_threshold", c.nms_threshold);
}

}  // namespace

Error badField(const std::string& field, const std::string& what) { return invalidArgument(field + ": " + what); }

const char* detectorKindName(DetectorKind kind) {
  switch (kind) {
    case DetectorKind::kHog: return "hog";
    case DetectorKind::kCascade: return "cascade";
    case DetectorKind::kDnn: return "dnn";
  }
  return "unknown";
}

Expected<DetectorKind> parseDetectorKind(const std::string& name) {
  for (DetectorKind kind : {DetectorKind::kHog, DetectorKind::kCascade, DetectorKind::kDnn}) {
    if (name == detectorKindName(kind)) return kind;
  }
  return badField("kind", "unknown detector '" + name + "' (hog, cascade or dnn)");
}

const char* dnnOutputName(DnnOutput output) {
  switch (output) {
    case DnnOutput::kSsd: return "ssd";
    case DnnOutput::kYoloDarknet: return "yolo-darknet";
    case DnnOutput::kYoloExport: return "yolo-export";
  }
  return "unknown";
}

Expected<DnnOutput> parseDnnOutput(const std::string& name) {
  for (DnnOutput output : {DnnOutput::kSsd, DnnOutput::kYoloDarknet, DnnOutput::kYoloExport}) {
    if (name == dnnOutputName(output)) return output;
  }
  return badField("dnn.output", "unknown output layout '" + name + "' (ssd, yolo-darknet or yolo-export)");
}

Status validate(const DetectorConfig& config) {
  switch (config.kind) {
    case DetectorKind::kHog: return validateHog(config.hog);
    case DetectorKind::kCascade: return validateCascade(config.cascade);
    case DetectorKind::kDnn: return validateDnn(config.dnn);
  }
  return badField("kind", "unknown detector kind " + std::to_string(static_cast<int>(config.kind)));
}

}  // namespace fogmap::camera
