// fogctl overlay: a camera frame with LiDAR points, labelled 3D boxes and detections drawn over it
// (pictures/camera_overlay.hpp), to check a calibration and a detector by eye.
#include <cstdio>
#include <fstream>
#include <span>
#include <sstream>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "common/camera/detector.hpp"
#include "common/classify/object_classifier.hpp"
#include "common/config/topology.hpp"
#include "common/config/topology_presets.hpp"
#include "common/io/cloud_io.hpp"
#include "pictures/camera_overlay.hpp"
#include "services/edge_cluster/edge_node.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using pictures::OverlayLayers;
using pictures::writeCameraOverlay;

Expected<std::string> readText(const std::string& path) {
  std::ifstream in(path);
  if (!in) return notFound("cannot open " + path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The map an edge makes of the scan with the ready-made KITTI topology's settings (crop, ground
// 1.73 m below the sensor, MAD-C eps 0.35 m, 10 points, alpha 1.5), in the scan's frame: each
// cluster's oriented box, fitted from the sensor at the origin, and with a classifier its class.
Expected<std::vector<MapObject>> edgeMapOf(const Cloud& scan, std::shared_ptr<const ObjectClassifier> classifier) {
  const TopologyConfig kitti = makeStarTopology(1, "scan", 1);
  EdgeConfig config;
  config.node = 1;
  config.mode = Mode::kMadc;
  config.madc = kitti.madc;
  config.preprocess = kitti.preprocess;
  config.boxes = true;
  config.classifier = std::move(classifier);
  EdgeNode edge(config);
  auto output = edge.processFrame(scan, 0, 0);
  if (!output) return output.error();
  if (!output->map) return std::vector<MapObject>{};
  return output->map->map.objects;
}

int runOverlay(int argc, char** argv) {
  const std::string who = "fogctl overlay";
  const auto args = Args::parse(argc, argv, 2, {"image", "calib", "labels", "scan", "hog-upscale", "classifier", "out"}, {"hog", "objects"});
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
  std::vector<MapObject> objects;
  if (args->has("objects")) {
    if (!args->has("scan")) return fail(invalidArgument("--objects draws the map of the --scan: give --scan too"), who);
    auto classifier = classifierFlag(*args);
    if (!classifier) return fail(classifier.error(), who);
    auto map = edgeMapOf(points, std::move(*classifier));
    if (!map) return fail(Error{map.error().code, args->get("scan") + ": " + map.error().message}, who);
    objects = std::move(*map);
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
  // The points are drawn when asked for alone; with --objects the map is the point of the picture.
  OverlayLayers layers{.lidar_points = args->has("objects") ? std::span<const Point>() : std::span<const Point>(points),
                       .labels = labels,
                       .detections = detections,
                       .objects = objects};
  const auto counts = writeCameraOverlay(args->get("image"), *calibration, layers, args->get("out"));
  if (!counts) return fail(counts.error(), who);
  std::printf("wrote %s: %zu LiDAR points, %zu labelled boxes, %zu detections, %zu map objects\n", args->get("out").c_str(),
              counts->points_drawn, counts->boxes_drawn, counts->detections_drawn, counts->objects_drawn);
  return 0;
}

}  // namespace

Command overlayCommand() {
  return {"overlay",
          "--image IMG --calib CALIB --out PNG [--labels FILE] [--scan FILE [--objects]] [--hog]   draw on a camera frame",
          "usage: fogctl overlay --image IMG --calib CALIB --out PNG [--labels FILE] [--scan FILE [--objects [--classifier FILE]]]\n"
          "                      [--hog [--hog-upscale 1.5]]\n"
          "Draws over a camera frame (KITTI camera 2) what fogmap knows: a LiDAR scan's points projected into\n"
          "the image (coloured by depth), the 3D boxes of a label_2 file as wireframes, and with --hog the\n"
          "people OpenCV's HOG detector finds; writes PNG. For checking a calibration and a detector by eye.\n"
          "  --calib FILE   KITTI calibration (P2, R0_rect, Tr_velo_to_cam)\n"
          "  --labels FILE  KITTI label_2 objects; --scan FILE  a Velodyne scan (.bin, .pcd)\n"
          "  --objects      instead of the scan's points, the map an edge makes of it (the ready-made KITTI\n"
          "                 topology's crop, ground and MAD-C): each object's oriented 3D box as a wireframe in\n"
          "                 its LiDAR class's colour, with the class and confidence\n"
          "  --classifier FILE  the LiDAR classifier (default: the bundled data/models/lidar_classifier.yml.gz\n"
          "                 when it is there; without one the boxes have no class)\n",
          runOverlay};
}

}  // namespace fogmap::cli
