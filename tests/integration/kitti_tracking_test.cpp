// Tracking on real data, as real processes: one edge replaying the bundled KITTI raw scans (an ego
// car in traffic, 5 frames at 10 Hz, looped), the root, a camera running the HOG people detector
// on the same drive's images, and the tracker. The cars ahead of the ego car must keep their track
// ids from frame to frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/camera/kitti.hpp"
#include "common/config/topology.hpp"
#include "common/config/tracker_node.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/proto_convert.hpp"
#include "tests/support/cluster_streams.hpp"
#include "tests/support/free_ports.hpp"
#include "tests/support/process_cluster.hpp"
#include "tests/support/scratch_dir.hpp"
#include "tests/support/topology_builders.hpp"
#include "harness/launcher.hpp"

namespace fogmap {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using test_support::node;

const fs::path kDrive = fs::path(FOGMAP_SOURCE_DIR) / "data" / "kitti_raw_seq_a";
constexpr std::uint64_t kScans = 5;

TopologyConfig kittiTopology() {
  TopologyConfig topology;
  topology.name = "kitti-tracking";
  topology.deadline_ms = 300.0;  // a loaded 2-core machine must not turn slow epochs into partial ones
  topology.preprocess.crop = CropBox{Eigen::Vector3d(-40, -40, -3), Eigen::Vector3d(40, 40, 3)};
  GroundParams ground;
  ground.distance_threshold_m = 0.2;
  ground.ground_z_hint_m = -1.73;  // the HDL-64E is 1.73 m above the road
  topology.preprocess.ground = ground;
  NodeConfig edge = node(1, "edge", Role::kEdge, "root");
  SensorConfig sensor;
  sensor.source = kDrive;
  sensor.rate_hz = 10.0;
  sensor.loop = true;
  edge.sensor = sensor;
  NodeConfig tracker = node(50, "tracker", Role::kTracker, "");
  tracker.tracker = TrackerNodeConfig{};
  topology.nodes = {node(100, "root", Role::kAggregator, ""), edge, tracker};
  return topology;
}

TEST(KittiTracking, TheCarsAheadKeepTheirTrackIdsFromFrameToFrame) {
  test_support::ScratchDir dir("kitti-tracking");
  TopologyConfig topology = kittiTopology();
  test_support::useFreePorts(topology);
  const fs::path topology_file = dir.path() / "topology.yaml";
  const auto reloaded = test_support::writeTopology(topology_file, topology);
  ASSERT_TRUE(reloaded.ok()) << reloaded.error().message;
  auto cluster = harness::startCluster(topology_file, *reloaded, dir.path() / "state", 60s);
  ASSERT_TRUE(cluster.ok()) << cluster.error().message;
  const test_support::StopOnExit stop(*cluster);

  // The root's global maps by sensor time: the oracle for which objects are the cars ahead.
  test_support::GlobalMapRecorder maps(*reloaded->root(), 60s);

  test_support::TrackStream track_lists(*reloaded->find("tracker"), 60s);

  // After a warm-up of one pass (tracks confirm after 3 hits), 3 passes over the 5 scans. In each
  // frame, the cars ahead are the global map's car-sized obstacles in the ego lane (|y| below
  // 1.5 m, 4 to 25 m ahead); each must have a confirmed track within 2.5 m of its box centre, and
  // the ids of those tracks must be the same in every frame (the ego car stands in traffic here:
  // the cars ahead stay where they are, so one id each, whatever the scan). Further out, the car
  // at 29 m is an object in only 3 of the 5 scans (its rear has too few points in the others).
  constexpr int kWarmUp = static_cast<int>(kScans);
  constexpr int kScored = 3 * static_cast<int>(kScans);
  v1::TrackList list;
  int lists = 0;
  int scored = 0;
  std::set<std::uint64_t> first_ids;
  std::size_t cars_seen = 0;
  while (scored < kScored && lists < 200 && track_lists.read(list)) {
    ++lists;
    if (lists <= kWarmUp) continue;
    const std::optional<Map> map = maps.find(list.lidar_time_ns());
    if (!map) continue;  // the tracks of a map the recorder did not get
    ++scored;
    std::vector<tracking::Track> confirmed;
    for (const auto& proto : list.tracks()) {
      const auto track = fromProto(proto);
      ASSERT_TRUE(track.ok()) << track.error().message;
      if (track->state == tracking::TrackState::kConfirmed) confirmed.push_back(*track);
    }
    std::set<std::uint64_t> ids;
    for (const MapObject& object : map->objects) {
      const Eigen::Vector2d centre = (0.5 * (object.box.min + object.box.max)).head<2>();
      const Eigen::Vector2d extent = (object.box.max - object.box.min).head<2>();
      if (std::abs(centre.y()) >= 1.5 || centre.x() < 4.0 || centre.x() > 25.0 || extent.maxCoeff() < 1.0) continue;
      ++cars_seen;
      const tracking::Track* nearest = nullptr;
      for (const tracking::Track& track : confirmed) {
        if (!nearest || (track.position - centre).norm() < (nearest->position - centre).norm()) nearest = &track;
      }
      ASSERT_NE(nearest, nullptr) << "no confirmed track at all in frame " << scored;
      EXPECT_LT((nearest->position - centre).norm(), 2.5)
          << "the car ahead at (" << centre.x() << ", " << centre.y() << ") has no confirmed track near it";
      ids.insert(nearest->id);
    }
    if (first_ids.empty()) first_ids = ids;
    EXPECT_EQ(ids, first_ids) << "the cars ahead changed track ids in frame " << scored << " (sensor time "
                              << list.lidar_time_ns() << ")";
  }
  track_lists.cancel();
  maps.stop();
  std::printf("kitti tracking: %d frames scored, %zu car observations ahead, track ids:", scored, cars_seen);
  for (const std::uint64_t id : first_ids) std::printf(" %lu", static_cast<unsigned long>(id));
  std::printf("\n");
  ASSERT_EQ(scored, kScored) << lists << " track lists in all";
  // The drive's scans show two cars ahead in the lane within 25 m (at 7.6 and 19.3 m); in some
  // scans MAD-C cuts one of them into two objects, which the tracker's ground merge makes one.
  EXPECT_EQ(first_ids.size(), 2U);
  EXPECT_GE(cars_seen, 2U * static_cast<std::size_t>(kScored));
}

}  // namespace
}  // namespace fogmap
