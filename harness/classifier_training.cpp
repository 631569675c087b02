#include "harness/classifier_training.hpp"

#include <algorithm>
#include <array>
#include <fstream>
#include <map>
#include <sstream>
#include <unordered_map>

#include "common/classify/cluster_views.hpp"
#include "common/io/cloud_io.hpp"
#include "common/perception/box_fitting.hpp"
#include "common/perception/lidar_models.hpp"
#include "common/perception/object_features.hpp"
#include "common/perception/preprocess.hpp"
#include "common/perception/sensor_clustering.hpp"
#include "common/sim/generators.hpp"
#include "common/sim/raycaster.hpp"
#include "common/sim/truth.hpp"

namespace fogmap::harness {

ObjectClass classOfSceneLabel(std::string_view label) {
  if (label == "person" || label == "pedestrian") return ObjectClass::kPerson;
  if (label == "car") return ObjectClass::kCar;
  if (label == "pole" || label == "post") return ObjectClass::kPole;
  if (label == "truck" || label == "bus" || label == "van") return ObjectClass::kTruckOrBus;
  if (label == "cyclist" || label == "bicycle") return ObjectClass::kCyclist;
  return ObjectClass::kOther;
}

std::string lidarModelOfSeed(std::uint64_t seed) {
  static const std::array<std::string, 3> models = {"VLP-16", "HDL-32E", "HDL-64E"};
  return models[seed % models.size()];
}

Expected<SampleSet> simulatedSamples(std::span<const std::uint64_t> seeds, const SimSampleOptions& options) {
  SampleSet out;
  for (const std::uint64_t seed : seeds) {
    sim::Scene scene = sim::randomScene(options.objects, options.lidars, seed);
    const std::string model_name = lidarModelOfSeed(seed);
    const auto model = lidarModel(model_name);
    if (!model) return model.error();
    for (auto& lidar : scene.lidars) lidar.model = model_name;
    std::unordered_map<std::uint32_t, ObjectClass> class_of;
    for (const auto& object : scene.objects) class_of[object.id] = classOfSceneLabel(object.label);

    const auto raycaster = sim::SceneRaycaster::build(scene, 0.0);
    if (!raycaster) return raycaster.error();
    for (const auto& lidar : scene.lidars) {
      const auto frame = raycaster->scan(lidar, seed, 0, 1);
      if (!frame) return frame.error();
      // In the sensor frame, as the LiDAR gives its points: the ground lies the mount's height
      // below it (the paper's spots are level).
      GroundParams ground_params;
      ground_params.ground_z_hint_m = -frame->sensor_pose.translation().z();
      const auto ground = removeGround(frame->points, ground_params);
      if (!ground) return ground.error();
      const Cloud& points = ground->non_ground;
      const auto truth = sim::truthOfPoints(points, frame->points, frame->truth, 1e-3);

      SensorClusteringParams params;
      params.clustering.min_points = options.min_points;
      params.links.beams = beamTableOf(*model);
      const auto clustering = sensorAwareClusters(points, params);
      if (!clustering) return clustering.error();

      std::vector<Cloud> clusters(static_cast<std::size_t>(clustering->cluster_count));
      std::vector<std::map<std::int64_t, std::size_t>> votes(clusters.size());
      for (std::size_t i = 0; i < points.size(); ++i) {
        const auto label = clustering->labels[i];
        if (label < 0) continue;
        clusters[static_cast<std::size_t>(label)].push_back(points[i]);
        ++votes[static_cast<std::size_t>(label)][truth[i]];
      }
      const Eigen::Vector3d sensor = Eigen::Vector3d::Zero();
      for (std::size_t c = 0; c < clusters.size(); ++c) {
        ++out.clusters;
        const auto top = std::max_element(votes[c].begin(), votes[c].end(),
                                          [](const auto& a, const auto& b) { return a.second < b.second; });
        const auto known = class_of.find(static_cast<std::uint32_t>(std::max<std::int64_t>(top->first, 0)));
        if (top->first <= 0 || known == class_of.end() ||
            static_cast<double>(top->second) < options.min_majority * static_cast<double>(clusters[c].size())) {
          ++out.unlabelled;
          continue;
        }
        const auto box = fitOrientedBox(clusters[c], sensor);
        if (!box) return box.error();
        out.samples.push_back({objectFeatures(clusters[c], *box, sensor), known->second});
      }
    }
  }
  return out;
}

std::optional<ObjectClass> classOfKittiType(std::string_view type) {
  if (type == "Car") return ObjectClass::kCar;
  if (type == "Van" || type == "Truck") return ObjectClass::kTruckOrBus;
  if (type == "Pedestrian" || type == "Person_sitting") return ObjectClass::kPerson;
  if (type == "Cyclist") return ObjectClass::kCyclist;
  return std::nullopt;
}

namespace {

Expected<std::string> readText(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) return notFound(file.string() + ": cannot read");
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

Expected<std::vector<KittiObject>> kittiObjects(const std::filesystem::path& dir, const ObjectClassifier* classifier,
                                                std::size_t min_points) {
  namespace fs = std::filesystem;
  std::error_code ec;
  std::vector<fs::path> scans;
  for (const auto& entry : fs::directory_iterator(dir / "velodyne", ec)) {
    if (entry.path().extension() == ".bin") scans.push_back(entry.path());
  }
  if (ec) return notFound((dir / "velodyne").string() + ": " + ec.message());
  std::sort(scans.begin(), scans.end());
  const auto model = lidarModel("HDL-64E");
  if (!model) return model.error();
  std::vector<KittiObject> out;
  for (const auto& scan_file : scans) {
    const std::string id = scan_file.stem().string();
    const fs::path calib_file = dir / "calib" / (id + ".txt");
    const fs::path label_file = dir / "label_2" / (id + ".txt");
    if (!fs::exists(calib_file) || !fs::exists(label_file)) continue;
    const auto scan = readKittiBin(scan_file);
    if (!scan) return scan.error();
    const auto calib_text = readText(calib_file);
    if (!calib_text) return calib_text.error();
    const auto calibration = camera::parseKittiCalibration(*calib_text);
    if (!calibration) return Error{calibration.error().code, calib_file.string() + ": " + calibration.error().message};
    const auto label_text = readText(label_file);
    if (!label_text) return label_text.error();
    const auto labels = camera::parseKittiLabels(*label_text);
    if (!labels) return Error{labels.error().code, label_file.string() + ": " + labels.error().message};

    const auto ground = removeGround(scan->points, GroundParams{});
    if (!ground) return ground.error();
    const Cloud& points = ground->non_ground;
    SensorClusteringParams params;
    params.links.beams = beamTableOf(*model);
    const auto clustering = sensorAwareClusters(points, params);
    if (!clustering) return clustering.error();
    const auto found = sensorObjects(points, *clustering, Eigen::Vector3d::Zero(), classifier);
    if (!found) return found.error();

    for (const auto& label : *labels) {
      const auto truth = classOfKittiType(label.type);
      if (!truth) continue;
      KittiObject object;
      object.label_box = camera::labelBoxInVelodyne(label, *calibration);
      std::map<std::int32_t, std::size_t> votes;
      for (std::size_t i = 0; i < points.size(); ++i) {
        if (object.label_box.contains(points[i].xyz().cast<double>())) {
          ++object.points_in_box;
          ++votes[found->clustering.labels[i]];
        }
      }
      if (object.points_in_box < min_points) continue;
      object.frame = id;
      object.type = label.type;
      object.truth = *truth;
      object.range_m = object.label_box.centre.head<2>().norm();
      const auto top = std::max_element(votes.begin(), votes.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
      object.clusters = votes.size() - votes.count(-1);
      if (top->first >= 0) object.found = found->views[static_cast<std::size_t>(top->first)];
      out.push_back(std::move(object));
    }
  }
  return out;
}

}  // namespace fogmap::harness
