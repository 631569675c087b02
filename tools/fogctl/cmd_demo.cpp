// fogctl demo: a local MAD-C cluster and the baseline over the same real frames, side by side:
// objects, bytes per frame, merge and end-to-end latency, Rand index against the baseline, a
// bird's-eye PNG of the global map and a JSON report. On a moving simulated scene with cameras,
// also the tracker and the detection services, their tracks scored against the truth.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <optional>

#include "common/base/text.hpp"
#include "common/config/topology.hpp"
#include "common/config/topology_presets.hpp"
#include "common/config/tracker_node.hpp"
#include "common/sim/scene.hpp"
#include "common/tracking/tracker_config.hpp"
#include "harness/cluster_run.hpp"
#include "harness/demo_report.hpp"
#include "harness/launcher.hpp"
#include "harness/report_text.hpp"
#include "harness/scene_run.hpp"
#include "harness/track_scoring.hpp"
#include "pictures/birdseye.hpp"
#include "pictures/scene_picture.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using harness::EdgeView;
using harness::Json;
using harness::RunOptions;
using harness::SceneRunOptions;
using harness::SceneTrackingOptions;
using harness::binaryDir;
using harness::installStopHandlers;
using harness::jsonNumber;
using harness::jsonText;
using harness::lastCompleteView;
using harness::missedObjectCentres;
using harness::movingObjects;
using harness::runCluster;
using harness::runScene;
using harness::recordedReport;
using harness::recordedScoresText;
using harness::runSceneTracking;
using harness::sceneScoresReport;
using harness::sceneScoresText;
using harness::sceneTrackingReport;
using harness::sceneTrackingText;
using harness::scoreRecordedRuns;
using harness::scoreSceneRuns;
using harness::scoreSceneTracking;
using harness::stopRequested;
using harness::tracksScene;
using harness::writeCycledScene;
using pictures::BirdseyeScene;
using pictures::drawBirdseye;
using pictures::drawSceneBirdseye;
using pictures::drawSceneTracks;

// The bird's-eye picture of a global map of recorded scans: the edges' points, the global objects
// and the recording's LiDAR (every virtual LiDAR is a sector of it, at its place).
Status drawRecordedBirdseye(const std::filesystem::path& png, const GlobalMapMessage& global, const EdgeView& view, int lidars) {
  BirdseyeScene picture;
  picture.title = "fogmap global map, epoch " + std::to_string(global.header.epoch) + ": " +
                  std::to_string(global.map.objects.size()) + " objects from " + std::to_string(lidars) + " virtual LiDARs";
  picture.half_extent_m = 40.0;
  for (const auto& [node, points] : view.points) picture.points.emplace_back(points);
  picture.objects = global.map.objects;
  picture.sensors = {{"LiDAR", Eigen::Isometry3d::Identity(), 0.0}};
  return drawBirdseye(png, picture);
}

std::filesystem::path defaultInput() {
  for (const auto& candidate : {binaryDir() / ".." / ".." / "data" / "kitti_raw_seq_a", std::filesystem::path("data/kitti_raw_seq_a")}) {
    if (std::filesystem::is_directory(candidate)) return std::filesystem::canonical(candidate);
  }
  return {};
}

// fogctl demo --scene: the scene's LiDARs as edges, MAD-C (ext) and the baseline, both scored
// against the baseline and the truth.
int runSceneDemo(const Args& args) {
  const std::filesystem::path scene_path = std::filesystem::absolute(args.get("scene"));
  auto scene = sim::loadScene(scene_path);
  if (!scene) return fail(scene.error(), "fogctl demo");
  if (scene->lidars.empty()) return fail(invalidArgument("the scene " + scene_path.string() + " has no LiDAR"), "fogctl demo");
  const auto frames = args.getInt("frames", 10);
  const auto base = args.getInt("base-port", 46000);
  const auto alpha = args.getDouble("alpha", 1.5);
  if (!frames || *frames < 1 || *frames > 1000) return fail(invalidArgument("--frames must be in [1, 1000]"), "fogctl demo");
  if (!base || *base < 1024 || *base > 60000) return fail(invalidArgument("--base-port must be in [1024, 60000]"), "fogctl demo");
  if (!alpha || !(*alpha > 0.0)) return fail(invalidArgument("--alpha must be positive"), "fogctl demo");
  const std::string shape = args.get("topology", "star");
  if (shape != "star" && shape != "tree") return fail(invalidArgument("--topology must be star or tree"), "fogctl demo");
  const std::filesystem::path dir = args.get("state", ".fogmap/demo");
  // On a moving scene with cameras, the tracker and a detection service per camera run too.
  const bool tracks = tracksScene(*scene);
  const sim::Scene uncycled = *scene;
  SceneTrackingOptions tracking_options;
  if (!tracks && (args.has("miss-rate") || args.has("association") || args.has("tracker-input") || args.has("track-frames") ||
                  args.has("scene-start"))) {
    return fail(invalidArgument("--miss-rate, --association, --tracker-input, --track-frames and --scene-start need a scene with "
                                "moving objects and cameras"),
                "fogctl demo");
  }
  {
    const auto miss = args.getDouble("miss-rate", tracking_options.truth.miss_rate);
    if (!miss || !(*miss >= 0.0 && *miss <= 1.0)) return fail(invalidArgument("--miss-rate must be in [0, 1]"), "fogctl demo");
    tracking_options.truth.miss_rate = *miss;
    const auto association = tracking::parseAssociation(args.get("association", "kalman"));
    if (!association) return fail(invalidArgument("--association: " + association.error().message), "fogctl demo");
    tracking_options.association = *association;
    const auto input = parseTrackerInput(args.get("tracker-input", trackerInputName(tracking_options.input)));
    if (!input) return fail(invalidArgument("--tracker-input: " + input.error().message), "fogctl demo");
    tracking_options.input = *input;
    const auto track_frames = args.getInt("track-frames", static_cast<long>(tracking_options.scored_lists));
    if (!track_frames || *track_frames < 1 || *track_frames > 3000) {
      return fail(invalidArgument("--track-frames must be in [1, 3000]"), "fogctl demo");
    }
    tracking_options.scored_lists = static_cast<std::size_t>(*track_frames);
    if (args.has("scene-start")) {
      // The scored lists and the warm-up before them fit in one cycle of the scene.
      const auto start = args.getDouble("scene-start", 0.0);
      const double warmup_s = static_cast<double>(tracking_options.warmup_lists) / tracking_options.rate_hz;
      const double scored_s = static_cast<double>(tracking_options.scored_lists) / tracking_options.rate_hz;
      if (!start || !(*start >= warmup_s && *start + scored_s <= scene->duration_s)) {
        return fail(invalidArgument("--scene-start must be a scene time in [" + readableNumber(warmup_s) + ", " +
                                    readableNumber(scene->duration_s - scored_s) + "] s: the " +
                                    std::to_string(tracking_options.warmup_lists) + " lists of warm-up before it and the " +
                                    std::to_string(tracking_options.scored_lists) + " scored after it (--track-frames) " +
                                    "fit in the scene's " + readableNumber(scene->duration_s) + " s cycle"),
                    "fogctl demo");
      }
      tracking_options.scene_start_s = *start;
    }
    tracking_options.base_port = static_cast<int>(*base) + 800;
  }
  // A scene's edges fit boxes and classify (the bundled model) unless --objects says otherwise: the
  // tracker measures vehicles at their boxes and fuses camera detections by them.
  sim::SceneMapping scene_defaults;
  scene_defaults.objects.boxes = true;
  scene_defaults.objects.classifier = bundledClassifierModel();
  const auto mapping = sceneMapping(args, scene_defaults);
  if (!mapping) return fail(mapping.error(), "fogctl demo");
  tracking_options.mapping = *mapping;
  installStopHandlers();
  SceneRunOptions options;
  options.mapping = *mapping;
  options.alpha = *alpha;
  options.tree = shape == "tree";
  options.base_port = static_cast<int>(*base);
  options.frames = static_cast<std::uint64_t>(*frames);
  // Both clusters replay the scene's first frames in a loop, so that they see the same frames.
  const auto cycled = writeCycledScene(dir, *scene, options.frames, options.rate_hz);
  if (!cycled) return fail(cycled.error(), "fogctl demo");
  std::printf("fogmap demo: scene %s (%zu objects, %zu LiDARs), %s topology, %lu frames at %.0f Hz, alpha %.2f\n",
              scene_path.c_str(), scene->objects.size(), scene->lidars.size(), shape.c_str(),
              static_cast<unsigned long>(options.frames), options.rate_hz, *alpha);
  std::printf("running the MAD-C-ext cluster (%zu edges)...\n", scene->lidars.size());
  options.mode = Mode::kExt;
  auto madc = runScene(dir, *cycled, *scene, options);
  if (!madc) return fail(madc.error(), "fogctl demo");
  if (stopRequested()) return 1;
  std::printf("running the baseline cluster (ship all points, cluster at the sink)...\n");
  options.mode = Mode::kBaseline;
  options.base_port += 400;
  auto baseline = runScene(dir, *cycled, *scene, options);
  if (!baseline) return fail(baseline.error(), "fogctl demo");
  const auto scores = scoreSceneRuns(*scene, *madc, &*baseline);
  if (!scores) return fail(scores.error(), "fogctl demo");
  std::fputs(sceneScoresText(*scores).c_str(), stdout);

  const std::filesystem::path png = args.get("png", (dir / "global_map.png").string());
  if (auto last = lastCompleteView(*madc)) {
    const GlobalMapMessage& g = madc->result.epochs.at(last->first);
    auto missed = missedObjectCentres(*scene, *madc, last->first, last->second);
    if (!missed) return fail(missed.error(), "fogctl demo");
    const std::size_t missed_count = missed->size();
    if (Status drawn = drawSceneBirdseye(png, g, last->second, *scene, madc->topology, "MAD-C global map", {}, std::move(*missed));
        !drawn) {
      return fail(drawn.error(), "fogctl demo");
    }
    std::printf("  bird's-eye view of epoch %lu (%zu true objects missed, marked): %s\n", static_cast<unsigned long>(last->first),
                missed_count, png.c_str());
  }
  std::optional<Json> tracking_report;
  if (tracks) {
    if (stopRequested()) return 1;
    std::printf("\nrunning the tracking cluster (%zu edges, a detection service per camera replaying the truth with %.0f %% "
                "missed, the tracker with association %s on %s)...\n",
                uncycled.lidars.size(), 100.0 * tracking_options.truth.miss_rate,
                tracking::associationName(tracking_options.association), trackerInputName(tracking_options.input));
    auto run = runSceneTracking(dir, scene_path, uncycled, tracking_options);
    if (!run) return fail(run.error(), "fogctl demo");
    const auto scored = scoreSceneTracking(uncycled, *run, tracking_options);
    if (!scored) return fail(scored.error(), "fogctl demo");
    const std::size_t moving = movingObjects(uncycled).size();
    std::fputs(sceneTrackingText(*scored, tracking_options, moving).c_str(), stdout);
    tracking_report = sceneTrackingReport(*scored, tracking_options, moving);
    const std::filesystem::path tracks_png = args.get("tracks-png", (dir / "tracks.png").string());
    const std::size_t last_scored = scored->first_list + scored->frames - 1;
    constexpr std::size_t kTrailLists = 30;  // 3 s at 10 Hz
    if (Status drawn = drawSceneTracks(tracks_png, uncycled, *run, last_scored, kTrailLists); !drawn) {
      return fail(drawn.error(), "fogctl demo");
    }
    std::printf("  bird's-eye view of the last scored track list, with 3 s trails: %s\n", tracks_png.c_str());
    const std::filesystem::path track_lists = dir / "track_lists.jsonl";
    const auto lines = sceneTrackListsJsonLines(uncycled, *run, *scored, tracking_options);
    if (!lines) return fail(lines.error(), "fogctl demo");
    if (Status written = harness::writeTextFile(track_lists, *lines); !written) return fail(written.error(), "fogctl demo");
    std::printf("  the scored track lists and the truth, one JSON line a list: %s\n", track_lists.c_str());
  }
  const std::filesystem::path report = args.get("report", (dir / "report.json").string());
  Json j;
  j["scene"] = scene_path.string();
  j["topology"] = shape;
  j["nodes"] = scene->lidars.size();
  j["alpha"] = jsonNumber(*alpha);
  j.update(sceneScoresReport(*scores));
  if (tracking_report) j["tracking"] = *tracking_report;
  if (Status written = harness::writeTextFile(report, jsonText(j)); !written) return fail(written.error(), "fogctl demo");
  std::printf("  report: %s\n", report.c_str());
  return 0;
}

int runDemo(int argc, char** argv) {
  const auto args =
      Args::parse(argc, argv, 2,
                  {"input", "scene", "nodes", "topology", "frames", "report", "png", "base-port", "state", "alpha", "miss-rate",
                   "association", "tracker-input", "track-frames", "scene-start", "tracks-png", "clustering", "fragment-min-points", "alpha-max",
                   "objects", "classifier"},
                  {});
  if (!args) return fail(args.error(), "fogctl demo");
  if (args->has("scene")) {
    if (args->has("input") || args->has("nodes")) {
      return fail(invalidArgument("--scene runs one edge per LiDAR of the scene: no --input or --nodes with it"), "fogctl demo");
    }
    return runSceneDemo(*args);
  }
  for (const char* flag : {"miss-rate", "association", "tracker-input", "track-frames", "scene-start", "tracks-png", "clustering"}) {
    if (args->has(flag)) return fail(invalidArgument(std::string("--") + flag + " goes with --scene"), "fogctl demo");
  }
  const std::filesystem::path input = args->has("input") ? std::filesystem::absolute(args->get("input")) : defaultInput();
  if (input.empty() || !std::filesystem::exists(input)) return fail(invalidArgument("--input DIR of scans is required (bundled data not found)"), "fogctl demo");
  const auto nodes = args->getInt("nodes", 4);
  const auto frames = args->getInt("frames", 20);
  const auto base = args->getInt("base-port", 46000);
  const auto alpha = args->getDouble("alpha", 1.5);
  if (!nodes || *nodes < 1 || *nodes > 32) return fail(invalidArgument("--nodes must be in [1, 32]"), "fogctl demo");
  if (!frames || *frames < 1 || *frames > 10000) return fail(invalidArgument("--frames must be in [1, 10000]"), "fogctl demo");
  if (!base || *base < 1024 || *base > 60000) return fail(invalidArgument("--base-port must be in [1024, 60000]"), "fogctl demo");
  if (!alpha || !(*alpha > 0.0)) return fail(invalidArgument("--alpha must be positive"), "fogctl demo");
  const std::string shape = args->get("topology", "star");
  if (shape != "star" && shape != "tree") return fail(invalidArgument("--topology must be star or tree"), "fogctl demo");
  const std::filesystem::path dir = args->get("state", ".fogmap/demo");
  // Recorded scans: the paper's MAD-C unless told (the sensor's model is not known here).
  const auto mapping = sceneMapping(*args, sim::paperMapping());
  if (!mapping) return fail(mapping.error(), "fogctl demo");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  installStopHandlers();

  auto make = [&](Mode mode, int port) {
    TopologyConfig t = shape == "star" ? makeStarTopology(static_cast<int>(*nodes), input, port)
                                       : makeTreeTopology(static_cast<int>(*nodes), input, port);
    t.mode = mode;
    t.name = std::string(modeName(mode)) + "-" + t.name;
    t.madc.alpha = *alpha;
    t.madc.fragment_min_points = mapping->fragment_min_points;
    t.madc.alpha_max = mapping->alpha_max;
    t.objects = mapping->objects;
    for (auto& n : t.nodes) {
      if (n.sensor) n.sensor->frames = static_cast<std::uint64_t>(*frames);
    }
    return t;
  };
  const TopologyConfig madc_topology = make(Mode::kMadc, static_cast<int>(*base));
  const TopologyConfig baseline_topology = make(Mode::kBaseline, static_cast<int>(*base) + 400);
  const double rate_hz = madc_topology.nodes.back().sensor->rate_hz;
  const auto n_frames = static_cast<std::uint64_t>(*frames);

  std::printf("fogmap demo: %ld virtual LiDARs cut from %s, %s topology, %lu frames at %.0f Hz, alpha %.2f\n", *nodes,
              input.c_str(), shape.c_str(), static_cast<unsigned long>(n_frames), rate_hz, *alpha);
  std::printf("running the MAD-C cluster (%zu services)...\n", madc_topology.nodes.size());
  RunOptions options;
  options.frames = n_frames;
  options.timeout = std::chrono::seconds(30) + std::chrono::milliseconds(static_cast<long>(3000.0 * static_cast<double>(n_frames) / rate_hz));
  auto madc = runCluster(dir, madc_topology, options);
  if (!madc) return fail(madc.error(), "fogctl demo");
  if (stopRequested()) return 1;
  std::printf("running the baseline cluster (ship all points, cluster at the sink)...\n");
  options.point_labels = true;
  auto baseline = runCluster(dir, baseline_topology, options);
  if (!baseline) return fail(baseline.error(), "fogctl demo");
  // Every complete MAD-C epoch against a complete baseline epoch that replayed the same scan.
  const auto scores = scoreRecordedRuns(madc_topology, *madc, *baseline);
  if (!scores) return fail(Error{scores.error().code, scores.error().message + "; see the logs in " + dir.string()}, "fogctl demo");
  std::fputs(recordedScoresText(*scores).c_str(), stdout);

  const std::filesystem::path png = args->get("png", (dir / "global_map.png").string());
  const std::uint64_t last_epoch = scores->epochs.back().epoch;
  if (const Status s = drawRecordedBirdseye(png, madc->epochs.at(last_epoch), scores->last_view, static_cast<int>(*nodes)); !s) {
    return fail(s.error(), "fogctl demo");
  }
  std::printf("  bird's-eye view of frame %lu: %s\n", static_cast<unsigned long>(last_epoch), png.c_str());
  const std::filesystem::path report = args->get("report", (dir / "report.json").string());
  Json j;
  j["topology"] = shape;
  j["nodes"] = *nodes;
  j["input"] = input.string();
  j["alpha"] = jsonNumber(*alpha);
  j.update(recordedReport(*scores));
  if (Status written = harness::writeTextFile(report, jsonText(j)); !written) return fail(written.error(), "fogctl demo");
  std::printf("  report: %s\n", report.c_str());
  return 0;
}

}  // namespace

Command demoCommand() {
  return {"demo",
          "[--input DIR | --scene FILE] [--nodes 4] [--topology star|tree] [--frames 20] [--report FILE] [--png FILE]",
          std::string("usage: fogctl demo [--input DIR] [--nodes 4] [--topology star|tree] [--frames 20] [--report FILE] [--png FILE]\n"
          "                   [--alpha 1.5] [--base-port 46000] [--state DIR] [--fragment-min-points N|off]\n"
          "                   [--objects none|boxes|classes] [--classifier FILE]\n"
          "       fogctl demo --scene FILE [--topology star|tree] [--frames 10] [--report FILE] [--png FILE] [--alpha 1.5]\n"
          "                   [--base-port 46000] [--state DIR] [--miss-rate 0.3] [--association kalman|paper]\n"
          "                   [--tracker-input global_map|centroids] [--track-frames 100] [--scene-start S] [--tracks-png FILE]\n"
          "                   [--clustering exact|sensor] [--fragment-min-points N|off] [--objects none|boxes|classes]\n"
          "Runs a local MAD-C cluster and the baseline over the same frames and compares them: bytes,\n"
          "latency, Rand index; writes a JSON report and a bird's-eye PNG (under --state, default .fogmap/demo).\n"
          "  --input DIR    recorded scans (default: the bundled KITTI frames), cut into --nodes virtual LiDARs\n"
          "  --scene FILE   a simulated scene (fogctl scene): one edge per LiDAR of the scene, MAD-C-ext and the\n"
          "                 baseline over its first --frames frames (replayed in a loop, so both see the same\n"
          "                 frames), both also scored against the scene's truth (Rand index, ARI, objects found\n"
          "                 whole, split, merged, missed, also by range to the nearest LiDAR and by kind; the PNG\n"
          "                 marks the true objects MAD-C missed). When something in the scene moves and it has\n"
          "                 cameras, then also the cluster of fogctl topology --scene FILE --tracker: the tracker\n"
          "                 and a detection service per camera replaying the truth (--miss-rate of it missed, 2 px\n"
          "                 box jitter, 50 ms latency); after 30 track lists, --track-frames of them within one\n"
          "                 cycle of the scene are scored against the truth (CLEAR MOT, IDF1, localization error,\n"
          "                 sensor time to published tracks: the report's \"tracking\" object), and --tracks-png\n"
          "                 (default tracks.png under --state) shows the last with the tracks, their ids, labels\n"
          "                 and trails. The wall clock picks the stretch of the scene scored; --scene-start S\n"
          "                 scores the lists from scene time S on instead (waiting up to one cycle for it), so\n"
          "                 that runs of one scene compare\n")
              .append(kSceneMappingUsage),
          runDemo};
}

}  // namespace fogmap::cli
