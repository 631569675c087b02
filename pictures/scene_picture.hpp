#pragma once
// The bird's-eye picture of a global map over a simulated scene: the edges' points, the global
// objects, the LiDARs with their range and the true objects' outlines at the frame's instant, and the
// tracks a tracker held then. Pictures of what the harness ran: part of fogmap::run_pictures.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "common/io/messages.hpp"
#include "common/sim/scene.hpp"
#include "harness/cluster_run.hpp"
#include "harness/scene_run.hpp"
#include "harness/track_scoring.hpp"
#include "pictures/birdseye.hpp"

namespace fogmap::pictures {

// `what` starts the title ("MAD-C global map"); the epoch and the object count follow. The frame's
// instant comes from the epoch (sim::sceneTime of its scan number). `tracks` (may be empty) are
// drawn over the map; `missed`, when given, marks the centres of the true objects the map missed
// (harness::missedObjectCentres) and counts them in the title.
Status drawSceneBirdseye(const std::filesystem::path& png, const GlobalMapMessage& global, const harness::EdgeView& view,
                         const sim::Scene& scene, const TopologyConfig& topology, const std::string& what,
                         std::vector<BirdseyeTrack> tracks = {},
                         std::optional<std::vector<Eigen::Vector2d>> missed = std::nullopt);

// The tracks of lists[index] a picture shows (confirmed and lost ones, isHypothesis), each with its
// positions in up to `trail` lists before it as its trail. Empty when index is out of range.
std::vector<BirdseyeTrack> birdseyeTracks(std::span<const harness::PublishedTracks> lists, std::size_t index, std::size_t trail);

// The picture of a tracking run at its track list `index`: the global map the tracker fused then
// (with the edges' points recomputed), the truth, and the tracks with `trail` lists of trail. An
// error when the root published no map for that list's epoch.
Status drawSceneTracks(const std::filesystem::path& png, const sim::Scene& scene, const harness::SceneTrackingRun& run,
                       std::size_t index, std::size_t trail);

}  // namespace fogmap::pictures
