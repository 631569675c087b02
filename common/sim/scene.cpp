#include "common/sim/scene.hpp"

#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "common/base/angles.hpp"
#include "common/config/yaml_fields.hpp"
#include "common/perception/lidar_models.hpp"

namespace fogmap::sim {
namespace {

const YamlFields kFields("scene");

Error bad(const std::string& where, const std::string& what) { return kFields.bad(where, what); }

template <class T>
Expected<T> scalar(const YAML::Node& node, const std::string& key, const std::string& where, T fallback) {
  return kFields.scalar<T>(node, key, where, fallback);
}

Expected<Eigen::Vector2d> vec2(const YAML::Node& v, const std::string& where) {
  if (!v.IsSequence() || v.size() != 2) return bad(where, "expected a list of 2 numbers");
  try {
    const Eigen::Vector2d out(v[0].as<double>(), v[1].as<double>());
    if (!out.allFinite()) return bad(where, "values must be finite");
    return out;
  } catch (const YAML::Exception&) {
    return bad(where, "expected a list of 2 numbers");
  }
}

// node.name: present and not empty.
Expected<std::string> requiredName(const YAML::Node& node, const std::string& where, const std::string& what) {
  const auto name = scalar<std::string>(node, "name", where, "");
  if (!name) return name.error();
  if (name->empty()) return bad(where + ".name", "every " + what + " needs a name");
  return *name;
}

Status positive(double value, const std::string& where) {
  if (std::isfinite(value) && value > 0.0) return {};
  return bad(where, "must be a positive number");
}

Expected<Part> parsePart(const YAML::Node& node, const std::string& where) {
  if (const Status s = kFields.checkSection(node, where, {"shape", "size_m", "radius_m", "height_m", "at", "yaw_deg"}); !s) {
    return s.error();
  }
  Part part;
  const auto shape = scalar<std::string>(node, "shape", where, "box");
  if (!shape) return shape.error();
  const auto at = kFields.vec3(node, "at", where, Eigen::Vector3d::Zero());
  if (!at) return at.error();
  part.at = *at;
  const auto yaw = scalar<double>(node, "yaw_deg", where, 0.0);
  if (!yaw) return yaw.error();
  part.yaw_deg = *yaw;
  if (*shape == "box") {
    if (node["radius_m"] || node["height_m"]) return bad(where, "a box has size_m, not radius_m or height_m");
    if (!node["size_m"]) return bad(where + ".size_m", "a box needs its size [x, y, z]");
    const auto size = kFields.vec3(node, "size_m", where, Eigen::Vector3d::Ones());
    if (!size) return size.error();
    for (int i = 0; i < 3; ++i) {
      if (const Status s = positive((*size)[i], where + ".size_m"); !s) return s.error();
    }
    part.shape = Shape::kBox;
    part.size = *size;
  } else if (*shape == "cylinder") {
    if (node["size_m"]) return bad(where, "a cylinder has radius_m and height_m, not size_m");
    const auto radius = scalar<double>(node, "radius_m", where, -1.0);
    if (!radius) return radius.error();
    const auto height = scalar<double>(node, "height_m", where, -1.0);
    if (!height) return height.error();
    if (const Status s = positive(*radius, where + ".radius_m"); !s) return s.error();
    if (const Status s = positive(*height, where + ".height_m"); !s) return s.error();
    part.shape = Shape::kCylinder;
    part.size = {2.0 * *radius, 2.0 * *radius, *height};
  } else {
    return bad(where + ".shape", "must be box or cylinder, got '" + *shape + "'");
  }
  return part;
}

Expected<Motion> parseMotion(const YAML::Node& node, const std::string& where) {
  Motion motion;
  if (!node) return motion;
  if (const Status s = kFields.checkSection(node, where, {"velocity_mps", "waypoints", "speed_mps", "loop"}); !s) {
    return s.error();
  }
  if (node["velocity_mps"] && node["waypoints"]) return bad(where, "either velocity_mps or waypoints, not both");
  if (node["velocity_mps"]) {
    const auto v = vec2(node["velocity_mps"], where + ".velocity_mps");
    if (!v) return v.error();
    motion.velocity_mps = *v;
  }
  if (node["waypoints"]) {
    const YAML::Node list = node["waypoints"];
    if (!list.IsSequence() || list.size() < 2) return bad(where + ".waypoints", "needs at least 2 points");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const auto p = vec2(list[i], where + ".waypoints[" + std::to_string(i) + "]");
      if (!p) return p.error();
      motion.waypoints.push_back(*p);
    }
    const auto speed = scalar<double>(node, "speed_mps", where, -1.0);
    if (!speed) return speed.error();
    if (const Status s = positive(*speed, where + ".speed_mps"); !s) return s.error();
    motion.speed_mps = *speed;
    const auto loop = scalar<bool>(node, "loop", where, false);
    if (!loop) return loop.error();
    motion.loop = *loop;
  } else if (node["speed_mps"] || node["loop"]) {
    return bad(where, "speed_mps and loop go with waypoints");
  }
  return motion;
}

Expected<SceneObject> parseObject(const YAML::Node& node, const std::string& where) {
  if (const Status s = kFields.checkSection(node, where, {"id", "name", "label", "xy", "yaw_deg", "parts", "motion"}); !s) {
    return s.error();
  }
  SceneObject object;
  const auto id = scalar<long long>(node, "id", where, -1);
  if (!id) return id.error();
  if (*id < 1 || *id > 0xFFFFFFFFLL) return bad(where + ".id", "must be an integer from 1 (0 is the ground)");
  object.id = static_cast<std::uint32_t>(*id);
  const auto name = scalar<std::string>(node, "name", where, "object-" + std::to_string(*id));
  if (!name) return name.error();
  object.name = *name;
  const auto label = scalar<std::string>(node, "label", where, "object");
  if (!label) return label.error();
  object.label = *label;
  if (node["xy"]) {
    const auto xy = vec2(node["xy"], where + ".xy");
    if (!xy) return xy.error();
    object.xy = *xy;
  }
  const auto yaw = scalar<double>(node, "yaw_deg", where, 0.0);
  if (!yaw) return yaw.error();
  if (!std::isfinite(*yaw)) return bad(where + ".yaw_deg", "must be finite");
  object.yaw_deg = *yaw;
  const YAML::Node parts = node["parts"];
  if (!parts || !parts.IsSequence() || parts.size() == 0) return bad(where + ".parts", "an object needs at least one part");
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const auto part = parsePart(parts[i], where + ".parts[" + std::to_string(i) + "]");
    if (!part) return part.error();
    object.parts.push_back(*part);
  }
  const auto motion = parseMotion(node["motion"], where + ".motion");
  if (!motion) return motion.error();
  object.motion = *motion;
  return object;
}

Expected<LidarConfig> parseLidar(const YAML::Node& node, const std::string& where) {
  if (const Status s = kFields.checkSection(node, where, {"name", "model", "pose", "range_noise_m", "dropout", "min_range_m",
                                                         "max_range_m", "azimuth_steps"});
      !s) {
    return s.error();
  }
  LidarConfig lidar;
  const auto name = requiredName(node, where, "LiDAR");
  if (!name) return name.error();
  lidar.name = *name;
  const auto model = scalar<std::string>(node, "model", where, lidar.model);
  if (!model) return model.error();
  if (const auto known = lidarModel(*model); !known) return bad(where + ".model", known.error().message);
  lidar.model = *model;
  const auto pose = kFields.pose(node["pose"], where + ".pose");
  if (!pose) return pose.error();
  lidar.pose = *pose;
  const auto noise = scalar<double>(node, "range_noise_m", where, lidar.range_noise_m);
  if (!noise) return noise.error();
  if (!std::isfinite(*noise) || *noise < 0.0 || *noise > 1.0) return bad(where + ".range_noise_m", "must be in [0, 1] m");
  lidar.range_noise_m = *noise;
  const auto dropout = scalar<double>(node, "dropout", where, 0.0);
  if (!dropout) return dropout.error();
  if (!(*dropout >= 0.0 && *dropout < 1.0)) return bad(where + ".dropout", "must be in [0, 1)");
  lidar.dropout = *dropout;
  for (const char* key : {"min_range_m", "max_range_m"}) {
    if (!node[key]) continue;
    const auto value = scalar<double>(node, key, where, 0.0);
    if (!value) return value.error();
    if (const Status s = positive(*value, where + "." + key); !s) return s.error();
    (std::string(key) == "min_range_m" ? lidar.min_range_m : lidar.max_range_m) = *value;
  }
  if (lidar.min_range_m && lidar.max_range_m && *lidar.min_range_m >= *lidar.max_range_m) {
    return bad(where, "min_range_m must be below max_range_m");
  }
  if (node["azimuth_steps"]) {
    const auto steps = scalar<int>(node, "azimuth_steps", where, 0);
    if (!steps) return steps.error();
    if (*steps < 1 || *steps > 100000) return bad(where + ".azimuth_steps", "must be in [1, 100000]");
    lidar.azimuth_steps = *steps;
  }
  return lidar;
}

Expected<CameraConfig> parseCamera(const YAML::Node& node, const std::string& where) {
  if (const Status s =
          kFields.checkSection(node, where, {"name", "pose", "fx", "fy", "cx", "cy", "width", "height", "rate_hz"});
      !s) {
    return s.error();
  }
  CameraConfig camera;
  const auto name = requiredName(node, where, "camera");
  if (!name) return name.error();
  camera.name = *name;
  const auto pose = kFields.pose(node["pose"], where + ".pose");
  if (!pose) return pose.error();
  camera.pose = *pose;
  for (auto [key, field] : {std::pair{"fx", &camera.fx}, std::pair{"fy", &camera.fy}, std::pair{"cx", &camera.cx},
                            std::pair{"cy", &camera.cy}, std::pair{"rate_hz", &camera.rate_hz}}) {
    const auto value = scalar<double>(node, key, where, *field);
    if (!value) return value.error();
    if (const Status s = positive(*value, where + "." + key); !s) return s.error();
    *field = *value;
  }
  for (auto [key, field] : {std::pair{"width", &camera.width}, std::pair{"height", &camera.height}}) {
    const auto value = scalar<int>(node, key, where, *field);
    if (!value) return value.error();
    if (*value < 1 || *value > 16384) return bad(where + "." + key, "must be in [1, 16384] pixels");
    *field = *value;
  }
  return camera;
}

void emitPose(YAML::Emitter& out, const Eigen::Isometry3d& pose) {
  const Eigen::Vector3d t = pose.translation();
  const Eigen::Vector3d rpy = rpyDegrees(pose.rotation());
  out << YAML::Key << "pose" << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "translation_m" << YAML::Value << YAML::Flow << YAML::BeginSeq << t.x() << t.y() << t.z() << YAML::EndSeq;
  out << YAML::Key << "rpy_deg" << YAML::Value << YAML::Flow << YAML::BeginSeq << rpy.x() << rpy.y() << rpy.z() << YAML::EndSeq;
  out << YAML::EndMap;
}

}  // namespace

double Ground::heightAt(double x) const {
  double z = height_m + std::tan(tilt_deg * kDegToRad) * x;
  if (step_x_m && x >= *step_x_m) z += step_height_m;
  return z;
}

ObjectPose poseAt(const SceneObject& object, double time_s) {
  const Motion& m = object.motion;
  if (m.waypoints.size() >= 2 && m.speed_mps > 0.0) {
    std::vector<Eigen::Vector2d> path = m.waypoints;
    if (m.loop) path.push_back(path.front());
    double length = 0.0;
    for (std::size_t i = 1; i < path.size(); ++i) length += (path[i] - path[i - 1]).norm();
    double s = m.speed_mps * std::max(0.0, time_s);
    if (length <= 0.0) return {path.front(), object.yaw_deg * kDegToRad};
    s = m.loop ? std::fmod(s, length) : std::min(s, length);
    for (std::size_t i = 1; i < path.size(); ++i) {
      const Eigen::Vector2d d = path[i] - path[i - 1];
      const double n = d.norm();
      if (n <= 0.0) continue;
      if (s <= n || i + 1 == path.size()) {
        const double f = std::min(1.0, s / n);
        return {path[i - 1] + f * d, std::atan2(d.y(), d.x())};
      }
      s -= n;
    }
    return {path.back(), object.yaw_deg * kDegToRad};
  }
  if (!m.velocity_mps.isZero()) {
    return {object.xy + m.velocity_mps * time_s, std::atan2(m.velocity_mps.y(), m.velocity_mps.x())};
  }
  return {object.xy, object.yaw_deg * kDegToRad};
}

double sceneTime(const Scene& scene, std::uint64_t scan_number, double rate_hz) {
  const double duration = scene.duration_s;
  if (!(rate_hz > 0.0) || !std::isfinite(rate_hz) || !(duration > 0.0) || !std::isfinite(duration)) return 0.0;
  const double cycle_frames = duration * rate_hz;
  const double whole = std::round(cycle_frames);
  // A whole number of frames per cycle (60 s at 10 Hz: 600): the remainder of the integer scan
  // number, exact however large it is. 1e-9 relative absorbs the rounding of duration x rate.
  if (whole >= 1.0 && whole < 9.0e18 && std::abs(cycle_frames - whole) <= 1e-9 * whole) {
    const auto frames = static_cast<std::uint64_t>(whole);
    return static_cast<double>(scan_number % frames) / rate_hz;
  }
  // Otherwise scan_number / rate_hz in long double (a 64-bit mantissa on x86-64: the scan number
  // itself is exact), then an exact fmod.
  const long double t = static_cast<long double>(scan_number) / static_cast<long double>(rate_hz);
  const double wrapped = static_cast<double>(std::fmod(t, static_cast<long double>(duration)));
  return wrapped < duration ? wrapped : 0.0;  // rounding to double may reach the duration itself
}

const LidarConfig* Scene::lidar(const std::string& name) const {
  for (const auto& l : lidars) {
    if (l.name == name) return &l;
  }
  return nullptr;
}

Expected<Scene> parseScene(const std::string& yaml_text) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    return invalidArgument(std::string("scene: not YAML: ") + e.what());
  }
  if (const Status s = kFields.checkSection(root, "", {"name", "seed", "extent_m", "duration_s", "ground", "objects", "lidars",
                                                     "cameras"});
      !s) {
    return s.error();
  }
  Scene scene;
  const auto name = scalar<std::string>(root, "name", "", scene.name);
  if (!name) return name.error();
  scene.name = *name;
  const auto seed = scalar<std::uint64_t>(root, "seed", "", scene.seed);
  if (!seed) return seed.error();
  scene.seed = *seed;
  const auto extent = scalar<double>(root, "extent_m", "", scene.extent_m);
  if (!extent) return extent.error();
  if (!(*extent > 0.0 && *extent <= 10000.0)) return bad("extent_m", "must be in (0, 10000] m");
  scene.extent_m = *extent;
  const auto duration = scalar<double>(root, "duration_s", "", scene.duration_s);
  if (!duration) return duration.error();
  if (const Status s = positive(*duration, "duration_s"); !s) return s.error();
  scene.duration_s = *duration;
  if (const YAML::Node g = root["ground"]) {
    if (const Status s = kFields.checkSection(g, "ground", {"height_m", "tilt_deg", "step_x_m", "step_height_m"}); !s) {
      return s.error();
    }
    for (auto [key, field] : {std::pair{"height_m", &scene.ground.height_m}, std::pair{"tilt_deg", &scene.ground.tilt_deg},
                              std::pair{"step_height_m", &scene.ground.step_height_m}}) {
      const auto value = scalar<double>(g, key, "ground", *field);
      if (!value) return value.error();
      if (!std::isfinite(*value)) return bad(std::string("ground.") + key, "must be finite");
      *field = *value;
    }
    if (std::abs(scene.ground.tilt_deg) > 30.0) return bad("ground.tilt_deg", "must be within 30 degrees");
    if (g["step_x_m"]) {
      const auto x = scalar<double>(g, "step_x_m", "ground", 0.0);
      if (!x) return x.error();
      if (!std::isfinite(*x)) return bad("ground.step_x_m", "must be finite");
      scene.ground.step_x_m = *x;
    }
  }
  std::set<std::uint32_t> ids;
  std::set<std::string> names;
  if (const YAML::Node list = root["objects"]) {
    if (!list.IsSequence()) return bad("objects", "must be a list");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string where = "objects[" + std::to_string(i) + "]";
      auto object = parseObject(list[i], where);
      if (!object) return object.error();
      if (!ids.insert(object->id).second) return bad(where + ".id", "id " + std::to_string(object->id) + " is used twice");
      scene.objects.push_back(std::move(*object));
    }
  }
  const YAML::Node lidars = root["lidars"];
  if (!lidars || !lidars.IsSequence() || lidars.size() == 0) return bad("lidars", "a scene needs at least one LiDAR");
  for (std::size_t i = 0; i < lidars.size(); ++i) {
    const std::string where = "lidars[" + std::to_string(i) + "]";
    auto lidar = parseLidar(lidars[i], where);
    if (!lidar) return lidar.error();
    if (!names.insert(lidar->name).second) return bad(where + ".name", "'" + lidar->name + "' is used twice");
    scene.lidars.push_back(std::move(*lidar));
  }
  if (const YAML::Node cameras = root["cameras"]) {
    if (!cameras.IsSequence()) return bad("cameras", "must be a list");
    for (std::size_t i = 0; i < cameras.size(); ++i) {
      const std::string where = "cameras[" + std::to_string(i) + "]";
      auto camera = parseCamera(cameras[i], where);
      if (!camera) return camera.error();
      if (!names.insert(camera->name).second) return bad(where + ".name", "'" + camera->name + "' is used twice");
      scene.cameras.push_back(std::move(*camera));
    }
  }
  return scene;
}

Expected<Scene> loadScene(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) return Error{ErrorCode::kNotFound, "scene: cannot read " + path.string()};
  std::stringstream text;
  text << in.rdbuf();
  auto scene = parseScene(text.str());
  if (!scene) return Error{scene.error().code, path.string() + ": " + scene.error().message};
  return scene;
}

std::string toYaml(const Scene& scene) {
  YAML::Emitter out;
  out.SetDoublePrecision(10);
  out << YAML::BeginMap;
  out << YAML::Key << "name" << YAML::Value << scene.name;
  out << YAML::Key << "seed" << YAML::Value << scene.seed;
  out << YAML::Key << "extent_m" << YAML::Value << scene.extent_m;
  out << YAML::Key << "duration_s" << YAML::Value << scene.duration_s;
  out << YAML::Key << "ground" << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "height_m" << YAML::Value << scene.ground.height_m;
  out << YAML::Key << "tilt_deg" << YAML::Value << scene.ground.tilt_deg;
  if (scene.ground.step_x_m) {
    out << YAML::Key << "step_x_m" << YAML::Value << *scene.ground.step_x_m;
    out << YAML::Key << "step_height_m" << YAML::Value << scene.ground.step_height_m;
  }
  out << YAML::EndMap;
  out << YAML::Key << "objects" << YAML::Value << YAML::BeginSeq;
  for (const SceneObject& o : scene.objects) {
    out << YAML::BeginMap;
    out << YAML::Key << "id" << YAML::Value << o.id;
    out << YAML::Key << "name" << YAML::Value << o.name;
    out << YAML::Key << "label" << YAML::Value << o.label;
    out << YAML::Key << "xy" << YAML::Value << YAML::Flow << YAML::BeginSeq << o.xy.x() << o.xy.y() << YAML::EndSeq;
    out << YAML::Key << "yaw_deg" << YAML::Value << o.yaw_deg;
    out << YAML::Key << "parts" << YAML::Value << YAML::BeginSeq;
    for (const Part& p : o.parts) {
      out << YAML::Flow << YAML::BeginMap;
      out << YAML::Key << "shape" << YAML::Value << (p.shape == Shape::kBox ? "box" : "cylinder");
      if (p.shape == Shape::kBox) {
        out << YAML::Key << "size_m" << YAML::Value << YAML::Flow << YAML::BeginSeq << p.size.x() << p.size.y() << p.size.z()
            << YAML::EndSeq;
      } else {
        out << YAML::Key << "radius_m" << YAML::Value << p.size.x() / 2.0;
        out << YAML::Key << "height_m" << YAML::Value << p.size.z();
      }
      if (!p.at.isZero()) {
        out << YAML::Key << "at" << YAML::Value << YAML::Flow << YAML::BeginSeq << p.at.x() << p.at.y() << p.at.z() << YAML::EndSeq;
      }
      if (p.yaw_deg != 0.0) out << YAML::Key << "yaw_deg" << YAML::Value << p.yaw_deg;
      out << YAML::EndMap;
    }
    out << YAML::EndSeq;
    const Motion& m = o.motion;
    if (!m.velocity_mps.isZero()) {
      out << YAML::Key << "motion" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "velocity_mps" << YAML::Value
          << YAML::Flow << YAML::BeginSeq << m.velocity_mps.x() << m.velocity_mps.y() << YAML::EndSeq << YAML::EndMap;
    } else if (!m.waypoints.empty()) {
      out << YAML::Key << "motion" << YAML::Value << YAML::BeginMap << YAML::Key << "waypoints" << YAML::Value << YAML::Flow
          << YAML::BeginSeq;
      for (const auto& w : m.waypoints) out << YAML::Flow << YAML::BeginSeq << w.x() << w.y() << YAML::EndSeq;
      out << YAML::EndSeq << YAML::Key << "speed_mps" << YAML::Value << m.speed_mps << YAML::Key << "loop" << YAML::Value
          << m.loop << YAML::EndMap;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "lidars" << YAML::Value << YAML::BeginSeq;
  for (const LidarConfig& l : scene.lidars) {
    out << YAML::BeginMap;
    out << YAML::Key << "name" << YAML::Value << l.name;
    out << YAML::Key << "model" << YAML::Value << l.model;
    emitPose(out, l.pose);
    out << YAML::Key << "range_noise_m" << YAML::Value << l.range_noise_m;
    out << YAML::Key << "dropout" << YAML::Value << l.dropout;
    if (l.min_range_m) out << YAML::Key << "min_range_m" << YAML::Value << *l.min_range_m;
    if (l.max_range_m) out << YAML::Key << "max_range_m" << YAML::Value << *l.max_range_m;
    if (l.azimuth_steps) out << YAML::Key << "azimuth_steps" << YAML::Value << *l.azimuth_steps;
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;
  if (!scene.cameras.empty()) {
    out << YAML::Key << "cameras" << YAML::Value << YAML::BeginSeq;
    for (const CameraConfig& c : scene.cameras) {
      out << YAML::BeginMap;
      out << YAML::Key << "name" << YAML::Value << c.name;
      emitPose(out, c.pose);
      out << YAML::Key << "fx" << YAML::Value << c.fx << YAML::Key << "fy" << YAML::Value << c.fy;
      out << YAML::Key << "cx" << YAML::Value << c.cx << YAML::Key << "cy" << YAML::Value << c.cy;
      out << YAML::Key << "width" << YAML::Value << c.width << YAML::Key << "height" << YAML::Value << c.height;
      out << YAML::Key << "rate_hz" << YAML::Value << c.rate_hz;
      out << YAML::EndMap;
    }
    out << YAML::EndSeq;
  }
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace fogmap::sim
