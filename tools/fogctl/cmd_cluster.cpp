// fogctl cluster: the core pipeline on one scan: its clusters, and a label per point.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/classify/cluster_views.hpp"
#include "common/io/cloud_io.hpp"
#include "common/perception/box_fitting.hpp"
#include "common/perception/clustering.hpp"
#include "common/perception/lidar_models.hpp"
#include "common/perception/sensor_clustering.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using Clock = std::chrono::steady_clock;

nlohmann::ordered_json boxJson(const OrientedBox& box) {
  return {{"x", box.centre.x()},  {"y", box.centre.y()},   {"z", box.centre.z()},      {"yaw", box.yaw},
          {"length", box.length}, {"width", box.width}, {"height", box.height}};
}

// One JSON object per object: its id (the label), class and confidence (with a classifier),
// points, and oriented box fitted in the scan's frame with the sensor at its origin.
nlohmann::ordered_json objectsJson(const SensorObjects& found) {
  auto objects = nlohmann::ordered_json::array();
  for (std::size_t id = 0; id < found.views.size(); ++id) {
    if (!found.views[id]) continue;  // a label no point has
    const ClusterView& view = *found.views[id];
    const OrientedBox& box = view.box;
    nlohmann::ordered_json object = {{"id", id}};
    if (view.label) {
      object["class"] = std::string(objectClassName(view.label->object_class));
      object["confidence"] = view.label->confidence;
    }
    object.update(nlohmann::ordered_json{{"points", view.points},
                       {"box", boxJson(box)},
                       {"nearest", std::string(boxAnchorName(box.anchor))}});
    if (const auto prior = vehiclePriorFor(box, view.label)) {
      const OrientedBox whole = grownToPrior(box, Eigen::Vector3d::Zero(), *prior);
      object["vehicle_box"] = boxJson(whole);
    }
    objects.push_back(std::move(object));
  }
  return objects;
}

// The clusters of the scan: the exact mode (fogmap's grid or PCL's), or with --lidar the
// sensor-aware mode with that model's beam table, the sensor at the scan's origin.
Expected<Clustering> clustersOf(const Cloud& cloud, const ClusteringParams& params, const std::string& method,
                                const std::string& lidar) {
  if (!lidar.empty()) {
    const auto model = lidarModel(lidar);
    if (!model) return invalidArgument("--lidar: " + model.error().message);
    SensorClusteringParams sensor;
    sensor.clustering = params;
    sensor.links.beams = beamTableOf(*model);
    return sensorAwareClusters(cloud, sensor);
  }
  if (method == "pcl") return clusterPoints(cloud, params, ClusteringMethod::kPcl);
  return clusterPoints(cloud, params, ClusteringMethod::kFogmap);
}

int runCluster(int argc, char** argv) {
  const auto args =
      Args::parse(argc, argv, 2,
                  {"input", "eps", "min-points", "labels", "objects", "classifier", "method", "lidar", "threads", "max-scan-bytes"},
                  {"remove-ground"});
  if (!args) return fail(args.error());
  const auto params = clusteringParams(*args);
  if (!params) return fail(params.error());
  const std::string method_name = args->get("method", "fogmap");
  if (method_name != "fogmap" && method_name != "pcl") {
    return fail(invalidArgument("--method must be fogmap or pcl, got '" + method_name + "'"));
  }
  const std::string lidar = args->get("lidar", "");
  if (!lidar.empty() && args->has("method")) return fail(invalidArgument("--lidar and --method exclude each other"));
  const auto cloud = loadScan(*args, true);
  if (!cloud) return fail(cloud.error());
  const auto start = Clock::now();
  auto clustering = clustersOf(*cloud, *params, method_name, lidar);
  if (!clustering) return fail(clustering.error());
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  std::optional<SensorObjects> found;
  if (args->has("objects")) {
    const auto classifier = classifierFlag(*args);
    if (!classifier) return fail(classifier.error());
    auto objects = sensorObjects(*cloud, *clustering, Eigen::Vector3d::Zero(), classifier->get(), params->min_points);
    if (!objects) return fail(objects.error());
    found = std::move(*objects);
  }
  if (args->has("labels")) {
    std::ofstream out(args->get("labels"));
    if (!out) return fail(ioError("cannot write labels to " + args->get("labels")));
    for (const auto l : (found ? found->clustering : *clustering).labels) out << l << '\n';
    if (!out) return fail(ioError("writing labels to " + args->get("labels") + " failed"));
  }
  if (found) {
    std::ofstream out(args->get("objects"));
    if (!out) return fail(ioError("cannot write objects to " + args->get("objects")));
    out << objectsJson(*found).dump(2) << '\n';
    if (!out) return fail(ioError("writing objects to " + args->get("objects") + " failed"));
  }
  const std::string mode = lidar.empty() ? method_name : "sensor-aware, " + lidar;
  if (found) {
    std::printf("%zu points, %d clusters, %.2f ms (%s); %d objects (%zu vehicle parts joined)\n", cloud->size(),
                clustering->cluster_count, ms, mode.c_str(), found->clustering.cluster_count, found->parts_joined);
    return 0;
  }
  std::printf("%zu points, %d clusters, %.2f ms (%s)\n", cloud->size(), clustering->cluster_count, ms, mode.c_str());
  return 0;
}

}  // namespace

Command clusterCommand() {
  return {"cluster",
          "--input SCAN [--eps 0.35] [--min-points 10] [--labels OUT.txt] [--objects OUT.json] [--method fogmap|pcl | --lidar MODEL] "
          "[--remove-ground] [--threads N]",
          "usage: fogctl cluster --input SCAN [--eps 0.35] [--min-points 10] [--labels OUT.txt] [--objects OUT.json]\n"
          "                      [--classifier FILE] [--method fogmap|pcl | --lidar MODEL] [--remove-ground] [--threads N]\n"
          "                      [--max-scan-bytes N]\n"
          "Clusters one scan (KITTI .bin, nuScenes .pcd.bin, PCD) and prints the number of clusters.\n"
          "  --eps M              clustering radius in metres, 0.001 to 100 (default 0.35)\n"
          "  --min-points N       smallest cluster, in points (default 10)\n"
          "  --labels FILE        one label per point of the file, in its order: the cluster (with --objects, the\n"
          "                       object), -1 for noise (non-finite points are noise); with --remove-ground, per\n"
          "                       non-ground point\n"
          "  --objects FILE       a JSON array, one object per cluster, as an edge with boxes ships them (a vehicle\n"
          "                       seen in pieces is one object): {\"id\", \"class\", \"confidence\", \"points\",\n"
          "                       \"box\": {\"x\", \"y\", \"z\", \"yaw\", \"length\", \"width\", \"height\"}, \"nearest\"}: the\n"
          "                       LiDAR-only class, the oriented box fitted by L-shape (metres, radians; yaw of the\n"
          "                       length axis in [-pi/2, pi/2)) in the scan's frame, and the face or corner nearest\n"
          "                       the sensor (at the frame's origin); for a vehicle (class car or truck_or_bus, or a\n"
          "                       box of at least 1.5 m) also \"vehicle_box\": the box grown to its class's typical\n"
          "                       size from that face or corner, where the vehicle stands as the tracker places it\n"
          "  --classifier FILE    the model for the classes (default " + std::string(kDefaultClassifierModel) + " when it\n"
          "                       exists, else no class; fogctl train-classifier makes it)\n"
          "  --method fogmap|pcl  the exact mode: fogmap's grid clustering or PCL's, the reference (default fogmap)\n"
          "  --lidar MODEL        the sensor-aware mode, as an edge with clustering: sensor: the exact links plus\n"
          "                       ring links from MODEL's beam table (VLP-16, HDL-32E, HDL-64E: KITTI's, OS1-64),\n"
          "                       the sensor at the scan's origin\n"
          "  --remove-ground      remove the ground before clustering\n"
          "  --threads N          threads for the neighbour search (default: one per core)\n"
          "  --max-scan-bytes N   refuse larger files unread (default " + std::to_string(fogmap::kDefaultMaxScanBytes) + ")\n",
          runCluster};
}

}  // namespace fogmap::cli
