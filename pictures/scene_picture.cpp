#include "pictures/scene_picture.hpp"

#include "common/base/epochs.hpp"
#include "common/sim/footprint.hpp"
#include "common/perception/lidar_models.hpp"
#include "pictures/birdseye.hpp"
#include "services/edge_cluster/edge_runner.hpp"

namespace fogmap::pictures {

Status drawSceneBirdseye(const std::filesystem::path& png, const GlobalMapMessage& global, const harness::EdgeView& view,
                         const sim::Scene& scene, const TopologyConfig& topology, const std::string& what,
                         std::vector<BirdseyeTrack> tracks, std::optional<std::vector<Eigen::Vector2d>> missed) {
  const auto schedule = EpochSchedule::create(topology.period_ms, topology.deadline_ms);
  if (!schedule) return schedule.error();
  const double rate = 1000.0 / topology.period_ms;
  const double time_s = sim::sceneTime(scene, scanNumberAt(*schedule, rate, global.header.epoch), rate);
  BirdseyeScene picture;
  picture.title = what + ", epoch " + std::to_string(global.header.epoch) + ": " +
                  std::to_string(global.map.objects.size()) + " objects, " + std::to_string(scene.objects.size()) +
                  " in the scene" + (missed ? ", " + std::to_string(missed->size()) + " missed" : "") +
                  (tracks.empty() ? "" : ", " + std::to_string(tracks.size()) + " tracks");
  picture.half_extent_m = scene.extent_m;
  for (const auto& [node, points] : view.points) picture.points.emplace_back(points);
  picture.objects = global.map.objects;
  for (const auto& lidar : scene.lidars) {
    const auto model = lidarModel(lidar.model);
    const double range = lidar.max_range_m.value_or(model ? model->max_range_m : 0.0);
    picture.sensors.push_back({lidar.name, lidar.pose, range});
  }
  for (const auto& object : scene.objects) {
    picture.truth.push_back({object.id, object.label, sim::footprint(object, time_s)});
  }
  picture.tracks = std::move(tracks);
  picture.missed = std::move(missed);
  return drawBirdseye(png, picture);
}

std::vector<BirdseyeTrack> birdseyeTracks(std::span<const harness::PublishedTracks> lists, std::size_t index, std::size_t trail) {
  std::vector<BirdseyeTrack> out;
  if (index >= lists.size()) return out;
  const std::size_t first = index >= trail ? index - trail : 0;
  for (const auto& track : lists[index].tracks) {
    if (!harness::isHypothesis(track)) continue;
    BirdseyeTrack drawn;
    drawn.id = track.id;
    drawn.label = track.label;
    drawn.position = track.position;
    drawn.confirmed = track.state == tracking::TrackState::kConfirmed;
    drawn.heading_rad = track.heading_rad;
    for (std::size_t i = first; i < index; ++i) {
      for (const auto& earlier : lists[i].tracks) {
        if (earlier.id == track.id) drawn.trail.push_back(earlier.position);
      }
    }
    out.push_back(std::move(drawn));
  }
  return out;
}

Status drawSceneTracks(const std::filesystem::path& png, const sim::Scene& scene, const harness::SceneTrackingRun& run,
                       std::size_t index, std::size_t trail) {
  if (index >= run.lists.size()) return invalidArgument("no track list " + std::to_string(index));
  const auto schedule = EpochSchedule::create(run.topology.period_ms, run.topology.deadline_ms);
  if (!schedule) return schedule.error();
  const std::uint64_t epoch = schedule->epochAt(run.lists[index].lidar_time_ns);
  const auto global = run.result.epochs.find(epoch);
  if (global == run.result.epochs.end()) {
    return Error{ErrorCode::kNotFound, "the root published no global map for epoch " + std::to_string(epoch)};
  }
  auto views = harness::recomputeEdges(run.topology, {epoch});
  if (!views) return views.error();
  return drawSceneBirdseye(png, global->second, views->at(epoch), scene, run.topology, "MAD-C global map and tracks",
                           birdseyeTracks(run.lists, index, trail));
}

}  // namespace fogmap::pictures
