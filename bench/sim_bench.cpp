// The scene simulator's speed: rays per second of whole LiDAR frames (issue targets: an HDL-64E
// frame of a 100-object scene within 30 ms on one core; 7 LiDARs within 200 ms).
#include <benchmark/benchmark.h>

#include "common/sim/generators.hpp"
#include "common/sim/raycaster.hpp"

namespace {

using namespace fogmap::sim;

// One frame of `lidars` LiDARs of `model` over a random scene of `objects` objects, BVH build included.
void simulateFrame(benchmark::State& state, int objects, int lidars, const char* model) {
  Scene scene = randomScene(objects, lidars, 1);
  for (auto& l : scene.lidars) l.model = model;
  std::uint64_t rays = 0;
  std::uint64_t points = 0;
  std::uint64_t frame = 0;
  for (auto _ : state) {
    auto raycaster = SceneRaycaster::build(scene, 0.1 * static_cast<double>(frame));
    for (const auto& lidar : scene.lidars) {
      const auto f = raycaster->scan(lidar, scene.seed, frame, 1);
      rays += f->rays;
      points += f->points.size();
      benchmark::DoNotOptimize(f->points.data());
    }
    ++frame;
  }
  state.counters["rays_per_s"] = benchmark::Counter(static_cast<double>(rays), benchmark::Counter::kIsRate);
  state.counters["points_per_frame"] = static_cast<double>(points) / static_cast<double>(std::max<std::uint64_t>(frame, 1));
}

BENCHMARK_CAPTURE(simulateFrame, hdl64e_100_objects_1_lidar, 100, 1, "HDL-64E")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(simulateFrame, hdl64e_100_objects_7_lidars, 100, 7, "HDL-64E")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(simulateFrame, hdl32e_100_objects_7_lidars, 100, 7, "HDL-32E")->Unit(benchmark::kMillisecond);

}  // namespace
