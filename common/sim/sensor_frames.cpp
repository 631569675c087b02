#include "common/sim/sensor_frames.hpp"

#include <algorithm>
#include <cmath>

namespace fogmap::sim {

std::uint64_t cycleFrame(const Scene& scene, std::uint64_t scan_number, double rate_hz) {
  // sceneTime(scan) x rate is the frame within the cycle; exact where the cycle is whole frames.
  const double cycle_frames = scene.duration_s * rate_hz;
  const double whole = std::round(cycle_frames);
  if (std::isfinite(cycle_frames) && whole >= 1.0 && whole < 9.0e18 && std::abs(cycle_frames - whole) <= 1e-9 * whole) {
    return scan_number % static_cast<std::uint64_t>(whole);
  }
  return scan_number;
}

bool anythingMoves(const Scene& scene) {
  return std::any_of(scene.objects.begin(), scene.objects.end(), [](const SceneObject& o) { return o.motion.moves(); });
}

Expected<SimFrame> simulateScan(const Scene& scene, const LidarConfig& lidar, std::uint64_t scan_number,
                                double rate_hz, RaycasterCache& cache, int threads) {
  const double time_s = sceneTime(scene, scan_number, rate_hz);
  const std::uint64_t frame = cycleFrame(scene, scan_number, rate_hz);
  if (!anythingMoves(scene)) {
    if (!cache.still) {
      auto built = SceneRaycaster::build(scene, 0.0);
      if (!built) return built.error();
      cache.still.emplace(std::move(*built));
    }
    auto cast = cache.still->scan(lidar, scene.seed, frame, threads);
    if (cast) cast->time_s = time_s;
    return cast;
  }
  auto built = SceneRaycaster::build(scene, time_s);
  if (!built) return built.error();
  return built->scan(lidar, scene.seed, frame, threads);
}

}  // namespace fogmap::sim
