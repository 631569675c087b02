// Google Benchmark: the tracker service's fusion step against what a LiDAR frame brings, to size the
// per-frame limits and read the fusion budget against (docs/design.md, "Tracker"). 6 people walk
// past 2 cameras that see them; every other observation is clutter at a new random place each frame
// (each one a new tentative track for tentative_timeout_s: the worst case for the step). Run a
// Release build: build/bin/fogmap_bench --benchmark_filter=tracker
#include <benchmark/benchmark.h>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "common/tracking/centroid_merge.hpp"
#include "common/tracking/tracker.hpp"

namespace fogmap {
namespace {

constexpr std::int64_t kPeriodNs = 100'000'000;
constexpr int kPeople = 6;

// A camera at `position` looking along +x (z up).
camera::PinholeCamera forwardCamera(const std::string& name, const Eigen::Vector3d& position) {
  camera::PinholeCamera cam;
  cam.name = name;
  cam.fx = cam.fy = 500.0;
  cam.cx = 320.0;
  cam.cy = 240.0;
  cam.width = 640;
  cam.height = 480;
  Eigen::Matrix3d r;
  r << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  cam.world_to_camera.linear() = r;
  cam.world_to_camera.translation() = -r * position;
  return cam;
}

Eigen::Vector3d personAt(int person, int frame) {
  return {10.0 + 2.0 * person, -3.0 + 0.1 * frame * (person % 2 == 0 ? 1.0 : -1.0) + 1.0 * person, 0.9};
}

struct Scenario {
  std::vector<camera::PinholeCamera> cameras;
  std::vector<tracking::CloudFrame> clouds;                    // one per frame
  std::vector<std::vector<tracking::DetectionFrame>> detections;  // per frame, one per camera
};

// `frames` frames of `observations` observations each (6 people, the rest clutter) and
// `detections_per_camera` detections per camera frame (the people's, the rest boxes on clutter).
Scenario scenario(int frames, int observations, int detections_per_camera) {
  Scenario s;
  s.cameras = {forwardCamera("cam-a", {0, 0, 1.5}), forwardCamera("cam-b", {0, 6, 1.5})};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> x(5.0, 105.0);
  std::uniform_real_distribution<double> y(-50.0, 50.0);
  for (int f = 0; f < frames; ++f) {
    tracking::CloudFrame cloud;
    cloud.time_ns = f * kPeriodNs;
    for (int i = 0; i < observations; ++i) {
      tracking::CloudObservation o;
      o.position = i < kPeople ? personAt(i, f) : Eigen::Vector3d(x(rng), y(rng), 0.9);
      o.covariance = Eigen::Matrix3d::Identity() * 0.02;
      o.point_count = 40;
      cloud.observations.push_back(o);
    }
    std::vector<tracking::DetectionFrame> per_camera;
    for (const auto& cam : s.cameras) {
      tracking::DetectionFrame d{cam.name, cloud.time_ns, {}};
      for (int i = 0; i < observations && static_cast<int>(d.detections.size()) < detections_per_camera; ++i) {
        const auto pixel = cam.project(cloud.observations[static_cast<std::size_t>(i)].position);
        if (!pixel) continue;
        camera::Detection det;
        det.box = {pixel->x() - 15, pixel->y() - 40, pixel->x() + 15, pixel->y() + 40};
        det.label = i < kPeople ? "person" : "car";
        det.score = 0.9;
        d.detections.push_back(det);
      }
      per_camera.push_back(std::move(d));
    }
    s.clouds.push_back(std::move(cloud));
    s.detections.push_back(std::move(per_camera));
  }
  return s;
}

// One fusion step (synchronise, predict, associate, update, spawn, prune) per iteration, in steady
// state (the clutter's tentative tracks of the last frames alive).
void trackerStep(benchmark::State& state) {
  const int observations = static_cast<int>(state.range(0));
  const int detections = static_cast<int>(state.range(1));
  constexpr int kFrames = 40;
  const Scenario s = scenario(kFrames, observations, detections);
  auto tracker = tracking::Tracker::create({}, s.cameras);
  if (!tracker) {
    state.SkipWithError(tracker.error().message.c_str());
    return;
  }
  std::int64_t frame = 0;
  const auto step = [&] {
    const auto& cloud = s.clouds[static_cast<std::size_t>(frame % kFrames)];
    tracking::CloudFrame now = cloud;
    now.time_ns = frame * kPeriodNs;
    for (auto d : s.detections[static_cast<std::size_t>(frame % kFrames)]) {
      d.capture_time_ns = now.time_ns;
      tracker->addDetections(std::move(d));
    }
    benchmark::DoNotOptimize(tracker->addCloud(now));
    ++frame;
  };
  for (int warm = 0; warm < 10; ++warm) step();
  for (auto _ : state) step();
  state.counters["tracks"] = static_cast<double>(tracker->tracks().size());
  state.counters["per_observation_us"] =
      benchmark::Counter(static_cast<double>(observations) * 1e-6, benchmark::Counter::kIsIterationInvariantRate |
                                                                       benchmark::Counter::kInvert);
}
BENCHMARK(trackerStep)
    ->Args({10, 10})
    ->Args({100, 20})
    ->Args({300, 20})
    ->Args({1000, 20})
    ->Args({2000, 20})
    ->Args({3000, 20})
    ->Args({1000, 200})
    ->Args({1000, 1000})
    ->Unit(benchmark::kMillisecond);

// One epoch's centroids from 4 edges merged into observations (the collector, before the step).
void centroidMerge(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> x(0.0, 200.0);
  std::vector<tracking::DisplacementCentroid> centroids(n);
  for (auto& c : centroids) {
    c.position = {x(rng), x(rng), 0.9};
    c.covariance = Eigen::Matrix3d::Identity() * 0.02;
    c.point_count = 30;
  }
  for (auto _ : state) benchmark::DoNotOptimize(tracking::mergeCentroids(centroids, 1.0));
}
BENCHMARK(centroidMerge)->Arg(1000)->Arg(4000)->Arg(40000)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace fogmap
