// Google Benchmark: the core algorithms on bundled real scans and on the paper's MERGE scenario.
// Run a Release build: build/bin/fogmap_bench
#include <benchmark/benchmark.h>

#include <random>

#include <Eigen/Geometry>

#include "common/cloud_io.hpp"
#include "common/clustering.hpp"
#include "common/map.hpp"
#include "common/preprocess.hpp"

namespace fogmap {
namespace {

const Cloud& scan(bool ground_removed) {
  static const Cloud full = [] {
    auto c = readCloud(std::string(FOGMAP_SOURCE_DIR) + "/data/kitti_raw_seq_a/0000000000.bin");
    return c ? c->points : Cloud{};
  }();
  static const Cloud no_ground = [] {
    auto g = removeGround(full, GroundParams{});
    return g ? g->non_ground : Cloud{};
  }();
  return ground_removed ? no_ground : full;
}

void clustering(benchmark::State& state, ClusteringMethod method, bool ground_removed) {
  const Cloud& cloud = scan(ground_removed);
  for (auto _ : state) benchmark::DoNotOptimize(clusterPoints(cloud, ClusteringParams{}, method));
  state.counters["points"] = static_cast<double>(cloud.size());
}
BENCHMARK_CAPTURE(clustering, fogmap_full_scan, ClusteringMethod::kFogmap, false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(clustering, pcl_unsorted_full_scan, ClusteringMethod::kPclUnsorted, false)->Unit(benchmark::kMillisecond)->Iterations(2);
BENCHMARK_CAPTURE(clustering, fogmap_ground_removed, ClusteringMethod::kFogmap, true)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(clustering, pcl_unsorted_ground_removed, ClusteringMethod::kPclUnsorted, true)->Unit(benchmark::kMillisecond)->Iterations(3);

void groundRemoval(benchmark::State& state) {
  const Cloud& cloud = scan(false);
  for (auto _ : state) benchmark::DoNotOptimize(removeGround(cloud, GroundParams{}));
}
BENCHMARK(groundRemoval)->Unit(benchmark::kMillisecond);

// The paper's Table 1 scenario: 7 nodes x 100 ellipsoids over a 50 x 50 m scene.
std::vector<Map> paperMaps() {
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> pos(-25.0, 25.0);
  std::uniform_real_distribution<double> axis(0.2, 1.5);
  std::normal_distribution<double> normal;
  std::vector<Map> maps;
  for (std::uint32_t node = 1; node <= 7; ++node) {
    std::vector<Ellipsoid> es;
    for (std::uint32_t k = 0; k < 100; ++k) {
      const Eigen::Matrix3d r =
          Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized().toRotationMatrix();
      Ellipsoid e;
      e.id = {node, 1, k};
      e.center = {pos(rng), pos(rng), 1.0};
      e.shape = r * Eigen::Vector3d(axis(rng), axis(rng), axis(rng)).cwiseAbs2().asDiagonal() * r.transpose();
      es.push_back(e);
    }
    maps.push_back(localMap(std::move(es)));
  }
  return maps;
}

void mergeSevenMaps(benchmark::State& state) {
  const auto maps = paperMaps();
  MergeStats stats;
  for (auto _ : state) {
    auto result = mergeAll(maps);
    stats = result.stats;
    benchmark::DoNotOptimize(result);
  }
  state.counters["pairs_all"] = static_cast<double>(stats.pairs_all);
  state.counters["pairs_tested"] = static_cast<double>(stats.pairs_tested);
  state.counters["pruning_ratio"] = static_cast<double>(stats.pairs_all) / static_cast<double>(std::max<std::uint64_t>(stats.pairs_tested, 1));
}
BENCHMARK(mergeSevenMaps)->Unit(benchmark::kMicrosecond);

void mergeSevenMapsAllPairs(benchmark::State& state) {
  const auto maps = paperMaps();
  std::vector<Ellipsoid> all;
  for (const auto& m : maps) {
    for (const auto& o : m.objects) all.insert(all.end(), o.ellipsoids.begin(), o.ellipsoids.end());
  }
  for (auto _ : state) benchmark::DoNotOptimize(mergeSpecification(all));
}
BENCHMARK(mergeSevenMapsAllPairs)->Unit(benchmark::kMicrosecond);

void intersectionTest(benchmark::State& state) {
  const auto maps = paperMaps();
  std::vector<std::pair<Ellipsoid, Ellipsoid>> pairs;
  for (std::size_t i = 0; i < 100; ++i) {
    Ellipsoid a = maps[0].objects[i].ellipsoids[0];
    Ellipsoid b = maps[1].objects[i].ellipsoids[0];
    b.center = a.center + Eigen::Vector3d(1.0, 0.5, 0.0) * (static_cast<double>(i % 10) * 0.2);  // near and far pairs
    pairs.emplace_back(a, b);
  }
  std::size_t k = 0;
  for (auto _ : state) {
    const auto& [a, b] = pairs[k++ % pairs.size()];
    benchmark::DoNotOptimize(intersects(a, b));
  }
}
BENCHMARK(intersectionTest);

}  // namespace
}  // namespace fogmap

BENCHMARK_MAIN();
