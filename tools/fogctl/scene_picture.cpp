#include "tools/fogctl/scene_picture.hpp"

#include "common/epochs.hpp"
#include "common/sim/footprint.hpp"
#include "common/sim/lidar_models.hpp"
#include "services/edge_cluster/edge_runner.hpp"
#include "tools/fogctl/birdseye.hpp"

namespace fogmap::cli {

Status drawSceneBirdseye(const std::filesystem::path& png, const GlobalMapMessage& global, const EdgeView& view,
                         const sim::Scene& scene, const TopologyConfig& topology, const std::string& what) {
  const auto schedule = EpochSchedule::create(topology.period_ms, topology.deadline_ms);
  if (!schedule) return schedule.error();
  const double rate = 1000.0 / topology.period_ms;
  const double time_s = sim::sceneTime(scene, scanNumberAt(*schedule, rate, global.header.epoch), rate);
  BirdseyeScene picture;
  picture.title = what + ", epoch " + std::to_string(global.header.epoch) + ": " +
                  std::to_string(global.map.objects.size()) + " objects, " + std::to_string(scene.objects.size()) +
                  " in the scene";
  picture.half_extent_m = scene.extent_m;
  for (const auto& [node, points] : view.points) picture.points.emplace_back(points);
  picture.objects = global.map.objects;
  for (const auto& lidar : scene.lidars) {
    const auto model = sim::lidarModel(lidar.model);
    const double range = lidar.max_range_m.value_or(model ? model->max_range_m : 0.0);
    picture.sensors.push_back({lidar.name, lidar.pose, range});
  }
  for (const auto& object : scene.objects) {
    picture.truth.push_back({object.id, object.label, sim::footprint(object, time_s)});
  }
  return drawBirdseye(png, picture);
}

}  // namespace fogmap::cli
