#pragma once
// A simulated LiDAR's frame by scan number, the one definition the edge's sim source and every
// recomputation (truth, evaluation) share: the scene is cast at sceneTime(scan number), and the
// noise and dropout are drawn for the scan's place in the scene's cycle, so that a cycle replays
// exactly (a recording of duration_s, looped) and two runs can be compared frame by frame.
#include <cstdint>
#include <optional>

#include "common/base/status.hpp"
#include "common/sim/raycaster.hpp"
#include "common/sim/scene.hpp"

namespace fogmap::sim {

// Keeps the acceleration structure of a scene in which nothing moves: it is the same at every
// instant. Belongs to one scene.
class RaycasterCache {
 public:
  std::optional<SceneRaycaster> still;
};

// The index of scan `scan_number` within the scene's cycle (scan_number mod duration_s x rate_hz
// when that is a whole number of frames, else the scan number itself).
std::uint64_t cycleFrame(const Scene& scene, std::uint64_t scan_number, double rate_hz);
bool anythingMoves(const Scene& scene);

// Casts `lidar` at sceneTime(scene, scan_number, rate_hz) with noise frame cycleFrame(...).
Expected<SimFrame> simulateScan(const Scene& scene, const LidarConfig& lidar, std::uint64_t scan_number,
                                double rate_hz, RaycasterCache& cache, int threads = 1);

}  // namespace fogmap::sim
