// The tracking pipeline as real processes on loopback: simulated LiDARs (edge-cluster), the root
// (merge-aggregator), two simulated cameras (detection, replaying the scene's objects with 30 %
// of them missed) and the tracker, started from a topology as fogctl up starts them. The tracks
// read from the tracker's stream are scored against the scene's truth at each LiDAR frame's
// instant.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/base/epochs.hpp"
#include "common/sim/generators.hpp"
#include "common/sim/scene.hpp"
#include "common/sim/scene_topology.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/proto_convert.hpp"
#include "tests/support/cluster_streams.hpp"
#include "tests/support/free_ports.hpp"
#include "tests/support/process_cluster.hpp"
#include "tests/support/scratch_dir.hpp"
#include "harness/launcher.hpp"
#include "pictures/scene_picture.hpp"
#include "harness/scene_run.hpp"
#include "harness/track_scoring.hpp"

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
  // As fogctl demo runs a scene: the edges fit boxes and class them, so the tracker measures the car
  // at its box and the cameras' detections overlay the boxes (a person passing 0.5 m beside the car
  // is told from it).
  options.mapping.objects.boxes = true;
  options.mapping.objects.classifier = fs::path(FOGMAP_SOURCE_DIR) / "data" / "models" / "lidar_classifier.yml.gz";
  TopologyConfig topology = sim::sceneTopology(scene, "scene.yaml", options);
  topology.deadline_ms = 300.0;  // a loaded 2-core machine must not turn slow epochs into partial ones
  test_support::useFreePorts(topology);
  const fs::path topology_file = dir.path() / "topology.yaml";
  const auto reloaded = test_support::writeTopology(topology_file, topology);
  ASSERT_TRUE(reloaded.ok()) << reloaded.error().message;
  ASSERT_EQ(reloaded->camerasOf("tracker").size(), 2U);

  auto cluster = harness::startCluster(topology_file, *reloaded, dir.path() / "state", 60s);
  ASSERT_TRUE(cluster.ok()) << cluster.error().message;
  const test_support::StopOnExit stop(*cluster);

  // The root's global maps, by sensor time, read beside the tracks: what the LiDARs saw.
  test_support::GlobalMapRecorder maps(*reloaded->root(), 60s);

  test_support::TrackStream track_lists(*reloaded->find("tracker"), 60s);

  // Score the track lists of 10 s (100 LiDAR frames) after a 3 s warm-up. A moving object the
  // LiDARs saw (a global-map object's footprint, grown by 0.5 m, holds its truth position) is
  // covered when a confirmed track, one per object, lies within 1 m (a person) or 2.5 m (a car) of its
  // truth position.
  // Every scored frame also goes to the CLEAR MOT and IDF1 scoring fogctl demo and track-eval use.
  const auto schedule = EpochSchedule::create(reloaded->period_ms, reloaded->deadline_ms);
  ASSERT_TRUE(schedule.ok());
  v1::TrackList list;
  int lists = 0;
  int scored = 0;
  std::size_t observable = 0;
  std::size_t covered = 0;
  std::size_t labelled_right = 0;
  std::size_t labelled = 0;
  std::vector<double> person_errors;
  std::vector<harness::TrackingFrame> frames;
  std::int64_t first_ns = 0;
  while (scored < 100 && track_lists.read(list)) {
    ++lists;
    if (first_ns == 0) first_ns = list.lidar_time_ns();
    if (list.lidar_time_ns() - first_ns < 3'000'000'000) continue;
    const std::optional<Map> map = maps.find(list.lidar_time_ns());
    if (!map) continue;  // the tracks of a map the recorder did not get
    ++scored;
    // The LiDAR frame's instant: the scan its epoch replays, as the edges pick it.
    const double t = harness::sceneTimeOf(scene, *schedule, 1000.0 / reloaded->period_ms, list.lidar_time_ns());
    std::vector<tracking::Track> tracks;
    for (const auto& proto : list.tracks()) {
      const auto track = fromProto(proto);
      ASSERT_TRUE(track.ok()) << track.error().message;
      tracks.push_back(*track);
    }
    frames.push_back(harness::trackingFrame(scene, t, tracks));
    const harness::TrackingFrame& frame = frames.back();
    // Each observable object (a global-map object's footprint, grown by 0.5 m, holds its truth
    // position) against the confirmed tracks, one track per object: the nearest pairs first, a
    // pair within reach (a car's observation is the centroid of its visible side: up to half its
    // length away). A person 0.5 m beside a car is matched to its own track, not the car's.
    struct Pair {
      double distance;
      std::size_t truth;
      std::size_t track;
    };
    std::vector<Pair> pairs;
    for (std::size_t i = 0; i < frame.mot.truth.size(); ++i) {
      const Eigen::Vector2d truth = frame.mot.truth[i].position;
      const bool in_map = std::any_of(map->objects.begin(), map->objects.end(), [&](const MapObject& o) {
        return truth.x() >= o.box.min.x() - 0.5 && truth.x() <= o.box.max.x() + 0.5 && truth.y() >= o.box.min.y() - 0.5 &&
               truth.y() <= o.box.max.y() + 0.5;
      });
      if (!in_map) continue;
      ++observable;
      const double reach = frame.truth_labels[i] == "person" ? 1.0 : 2.5;
      for (std::size_t k = 0; k < tracks.size(); ++k) {
        const double d = (tracks[k].position - truth).norm();
        if (tracks[k].state == tracking::TrackState::kConfirmed && d <= reach) pairs.push_back({d, i, k});
      }
    }
    std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.distance < b.distance; });
    std::vector<bool> truth_taken(frame.mot.truth.size(), false), track_taken(tracks.size(), false);
    for (const Pair& pair : pairs) {
      if (truth_taken[pair.truth] || track_taken[pair.track]) continue;
      truth_taken[pair.truth] = track_taken[pair.track] = true;
      const std::string& label = frame.truth_labels[pair.truth];
      const tracking::Track& best = tracks[pair.track];
      ++covered;
      if (label == "person") person_errors.push_back(pair.distance);
      if (best.label != tracking::kUnknownLabel) {
        ++labelled;
        labelled_right += best.label == label ? 1 : 0;
      }
    }
  }
  track_lists.cancel();
  maps.stop();
  const double coverage = static_cast<double>(covered) / static_cast<double>(std::max<std::size_t>(observable, 1));
  double person_error = 0.0;
  for (const double e : person_errors) person_error += e / static_cast<double>(person_errors.size());
  std::printf("tracking cluster: %zu of %zu observable truth positions covered (%.3f), people's mean error %.3f m over %zu, "
              "labels %zu of %zu right\n",
              covered, observable, coverage, person_error, person_errors.size(), labelled_right, labelled);
  ASSERT_EQ(scored, 100) << lists << " track lists in all";
  const auto mot = harness::scoreTracking(frames);
  ASSERT_TRUE(mot.ok()) << mot.error().message;
  std::printf("tracking cluster, every moving object (1 m gate): MOTA %.3f, IDF1 %.3f, %zu ID switches, error mean %.3f m",
              mot->mot.clear.mota, mot->mot.identity.idf1, mot->mot.clear.id_switches, mot->mot.localization.mean_m);
  for (const auto& [label, report] : mot->by_label) {
    std::printf("; %s MOTA %.3f IDF1 %.3f", label.c_str(), report.clear.mota, report.identity.idf1);
  }
  std::printf("\n");
  // Where the objects are depends on the wall clock (the scene loops every minute): at its ends
  // the LiDARs see less of them, but never nothing.
  ASSERT_GT(observable, 60U);
  EXPECT_GE(coverage, 0.8);
  ASSERT_FALSE(person_errors.empty());
  EXPECT_LT(person_error, 0.3);
  EXPECT_GT(labelled, covered / 2) << "most covered objects carry a camera's label";
  EXPECT_GE(static_cast<double>(labelled_right), 0.95 * static_cast<double>(labelled));
}

// fogctl demo --scene's tracking run (harness/scene_run): the cluster of `fogctl topology
// --scene F --tracker` as processes, its tracker's published tracks read, placed at their scene
// instants and scored against the truth, and drawn.
TEST(TrackingCluster, TheDemosTrackingRunScoresThePublishedTracksAgainstTheTruth) {
  test_support::ScratchDir dir("demo-tracking");
  // Four people walking apart (seed 7: no two come within 1.8 m), 4 LiDARs, 2 cameras. The scene
  // loops every minute on the wall clock, so the scored window falls anywhere in it: with the LiDARs
  // in the four corners, around 13 to 17 s every person is 16 to 23 m from the nearest one (too few
  // points for an object), and the window had nothing to track. With the fourth LiDAR in the middle,
  // at least 3 of the 4 are within 15 m of one at every instant.
  sim::Scene scene = sim::movingScene(4, 0, 4, 2, 7);
  ASSERT_EQ(scene.lidars.size(), 4U);
  scene.lidars[3].pose.translation() = Eigen::Vector3d(0, 0, scene.lidars[3].pose.translation().z());
  const fs::path scene_file = dir.path() / "scene.yaml";
  {
    std::ofstream out(scene_file);
    out << sim::toYaml(scene);
  }
  ASSERT_TRUE(harness::tracksScene(scene));
  harness::SceneTrackingOptions options;
  options.free_ports = true;
  options.warmup_lists = 30;
  options.scored_lists = 40;
  const auto run = harness::runSceneTracking(dir.path(), scene_file, scene, options);
  ASSERT_TRUE(run.ok()) << run.error().message;
  const auto scored = harness::scoreSceneTracking(scene, *run, options);
  ASSERT_TRUE(scored.ok()) << scored.error().message;
  std::printf("%s", harness::sceneTrackingText(*scored, options, 4).c_str());

  // The window: 40 lists after 30, their scene instants one frame apart within one cycle.
  EXPECT_EQ(scored->frames, 40U);
  EXPECT_GE(scored->first_list, 30U);
  // One frame apart at the least. Lists are lost on the way when the machine is slow (a subscriber
  // that falls behind loses the oldest lists queued for it, counted by the tracker): with two busy
  // processes, the suite and a browser beside it, 9 of 49 were lost once; never the whole window.
  EXPECT_GE(scored->last_time_s - scored->first_time_s, 3.9 - 0.05) << "lists one frame apart at the least";
  EXPECT_LT(scored->last_time_s - scored->first_time_s, 2 * 3.9) << "fewer lists lost on the way than scored";
  const auto& mot = scored->scores.mot;
  EXPECT_EQ(mot.clear.truth_count, 4U * 40U);
  EXPECT_GT(mot.clear.matches, 20U) << "the tracks follow the people the LiDARs see (those nearer a LiDAR than about 15 m)";
  EXPECT_LT(mot.localization.mean_m, 0.4) << "a person's observation is the near side of its body";
  EXPECT_GE(scored->scores.tracks_confirmed, 1U);
  ASSERT_EQ(scored->scores.by_label.size(), 1U);
  EXPECT_EQ(scored->scores.by_label[0].first, "person");
  // From the LiDAR frame's sensor time to its tracks: at least the cameras' 50 ms latency (the
  // frame waits for their detections), at most the wait's 250 ms bound and a margin.
  EXPECT_GE(scored->latency_p50_ms, options.truth.latency_ms);
  EXPECT_LE(scored->latency_p50_ms, scored->latency_p95_ms);
  EXPECT_LE(scored->latency_p95_ms, scored->latency_max_ms);
  EXPECT_LT(scored->latency_p50_ms, 1000.0);

  const std::string json = harness::sceneTrackingJson(*scored, options, 4);
  for (const char* key : {"\"mota\": ", "\"motp_m\": ", "\"id_switches\": ", "\"idf1\": ", "\"loc_error_mean_m\": ",
                          "\"loc_error_max_m\": ", "\"tracks_confirmed\": ", "\"fragmentations\": ", "\"e2e_p50_ms\": "}) {
    EXPECT_NE(json.find(key), std::string::npos) << key << " in " << json;
  }
  EXPECT_EQ(json.find("nan"), std::string::npos) << json;

  // The picture of the last scored list, with the tracks held then (birdseye_test checks how they
  // are drawn).
  const std::size_t last = scored->first_list + scored->frames - 1;
  const auto tracks = pictures::birdseyeTracks(run->lists, last, 30);
  EXPECT_TRUE(std::any_of(tracks.begin(), tracks.end(), [](const pictures::BirdseyeTrack& t) { return t.confirmed && !t.trail.empty(); }))
      << tracks.size() << " tracks";
  const fs::path png = dir.path() / "tracks.png";
  const Status drawn = pictures::drawSceneTracks(png, scene, *run, last, 30);
  ASSERT_TRUE(drawn.ok()) << drawn.error().message;
  EXPECT_GT(fs::file_size(png), 20000U);
}

}  // namespace
}  // namespace fogmap
