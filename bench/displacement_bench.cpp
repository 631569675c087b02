// Google Benchmark: displacement centroids (the camera-LiDAR fusion paper's Algorithm 1) on two
// consecutive bundled KITTI HDL-64E scans, with the outdoor preset. Target: at most 10 ms a frame on
// one core. Run a Release build: build/bin/fogmap_bench --benchmark_filter=displacement
#include <benchmark/benchmark.h>

#include <array>
#include <string>

#include <pcl/octree/octree_pointcloud_changedetector.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include "common/io/cloud_io.hpp"
#include "common/tracking/displacement.hpp"

namespace fogmap {
namespace {

const std::array<Cloud, 2>& consecutiveScans() {
  static const std::array<Cloud, 2> scans = [] {
    std::array<Cloud, 2> s;
    for (int i = 0; i < 2; ++i) {
      const std::string path = std::string(FOGMAP_SOURCE_DIR) + "/data/kitti_raw_seq_a/000000000" + std::to_string(i) + ".bin";
      if (auto c = readKittiBin(path)) s[static_cast<std::size_t>(i)] = std::move(c->points);
    }
    return s;
  }();
  return scans;
}

void exportCounters(benchmark::State& state, std::size_t points, const tracking::DisplacementResult& r) {
  state.counters["points"] = static_cast<double>(points);
  state.counters["displacement_points"] = static_cast<double>(r.displacement_points);
  state.counters["clusters"] = static_cast<double>(r.clusters);
  state.counters["centroids"] = static_cast<double>(r.centroids.size());
}

// Steady state: each iteration is one frame against the previous one, frames 0 and 1 in turn, so
// every push compares two consecutive scans (forwards, then backwards).
void displacementConsecutiveFrames(benchmark::State& state) {
  const auto& scans = consecutiveScans();
  auto detector = tracking::DisplacementDetector::create(tracking::DisplacementParams::outdoor());
  if (!detector.ok() || scans[0].empty() || scans[1].empty()) {
    state.SkipWithError("no detector or no scans");
    return;
  }
  (void)detector->push(scans[0]);
  const tracking::DisplacementResult forward = detector->push(scans[1]);  // frame 1 against frame 0
  std::size_t next = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(detector->push(scans[next]));
    next ^= 1U;
  }
  exportCounters(state, scans[1].size(), forward);
}
BENCHMARK(displacementConsecutiveFrames)->Unit(benchmark::kMillisecond);

// The first frame: every point is displacement, so DBSCAN runs on the whole scan (once per sensor).
void displacementFirstFrame(benchmark::State& state) {
  const auto& scans = consecutiveScans();
  tracking::DisplacementResult last;
  for (auto _ : state) {
    auto detector = tracking::DisplacementDetector::create(tracking::DisplacementParams::outdoor());
    if (!detector.ok()) {
      state.SkipWithError(detector.error().message.c_str());
      return;
    }
    last = detector->push(scans[0]);
    benchmark::DoNotOptimize(last);
  }
  exportCounters(state, scans[0].size(), last);
}
BENCHMARK(displacementFirstFrame)->Unit(benchmark::kMillisecond)->Iterations(3);

// For comparison, step 1 to 10 alone (no DBSCAN) as Algorithm 1 words them: a fresh change detector
// per frame, the previous frame inserted, the buffers switched, the current frame inserted, its new
// voxels listed. The detector above keeps the tree between frames and inserts each frame once. (This
// tree anchors its voxels at the first point, not at the sensor, so its count differs a little.)
void displacementOctreeRebuiltEachFrame(benchmark::State& state) {
  const auto& scans = consecutiveScans();
  std::array<pcl::PointCloud<pcl::PointXYZ>::Ptr, 2> clouds;
  for (std::size_t i = 0; i < 2; ++i) {
    clouds[i] = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
    for (const Point& p : scans[i]) clouds[i]->push_back(pcl::PointXYZ(p.x, p.y, p.z));
  }
  pcl::Indices moved;
  for (auto _ : state) {
    pcl::octree::OctreePointCloudChangeDetector<pcl::PointXYZ> octree(tracking::DisplacementParams::outdoor().voxel_m);
    octree.setInputCloud(clouds[0]);
    octree.addPointsFromInputCloud();
    octree.switchBuffers();
    octree.setInputCloud(clouds[1]);
    octree.addPointsFromInputCloud();
    moved.clear();
    octree.getPointIndicesFromNewVoxels(moved);
    benchmark::DoNotOptimize(moved.data());
  }
  state.counters["points"] = static_cast<double>(scans[1].size());
  state.counters["displacement_points"] = static_cast<double>(moved.size());
}
BENCHMARK(displacementOctreeRebuiltEachFrame)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace fogmap
