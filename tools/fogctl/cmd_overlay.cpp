// fogctl overlay: a camera frame with LiDAR points, labelled 3D boxes and detections drawn over it
// (tools/fogctl/camera_overlay.hpp), to check a calibration and a detector by eye.
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "common/camera/detector.hpp"
#include "common/cloud_io.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/camera_overlay.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

Expected<std::string> readText(const std::string& path) {
  std::ifstream in(path);
  if (!in) return notFound("cannot open " + path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

int runOverlay(int argc, char** argv) {
  const std::string who = "fogctl overlay";
  const auto args = Args::parse(argc, argv, 2, {"image", "calib", "labels", "scan", "hog-upscale", "out"}, {"hog"});
  if (!args) return fail(args.error(), who);
  for (const char* flag : {"image", "calib", "out"}) {
    if (!args->has(flag)) {
      return fail(invalidArgument(std::string("--") + flag + " is required (fogctl overlay --help)"), who);
    }
  }
  const auto calib_text = readText(args->get("calib"));
  if (!calib_text) return fail(calib_text.error(), who);
  const auto calibration = camera::parseKittiCalibration(*calib_text);
  if (!calibration) return fail(Error{calibration.error().code, args->get("calib") + ": " + calibration.error().message}, who);
  std::vector<camera::KittiLabel> labels;
  if (args->has("labels")) {
    const auto text = readText(args->get("labels"));
    if (!text) return fail(text.error(), who);
    auto parsed = camera::parseKittiLabels(*text);
    if (!parsed) return fail(Error{parsed.error().code, args->get("labels") + ": " + parsed.error().message}, who);
    labels = std::move(*parsed);
  }
  Cloud points;
  if (args->has("scan")) {
    auto loaded = readCloud(args->get("scan"));
    if (!loaded) return fail(loaded.error(), who);
    points = std::move(loaded->points);
  }
  std::vector<camera::Detection> detections;
  if (args->has("hog")) {
    camera::DetectorConfig config;
    const auto upscale = args->getDouble("hog-upscale", 1.5);
    if (!upscale) return fail(upscale.error(), who);
    config.hog.upscale = *upscale;
    auto detector = camera::makeDetector(config);
    if (!detector) return fail(detector.error(), who);
    const cv::Mat frame = cv::imread(args->get("image"), cv::IMREAD_COLOR);
    if (frame.empty()) return fail(ioError("cannot read the image " + args->get("image")), who);
    auto found = (*detector)->detect(frame, "camera", 0);
    if (!found) return fail(found.error(), who);
    detections = std::move(*found);
  }
  const auto counts = writeCameraOverlay(args->get("image"), *calibration, points, labels, detections, args->get("out"));
  if (!counts) return fail(counts.error(), who);
  std::printf("wrote %s: %zu LiDAR points, %zu labelled boxes, %zu detections\n", args->get("out").c_str(), counts->points_drawn,
              counts->boxes_drawn, counts->detections_drawn);
  return 0;
}

}  // namespace fogmap::cli
