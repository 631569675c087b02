#include "services/edge_cluster/sim_scan_source.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

#include "common/base/angles.hpp"
#include "common/config/yaml_fields.hpp"

namespace fogmap {
namespace {

std::string describePose(const Eigen::Isometry3d& pose) {
  const Eigen::Vector3d t = pose.translation();
  const Eigen::Vector3d rpy = rpyDegrees(pose.rotation());
  std::ostringstream out;
  out.precision(12);
  out << "{translation_m: [" << t.x() << ", " << t.y() << ", " << t.z() << "], rpy_deg: [" << rpy.x() << ", " << rpy.y()
      << ", " << rpy.z() << "]}";
  return out.str();
}

// Scans in one pass over the scene's duration: the end of a simulation that does not loop.
std::uint64_t scansPerPass(const sim::Scene& scene, double rate_hz) {
  const double frames = scene.duration_s * rate_hz;
  const double whole = std::round(frames);
  if (std::abs(frames - whole) <= 1e-9 * whole) return std::max<std::uint64_t>(1, static_cast<std::uint64_t>(whole));
  return std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::ceil(frames)));
}

}  // namespace

SimScanSource::SimScanSource(sim::Scene scene, std::size_t lidar_index, SensorConfig sensor, sim::RaycasterCache cache)
    : scene_(std::move(scene)),
      lidar_index_(lidar_index),
      sensor_(std::move(sensor)),
      moving_(!cache.still.has_value()),
      cache_(std::move(cache)) {}

Expected<SimScanSource> SimScanSource::open(const SensorConfig& sensor) {
  Expected<sim::Scene> scene = sim::loadScene(sensor.scene);
  if (!scene) return scene.error();
  return create(std::move(*scene), sensor);
}

Expected<SimScanSource> SimScanSource::create(sim::Scene scene, const SensorConfig& sensor) {
  if (!(sensor.rate_hz > 0.0) || !std::isfinite(sensor.rate_hz)) {
    return invalidArgument("simulated LiDAR '" + sensor.lidar + "': rate_hz must be positive");
  }
  const auto found = std::find_if(scene.lidars.begin(), scene.lidars.end(),
                                  [&](const sim::LidarConfig& l) { return l.name == sensor.lidar; });
  if (found == scene.lidars.end()) {
    std::string known;
    for (const sim::LidarConfig& l : scene.lidars) known += (known.empty() ? "'" : ", '") + l.name + "'";
    return invalidArgument(sensor.scene.string() + ": the scene has no LiDAR '" + sensor.lidar + "' (its LiDARs: " + known +
                           ")");
  }
  const auto index = static_cast<std::size_t>(found - scene.lidars.begin());
  const bool moving = sim::anythingMoves(scene);
  sim::RaycasterCache cache;
  if (!moving) {
    // Nothing moves: every instant is the same scene, built once (and any problem found now).
    Expected<sim::SceneRaycaster> built = sim::SceneRaycaster::build(scene, 0.0);
    if (!built) return Error{built.error().code, sensor.scene.string() + ": " + built.error().message};
    cache.still.emplace(std::move(*built));
  }
  return SimScanSource(std::move(scene), index, sensor, std::move(cache));
}

bool SimScanSource::done() const {
  if (sensor_.frames && emitted_ >= *sensor_.frames) return true;
  return !sensor_.loop && reads_ >= scansPerPass(scene_, sensor_.rate_hz);
}

Expected<ScanFrame> SimScanSource::at(std::uint64_t n) {
  if (done()) return Error{ErrorCode::kInternal, "SimScanSource::at called after the source is done"};
  ++reads_;
  const double time_s = sim::sceneTime(scene_, n, sensor_.rate_hz);
  Expected<sim::SimFrame> frame = sim::simulateScan(scene_, lidar(), n, sensor_.rate_hz, cache_);
  if (!frame) {
    return Error{frame.error().code, sensor_.scene.string() + ": LiDAR '" + lidar().name + "' at scene time " +
                                         std::to_string(time_s) + " s: " + frame.error().message};
  }
  ++emitted_;
  ScanFrame out;
  out.sequence = n;
  out.file = sensor_.scene;
  out.points = std::move(frame->points);
  return out;
}

std::string SimScanSource::describe() const {
  std::ostringstream out;
  out << "simulated " << lidar().model << " '" << lidar().name << "' in scene " << sensor_.scene.string() << " ("
      << scene_.objects.size() << " objects, " << (moving_ ? "moving" : "static") << ", " << scene_.duration_s
      << " s of scene time)";
  return out.str();
}

Status checkLidarPose(const Eigen::Isometry3d& topology_pose, const sim::LidarConfig& lidar, double tolerance) {
  const double offset_m = (topology_pose.translation() - lidar.pose.translation()).norm();
  const double angle_rad =
      Eigen::AngleAxisd(Eigen::Matrix3d(topology_pose.rotation().transpose() * lidar.pose.rotation())).angle();
  if (offset_m <= tolerance && angle_rad <= tolerance) return {};
  std::ostringstream why;
  why << "the topology's pose " << describePose(topology_pose) << " differs from the pose of LiDAR '" << lidar.name
      << "' in the scene " << describePose(lidar.pose) << " by " << offset_m << " m and " << angle_rad * kRadToDeg
      << " degrees (at most " << tolerance << " m and rad): its points would land in the wrong place; give the sensor "
      << "the scene's pose (fogctl topology --scene writes it)";
  return invalidArgument(why.str());
}

Status checkSensorPose(const SensorConfig& sensor) {
  if (!sensor.simulated()) return {};
  Expected<sim::Scene> scene = sim::loadScene(sensor.scene);
  if (!scene) return scene.error();
  const sim::LidarConfig* lidar = scene->lidar(sensor.lidar);
  if (lidar == nullptr) return invalidArgument(sensor.scene.string() + ": the scene has no LiDAR '" + sensor.lidar + "'");
  if (Status s = checkLidarPose(sensor.pose, *lidar); !s) {
    return invalidArgument(sensor.scene.string() + ": " + s.error().message);
  }
  return {};
}

}  // namespace fogmap
