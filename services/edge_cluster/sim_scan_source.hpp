#pragma once
// A simulated LiDAR as an edge's scans (topology `sensor: {source: sim, scene: FILE, lidar: NAME}`):
// scan n is LiDAR NAME's frame of the scene at the scene instant sim::sceneTime(scene, n, rate_hz),
// with noise and dropout drawn for its frame in the scene's cycle (sim::simulateScan, which every
// recomputation shares: a cycle of duration_s replays exactly). Scan numbers come from unix time (scanNumberAt), so
// every edge of a cluster shows the same instant of the scene in one epoch, and anyone can cast a
// frame again from (scene, LiDAR, n). Points are in the sensor frame; the topology's pose must be
// the LiDAR's pose in the scene (checkSensorPose).
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include <Eigen/Geometry>

#include "common/sim/raycaster.hpp"
#include "common/sim/scene.hpp"
#include "common/sim/sensor_frames.hpp"
#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "services/edge_cluster/scan_source.hpp"

namespace fogmap {

class SimScanSource : public ScanProvider {
 public:
  // Loads `sensor.scene` and finds `sensor.lidar` in it; an error names the file, or the LiDAR and
  // the scene's LiDARs.
  static Expected<SimScanSource> open(const SensorConfig& sensor);
  // The same from a scene in memory; `sensor.scene` only names it in frames and errors.
  static Expected<SimScanSource> create(sim::Scene scene, const SensorConfig& sensor);

  // True once `frames` frames were cast, or, without looping, after as many scans as the scene's
  // duration holds (ceil(duration_s x rate_hz)).
  bool done() const override;
  // LiDAR frame of scan number n: sim::simulateScan(scene, lidar, n, rate_hz), i.e. cast at
  // sceneTime(scene, n, rate_hz) with noise for cycleFrame(scene, n, rate_hz) and the scene's seed;
  // sequence n, file the scene file. Must not be called when done().
  Expected<ScanFrame> at(std::uint64_t n) override;
  std::uint64_t emitted() const override { return emitted_; }
  std::string describe() const override;

  const sim::Scene& scene() const { return scene_; }
  const sim::LidarConfig& lidar() const { return scene_.lidars[lidar_index_]; }
  // True when some object moves: the scene is then built again for every frame.
  bool moving() const { return moving_; }

 private:
  SimScanSource(sim::Scene scene, std::size_t lidar_index, SensorConfig sensor, sim::RaycasterCache cache);

  sim::Scene scene_;
  std::size_t lidar_index_ = 0;
  SensorConfig sensor_;
  bool moving_ = false;
  sim::RaycasterCache cache_;                 // the scene, built once when nothing moves
  std::uint64_t emitted_ = 0;                 // frames cast
  std::uint64_t reads_ = 0;                   // calls of at(), cast or not
};

// Where the topology pose of a simulated LiDAR may differ from its pose in the scene: 1e-6 m in
// translation and 1e-6 rad in rotation (the poses are written with 12 digits).
inline constexpr double kSimPoseTolerance = 1e-6;

// OK when `topology_pose` is `lidar`'s mounting pose within `tolerance` (metres and radians);
// otherwise an error that prints both poses, so a hand-written topology cannot misplace a LiDAR.
Status checkLidarPose(const Eigen::Isometry3d& topology_pose, const sim::LidarConfig& lidar,
                      double tolerance = kSimPoseTolerance);
// For a simulated sensor, loads its scene and checks its pose against its LiDAR's (checkLidarPose);
// OK for every other sensor.
Status checkSensorPose(const SensorConfig& sensor);

}  // namespace fogmap
