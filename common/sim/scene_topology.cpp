#include "common/config/displacement_node.hpp"
#include "common/config/topology_presets.hpp"
#include "common/sim/scene_topology.hpp"

#include <algorithm>
#include <cmath>
#include <set>

namespace fogmap::sim {
namespace {

bool nameChar(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
}

std::string sanitized(const std::string& text) {
  std::string out = text;
  std::replace_if(out.begin(), out.end(), [](char c) { return !nameChar(c); }, '_');
  return out;
}

// The highest point of any object above its ground, in metres (0 without objects).
double tallestObject(const Scene& scene) {
  double tallest = 0.0;
  for (const SceneObject& o : scene.objects) {
    for (const Part& p : o.parts) tallest = std::max(tallest, p.at.z() + p.size.z());
  }
  return tallest;
}

PreprocessConfig preprocessFor(const Scene& scene) {
  PreprocessConfig p;
  const double e = scene.extent_m;
  // The ground's lowest and highest points over the extent (a plane with a step).
  double low = std::min(scene.ground.heightAt(-e), scene.ground.heightAt(e));
  double high = std::max(scene.ground.heightAt(-e), scene.ground.heightAt(e));
  if (scene.ground.step_x_m && std::abs(*scene.ground.step_x_m) <= e) {
    const double below = scene.ground.heightAt(std::nextafter(*scene.ground.step_x_m, -e - 1.0));
    const double above = scene.ground.heightAt(*scene.ground.step_x_m);
    low = std::min({low, below, above});
    high = std::max({high, below, above});
  }
  p.crop = CropBox{{-e, -e, low - 1.0}, {e, e, high + std::max(3.0, tallestObject(scene) + 0.5)}};
  GroundParams ground;
  const double tilt = std::abs(scene.ground.tilt_deg);
  ground.max_tilt_deg = std::max(ground.max_tilt_deg, tilt + 5.0);
  // The hint picks the prior plane's points by height: only right where the ground is level.
  if (tilt == 0.0) ground.ground_z_hint_m = scene.ground.height_m;
  p.ground = ground;
  return p;
}

}  // namespace

std::string edgeNameFor(const std::string& lidar_name) {
  return ("edge-" + sanitized(lidar_name)).substr(0, kMaxNameChars);
}

std::string cameraNodeFor(const std::string& camera_name) {
  return ("cam-" + sanitized(camera_name)).substr(0, kMaxNameChars);
}

TopologyConfig sceneTopology(const Scene& scene, const std::filesystem::path& scene_file,
                             const SceneTopologyOptions& options) {
  const int edges = static_cast<int>(scene.lidars.size());
  TopologyConfig t = options.tree ? makeTreeTopology(edges, kSimSource, options.base_port, options.fanout)
                                  : makeStarTopology(edges, kSimSource, options.base_port);
  // "<scene>-star-3": the scene's name as a node name allows, leaving room for the shape.
  std::string prefix = sanitized(scene.name).substr(0, kMaxNameChars - 16);
  if (prefix.empty()) prefix = "scene";
  if (prefix.front() == '.') prefix.front() = '_';
  t.name = prefix + "-" + t.name;
  t.preprocess = preprocessFor(scene);
  t.objects = options.mapping.objects;

  std::set<std::string> taken;
  for (const NodeConfig& n : t.nodes) {
    if (n.role == Role::kAggregator) taken.insert(n.name);
  }
  for (NodeConfig& n : t.nodes) {
    if (n.role != Role::kEdge || n.id < 1 || n.id > scene.lidars.size()) continue;
    const LidarConfig& lidar = scene.lidars[n.id - 1];
    const std::string base = edgeNameFor(lidar.name);
    std::string name = base;
    // Two LiDAR names that differ only in replaced characters: the id (or the first free number
    // from it) tells the edges apart.
    for (std::size_t k = n.id; taken.count(name) > 0; ++k) {
      std::string suffix = std::to_string(k);
      suffix.insert(suffix.begin(), '-');
      name.assign(base, 0, kMaxNameChars - suffix.size());
      name.append(suffix);
    }
    taken.insert(name);
    n.name = name;
    SensorConfig s;
    s.source = kSimSource;
    s.scene = scene_file;
    s.lidar = lidar.name;
    s.rate_hz = options.rate_hz;
    s.pose = lidar.pose;
    s.clustering = options.mapping.clustering;
    if (s.clustering == ClusteringMode::kSensor) s.model = lidar.model;
    n.sensor = s;
  }
  if (options.tracker) {
    NodeConfig tracker = trackerNode(options.base_port, options.tracking);
    tracker.tracker->input = options.tracker_input;
    if (options.tracker_input == TrackerInput::kCentroids) {
      for (NodeConfig& n : t.nodes) {
        if (n.role == Role::kEdge) n.displacement = DisplacementNodeConfig{tracker.name, options.displacement};
      }
    }
    t.nodes.push_back(tracker);
    for (std::size_t k = 0; k < scene.cameras.size(); ++k) {
      const CameraConfig& cam = scene.cameras[k];
      std::string name = cameraNodeFor(cam.name);
      if (taken.count(name) > 0) name = name.substr(0, kMaxNameChars - 4) + "-" + std::to_string(k + 1);
      taken.insert(name);
      CameraNodeConfig c;
      c.source = kSimSource;
      c.scene = scene_file;
      c.camera = cam.name;
      c.rate_hz = cam.rate_hz;
      c.truth = true;
      c.truth_replay = options.truth;
      c.calibration.fx = cam.fx;
      c.calibration.fy = cam.fy;
      c.calibration.cx = cam.cx;
      c.calibration.cy = cam.cy;
      c.calibration.width = cam.width;
      c.calibration.height = cam.height;
      c.calibration.world_to_camera = cam.pose.inverse();
      t.nodes.push_back(detectionNode(static_cast<int>(k + 1), name, tracker.name, options.base_port, std::move(c)));
    }
  }
  t.madc.fragment_min_points = options.mapping.fragment_min_points;
  t.madc.alpha_max = options.mapping.alpha_max;
  return t;  // edges are leaves: renaming them leaves every parent link as it was
}

}  // namespace fogmap::sim
