#pragma once
// A simulated scene (docs: data/scenes/example.yaml): a ground, objects made of boxes and
// cylinders that may move, static LiDARs and cameras. Pure data with poses at any time.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "common/base/status.hpp"

namespace fogmap::sim {

// The truth label of ground points; objects have ids from 1.
inline constexpr std::uint32_t kGroundId = 0;

enum class Shape { kBox, kCylinder };

// One solid of an object, in the object's frame (x forward, z up, origin on the ground).
struct Part {
  Shape shape = Shape::kBox;
  Eigen::Vector3d at = Eigen::Vector3d::Zero();  // the centre of the part's bottom face
  Eigen::Vector3d size = Eigen::Vector3d::Ones();  // box: x, y, z extents; cylinder: 2 r, 2 r, height
  double yaw_deg = 0.0;                          // boxes: about the part's vertical axis
};

// Constant velocity, or waypoints followed at a speed (heading along the path), or neither.
struct Motion {
  Eigen::Vector2d velocity_mps = Eigen::Vector2d::Zero();
  std::vector<Eigen::Vector2d> waypoints;  // the first is where the object starts
  double speed_mps = 0.0;
  bool loop = false;  // back to the first waypoint after the last; else it stops there
  bool moves() const { return !velocity_mps.isZero() || (waypoints.size() >= 2 && speed_mps > 0.0); }
};

struct SceneObject {
  std::uint32_t id = 1;
  std::string name;
  std::string label;  // what it is: crate, truck, person, pole, forklift, car, shelf, ...
  std::vector<Part> parts;
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();  // at time 0 (ignored with waypoints)
  double yaw_deg = 0.0;                          // at time 0 (with motion: the heading of the path)
  Motion motion;
};

// Where an object is at a time: position on the ground plane and heading.
struct ObjectPose {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  double yaw_rad = 0.0;
};
ObjectPose poseAt(const SceneObject& object, double time_s);

// z = height_m + tan(tilt_deg) x, plus step_height_m where x >= step_x_m (a kerb, a platform).
struct Ground {
  double height_m = 0.0;
  double tilt_deg = 0.0;
  std::optional<double> step_x_m;
  double step_height_m = 0.0;
  double heightAt(double x) const;
};

struct LidarConfig {
  std::string name;
  std::string model = "VLP-16";          // lidarModel(...)
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // sensor -> scene
  double range_noise_m = 0.01;           // Gaussian sigma on the range
  double dropout = 0.0;                  // probability that a return is lost
  std::optional<double> min_range_m;     // default: the model's
  std::optional<double> max_range_m;
  std::optional<int> azimuth_steps;      // default: the model's
};

// A pinhole camera: x right, y down, z forward in its own frame.
struct CameraConfig {
  std::string name;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // camera -> scene
  double fx = 500.0, fy = 500.0, cx = 320.0, cy = 240.0;
  int width = 640, height = 480;
  double rate_hz = 10.0;
};

struct Scene {
  std::string name = "scene";
  std::uint64_t seed = 1;   // noise and dropout
  double extent_m = 50.0;   // the ground reaches this far from the origin in x and y
  double duration_s = 60.0;  // scene time runs in [0, duration_s) and starts again (sceneTime)
  Ground ground;
  std::vector<SceneObject> objects;
  std::vector<LidarConfig> lidars;
  std::vector<CameraConfig> cameras;
  const LidarConfig* lidar(const std::string& name) const;
};

// The scene instant a sensor of `rate_hz` shows in its scan `scan_number`: fmod(scan_number /
// rate_hz, duration_s). Scan numbers count sensor periods since the unix epoch (about 1.7e10 at
// 10 Hz), so where duration_s x rate_hz is a whole number of frames the remainder is taken on the
// integer scan number, exact for every scan number; otherwise in long double. Every edge of a
// cluster (and whoever recomputes a frame's truth) gets the same instant for the same scan number.
// `rate_hz` and duration_s must be positive and finite (0 otherwise).
double sceneTime(const Scene& scene, std::uint64_t scan_number, double rate_hz);

// Reads and checks a scene file; every error names its place ("scene: objects[2].parts[0].size: ...").
Expected<Scene> parseScene(const std::string& yaml_text);
Expected<Scene> loadScene(const std::filesystem::path& path);
std::string toYaml(const Scene& scene);

}  // namespace fogmap::sim
