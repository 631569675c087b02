#pragma once
// The bird's-eye picture of a global map over a simulated scene: the edges' points, the global
// objects, the LiDARs with their range and the true objects' outlines at the frame's instant, and the
// tracks a tracker held then.
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include "common/messages.hpp"
#include "common/sim/scene.hpp"
#include "common/status.hpp"
#include "common/topology.hpp"
#include "tools/fogctl/birdseye.hpp"
#include "tools/fogctl/cluster_run.hpp"
#include "tools/fogctl/scene_run.hpp"
#include "tools/fogctl/track_scoring.hpp"

namespace fogmap::cli {

// `what` starts the title ("MAD-C global map"); the epoch and the object count follow. The frame's
// instant comes from the epoch (sim::sceneTime of its scan number). `tracks` (may be empty) are
// drawn over the map.
Status drawSceneBirdseye(const std::filesystem::path& png, const GlobalMapMessage& global, const EdgeView& view,
                         const sim::Scene& scene, const TopologyConfig& topology, const std::string& what,
                         std::vector<BirdseyeTrack> tracks = {});

// The tracks of lists[index] a picture shows (confirmed and lost ones, isHypothesis), each with its
// positions in up to `trail` lists before it as its trail. Empty when index is out of range.
std::vector<BirdseyeTrack> birdseyeTracks(std::span<const PublishedTracks> lists, std::size_t index, std::size_t trail);

// The picture of a tracking run at its track list `index`: the global map the tracker fused then
// (with the edges' points recomputed), the truth, and the tracks with `trail` lists of trail. An
// error when the root published no map for that list's epoch.
Status drawSceneTracks(const std::filesystem::path& png, const sim::Scene& scene, const SceneTrackingRun& run,
                       std::size_t index, std::size_t trail);

}  // namespace fogmap::cli
