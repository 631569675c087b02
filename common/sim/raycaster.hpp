#pragma once
// Ray casting of a scene at one instant with Intel Embree: boxes and the ground as triangle
// meshes, cylinders as Embree user geometry with an exact ray-cylinder intersection. A LiDAR frame
// casts every ray of its beam pattern; each return carries the id of the object it hit (kGroundId
// for the ground), so every point has its truth.
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Geometry>

#include "common/base/status.hpp"
#include "common/geometry/cloud.hpp"
#include "common/perception/lidar_models.hpp"
#include "common/sim/scene.hpp"

namespace fogmap::sim {

struct Hit {
  double distance_m = 0.0;        // along the (unit) ray direction
  std::uint32_t object = kGroundId;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // not normalised to face the ray
};

// One LiDAR's frame: points in the sensor's frame, in ray order (ring-major, then azimuth).
struct SimFrame {
  std::string lidar;
  double time_s = 0.0;
  Eigen::Isometry3d sensor_pose = Eigen::Isometry3d::Identity();  // sensor -> scene
  Cloud points;                       // intensity 0: the simulator models no reflectance
  std::vector<std::uint32_t> truth;   // per point: the object hit (kGroundId for the ground)
  std::uint64_t rays = 0;             // rays cast (returns + misses + dropped)
};

class SceneRaycaster {
 public:
  // Builds the acceleration structure of `scene` with every object where it is at `time_s`.
  static Expected<SceneRaycaster> build(const Scene& scene, double time_s);
  SceneRaycaster(SceneRaycaster&&) noexcept;
  SceneRaycaster& operator=(SceneRaycaster&&) noexcept;
  ~SceneRaycaster();

  double time() const;
  // The nearest hit along the ray from `origin` in direction `direction` (normalised here),
  // between 0 and max_range_m; thread-safe.
  std::optional<Hit> cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, double max_range_m) const;

  // Every ray of `lidar`'s beam pattern at this instant: range noise and dropout drawn per ray from
  // (seed, frame, lidar name, ray index), so the frame is byte-identical whatever `threads`.
  Expected<SimFrame> scan(const LidarConfig& lidar, std::uint64_t seed, std::uint64_t frame, int threads = 1) const;

 private:
  struct Impl;
  explicit SceneRaycaster(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The unit direction of ray (ring, step) in the sensor frame: azimuth 2 pi step / steps from +x
// towards +y, elevation from the horizontal plane.
Eigen::Vector3d beamDirection(double elevation_deg, int step, int azimuth_steps);

}  // namespace fogmap::sim
