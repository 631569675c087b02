// The tracking pipeline as real processes on loopback: simulated LiDARs (edge-cluster), the root
// (merge-aggregator), two simulated cameras (detection, replaying the scene's objects with 30 %
// of them missed) and the tracker, started from a topology as fogctl up starts them. The tracks
// read from the tracker's stream are scored against the scene's truth at each LiDAR frame's
// instant.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <algorithm>
#include <map>
#include <mutex>
#include <thread>
#include <set>
#include <string>
#include <vector>

#include <grpcpp/grpcpp.h>

#include "common/sim/generators.hpp"
#include "common/sim/scene.hpp"
#include "common/sim/scene_topology.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "tests/support/free_ports.hpp"
#include "tests/support/scratch_dir.hpp"
#include "tools/fogctl/launcher.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

TEST(TrackingCluster, TracksFromLidarsAndCamerasFollowTheSimulatedPeopleWithTheirLabels) {
  test_support::ScratchDir dir("tracking");
  // 4 people and a car crossing a 40 x 40 m area, 4 LiDARs and 2 cameras around it.
  const sim::Scene scene = sim::movingScene(4, 1, 4, 2, 5);
  ASSERT_EQ(scene.cameras.size(), 2U);
  const fs::path scene_file = dir.path() / "scene.yaml";
  {
    std::ofstream out(scene_file);
    out << sim::toYaml(scene);
  }
  sim::SceneTopologyOptions options;
  options.tracker = true;
  options.truth = TruthReplayConfig{0.3, 1.0, 20.0};
  TopologyConfig topology = sim::sceneTopology(scene, "scene.yaml", options);
  topology.deadline_ms = 300.0;  // a loaded 2-core machine must not turn slow epochs into partial ones
  test_support::useFreePorts(topology);
  const fs::path topology_file = dir.path() / "topology.yaml";
  {
    std::ofstream out(topology_file);
    out << toYaml(topology);
  }
  const auto reloaded = loadTopology(topology_file);
  ASSERT_TRUE(reloaded.ok()) << reloaded.error().message;
  ASSERT_EQ(reloaded->camerasOf("tracker").size(), 2U);

  auto cluster = cli::startCluster(topology_file, *reloaded, dir.path() / "state", 60s);
  ASSERT_TRUE(cluster.ok()) << cluster.error().message;
  struct Stop {
    const cli::Cluster& cluster;
    ~Stop() { cli::stopCluster(cluster, 5s); }
  } stop{*cluster};

  // The root's global maps, by sensor time, read beside the tracks: what the LiDARs saw.
  const NodeConfig* root = reloaded->root();
  auto root_channel = makeChannel(root->host + ":" + std::to_string(root->port), 64U << 20);
  auto root_stub = v1::GlobalMapService::NewStub(root_channel);
  grpc::ClientContext root_context;
  root_context.set_deadline(std::chrono::system_clock::now() + 60s);
  v1::SubscribeRequest root_request;
  root_request.set_on_time_only(true);
  auto maps = root_stub->Subscribe(&root_context, root_request);
  std::mutex mutex;
  std::map<std::int64_t, Map> seen;  // by sensor time
  std::thread map_reader([&] {
    v1::GlobalMap message;
    while (maps->Read(&message)) {
      auto global = fromProto(message);
      if (!global) continue;
      std::lock_guard lock(mutex);
      seen[global->header.sensor_time_ns] = global->map;
    }
  });

  const NodeConfig* tracker = reloaded->find("tracker");
  auto channel = makeChannel(tracker->host + ":" + std::to_string(tracker->port), 64U << 20);
  auto stub = v1::TrackerService::NewStub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 60s);
  v1::TrackSubscribeRequest request;
  auto reader = stub->Subscribe(&context, request);

  // Score the track lists of 10 s (100 LiDAR frames) after a 3 s warm-up. A moving object the
  // LiDARs saw (a global-map object's footprint, grown by 0.5 m, holds its truth position) is
  // covered when a confirmed track lies within 1 m (a person) or 2.5 m (a car) of its truth position.
  const double period_s = reloaded->period_ms / 1000.0;
  v1::TrackList list;
  int lists = 0;
  int scored = 0;
  std::size_t observable = 0;
  std::size_t covered = 0;
  std::size_t labelled_right = 0;
  std::size_t labelled = 0;
  std::vector<double> person_errors;
  std::int64_t first_ns = 0;
  while (scored < 100 && reader->Read(&list)) {
    ++lists;
    if (first_ns == 0) first_ns = list.lidar_time_ns();
    if (list.lidar_time_ns() - first_ns < 3'000'000'000) continue;
    Map map;
    {
      std::lock_guard lock(mutex);
      const auto it = seen.find(list.lidar_time_ns());
      if (it == seen.end()) continue;  // the tracks of a map this reader did not get
      map = it->second;
    }
    ++scored;
    // The LiDAR frame's instant: scan floor(t / period) of a 10 Hz LiDAR (the edges' mapping).
    const auto scan = static_cast<std::uint64_t>(static_cast<double>(list.lidar_time_ns()) * 1e-9 / period_s);
    const double t = sim::sceneTime(scene, scan, 10.0);
    std::vector<tracking::Track> tracks;
    for (const auto& proto : list.tracks()) {
      const auto track = fromProto(proto);
      ASSERT_TRUE(track.ok()) << track.error().message;
      if (track->state == tracking::TrackState::kConfirmed) tracks.push_back(*track);
    }
    for (const auto& object : scene.objects) {
      const Eigen::Vector2d truth = sim::poseAt(object, t).xy;
      const bool in_map = std::any_of(map.objects.begin(), map.objects.end(), [&](const MapObject& o) {
        return truth.x() >= o.box.min.x() - 0.5 && truth.x() <= o.box.max.x() + 0.5 && truth.y() >= o.box.min.y() - 0.5 &&
               truth.y() <= o.box.max.y() + 0.5;
      });
      if (!in_map) continue;
      ++observable;
      const tracking::Track* best = nullptr;
      for (const auto& track : tracks) {
        if (!best || (track.position - truth).norm() < (best->position - truth).norm()) best = &track;
      }
      // A car's observation is the centroid of its visible side: up to half its length away.
      const double reach = object.label == "person" ? 1.0 : 2.5;
      if (!best || (best->position - truth).norm() > reach) continue;
      ++covered;
      if (object.label == "person") person_errors.push_back((best->position - truth).norm());
      if (best->label != tracking::kUnknownLabel) {
        ++labelled;
        labelled_right += best->label == object.label ? 1 : 0;
      }
    }
  }
  context.TryCancel();
  root_context.TryCancel();
  map_reader.join();
  const double coverage = static_cast<double>(covered) / static_cast<double>(std::max<std::size_t>(observable, 1));
  double person_error = 0.0;
  for (const double e : person_errors) person_error += e / static_cast<double>(person_errors.size());
  std::printf("tracking cluster: %zu of %zu observable truth positions covered (%.3f), people's mean error %.3f m over %zu, "
              "labels %zu of %zu right\n",
              covered, observable, coverage, person_error, person_errors.size(), labelled_right, labelled);
  ASSERT_EQ(scored, 100) << lists << " track lists in all";
  // Where the objects are depends on the wall clock (the scene loops every minute): at its ends
  // the LiDARs see less of them, but never nothing.
  ASSERT_GT(observable, 60U);
  EXPECT_GE(coverage, 0.8);
  ASSERT_FALSE(person_errors.empty());
  EXPECT_LT(person_error, 0.3);
  EXPECT_GT(labelled, covered / 2) << "most covered objects carry a camera's label";
  EXPECT_GE(static_cast<double>(labelled_right), 0.95 * static_cast<double>(labelled));
}

}  // namespace
}  // namespace fogmap
