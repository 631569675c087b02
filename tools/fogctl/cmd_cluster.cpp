// fogctl cluster: the core pipeline on one scan: its clusters, and a label per point.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/classify/cluster_views.hpp"
#include "common/io/cloud_io.hpp"
#include "common/perception/clustering.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using Clock = std::chrono::steady_clock;

// One JSON object per cluster: its id (the label), class and confidence (with a classifier),
// points, and oriented box fitted in the scan's frame with the sensor at its origin.
Expected<nlohmann::ordered_json> objectsJson(const Cloud& cloud, const Clustering& clustering, const ObjectClassifier* classifier) {
  const auto views = clusterViews(cloud, clustering, Eigen::Vector3d::Zero(), classifier);
  if (!views) return views.error();
  auto objects = nlohmann::ordered_json::array();
  for (std::size_t id = 0; id < views->size(); ++id) {
    if (!(*views)[id]) continue;  // a label no point has
    const ClusterView& view = *(*views)[id];
    const OrientedBox& box = view.box;
    nlohmann::ordered_json object = {{"id", id}};
    if (view.label) {
      object["class"] = std::string(objectClassName(view.label->object_class));
      object["confidence"] = view.label->confidence;
    }
    object.update(nlohmann::ordered_json{{"points", view.points},
                       {"box",
                        {{"x", box.centre.x()},
                         {"y", box.centre.y()},
                         {"z", box.centre.z()},
                         {"yaw", box.yaw},
                         {"length", box.length},
                         {"width", box.width},
                         {"height", box.height}}},
                       {"nearest", std::string(boxAnchorName(box.anchor))}});
    objects.push_back(std::move(object));
  }
  return objects;
}

int runCluster(int argc, char** argv) {
  const auto args =
      Args::parse(argc, argv, 2,
                  {"input", "eps", "min-points", "labels", "objects", "classifier", "method", "threads", "max-scan-bytes"},
                  {"remove-ground"});
  if (!args) return fail(args.error());
  const auto params = clusteringParams(*args);
  if (!params) return fail(params.error());
  const std::string method_name = args->get("method", "fogmap");
  ClusteringMethod method = ClusteringMethod::kFogmap;
  if (method_name == "pcl") {
    method = ClusteringMethod::kPcl;
  } else if (method_name != "fogmap") {
    return fail(invalidArgument("--method must be fogmap or pcl, got '" + method_name + "'"));
  }
  const auto cloud = loadScan(*args, true);
  if (!cloud) return fail(cloud.error());
  const auto start = Clock::now();
  const Clustering clustering = clusterPoints(*cloud, *params, method);
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  if (args->has("labels")) {
    std::ofstream out(args->get("labels"));
    if (!out) return fail(ioError("cannot write labels to " + args->get("labels")));
    for (const auto l : clustering.labels) out << l << '\n';
    if (!out) return fail(ioError("writing labels to " + args->get("labels") + " failed"));
  }
  if (args->has("objects")) {
    const auto classifier = classifierFlag(*args);
    if (!classifier) return fail(classifier.error());
    const auto objects = objectsJson(*cloud, clustering, classifier->get());
    if (!objects) return fail(objects.error());
    std::ofstream out(args->get("objects"));
    if (!out) return fail(ioError("cannot write objects to " + args->get("objects")));
    out << objects->dump(2) << '\n';
    if (!out) return fail(ioError("writing objects to " + args->get("objects") + " failed"));
  }
  std::printf("%zu points, %d clusters, %.2f ms (%s)\n", cloud->size(), clustering.cluster_count, ms, method_name.c_str());
  return 0;
}

}  // namespace

Command clusterCommand() {
  return {"cluster",
          "--input SCAN [--eps 0.35] [--min-points 10] [--labels OUT.txt] [--objects OUT.json] [--method fogmap|pcl] "
          "[--remove-ground] [--threads N]",
          "usage: fogctl cluster --input SCAN [--eps 0.35] [--min-points 10] [--labels OUT.txt] [--objects OUT.json]\n"
          "                      [--classifier FILE] [--method fogmap|pcl] [--remove-ground] [--threads N] [--max-scan-bytes N]\n"
          "Clusters one scan (KITTI .bin, nuScenes .pcd.bin, PCD) and prints the number of clusters.\n"
          "  --eps M              clustering radius in metres, 0.001 to 100 (default 0.35)\n"
          "  --min-points N       smallest cluster, in points (default 10)\n"
          "  --labels FILE        one label per point of the file, in its order: the cluster, -1 for noise\n"
          "                       (non-finite points are noise); with --remove-ground, per non-ground point\n"
          "  --objects FILE       a JSON array, one object per cluster: {\"id\", \"class\", \"confidence\", \"points\",\n"
          "                       \"box\": {\"x\", \"y\", \"z\", \"yaw\", \"length\", \"width\", \"height\"}, \"nearest\"}: the\n"
          "                       LiDAR-only class, the oriented box fitted by L-shape (metres, radians; yaw of the\n"
          "                       length axis in [-pi/2, pi/2)) in the scan's frame, and the face or corner nearest\n"
          "                       the sensor (at the frame's origin)\n"
          "  --classifier FILE    the model for the classes (default " + std::string(kDefaultClassifierModel) + " when it\n"
          "                       exists, else no class; fogctl train-classifier makes it)\n"
          "  --method fogmap|pcl  fogmap's grid clustering or PCL's, the reference (default fogmap)\n"
          "  --remove-ground      remove the ground before clustering\n"
          "  --threads N          threads for the neighbour search (default: one per core)\n"
          "  --max-scan-bytes N   refuse larger files unread (default " + std::to_string(fogmap::kDefaultMaxScanBytes) + ")\n",
          runCluster};
}

}  // namespace fogmap::cli
