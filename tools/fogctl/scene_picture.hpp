#pragma once
// The bird's-eye picture of a global map over a simulated scene: the edges' points, the global
// objects, the LiDARs with their range and the true objects' outlines at the frame's instant.
#include <cstdint>
#include <filesystem>
#include <string>

#include "common/messages.hpp"
#include "common/sim/scene.hpp"
#include "common/status.hpp"
#include "common/topology.hpp"
#include "tools/fogctl/cluster_run.hpp"

namespace fogmap::cli {

// `what` starts the title ("MAD-C global map"); the epoch and the object count follow. The frame's
// instant comes from the epoch (sim::sceneTime of its scan number).
Status drawSceneBirdseye(const std::filesystem::path& png, const GlobalMapMessage& global, const EdgeView& view,
                         const sim::Scene& scene, const TopologyConfig& topology, const std::string& what);

}  // namespace fogmap::cli
