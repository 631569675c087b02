// fogctl topology: writes a topology file: virtual LiDARs cut from recorded scans, or a simulated
// scene's LiDARs, under a star or a tree of aggregators; optionally a tracker and its cameras.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "common/camera/kitti.hpp"
#include "common/config/camera_node.hpp"
#include "common/config/topology.hpp"
#include "common/config/topology_parse.hpp"
#include "common/config/topology_presets.hpp"
#include "common/config/topology_yaml.hpp"
#include "common/config/tracker_node.hpp"
#include "common/sim/scene.hpp"
#include "common/sim/scene_topology.hpp"
#include "common/tracking/tracker_config.hpp"
#include "harness/tracking_eval.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using harness::trackingEvalDisplacement;

// `file` as a path relative to `dir` (both taken from the working directory), or absolute when
// they share no root: a topology names its files relative to its own directory.
std::filesystem::path relativeTo(const std::filesystem::path& file, const std::filesystem::path& dir) {
  const std::filesystem::path full = std::filesystem::absolute(file).lexically_normal();
  const std::filesystem::path relative = full.lexically_relative(std::filesystem::absolute(dir).lexically_normal());
  return relative.empty() ? full : relative;
}

// The detection nodes of `--cameras DIR[,DIR...]`: each DIR a directory of KITTI camera frames
// named image_0N (camera N of the calib file: `calib`, else calib.txt beside DIR, KITTI raw's
// layout), replayed at `rate_hz` through OpenCV's HOG people detector and sending to the tracker.
// The paths are written as given: like --source, relative to the topology file's directory
// `topology_dir`, where they are read now (the calibration, and the first image for its size).
Expected<std::vector<NodeConfig>> kittiCameraNodes(const std::string& list, const std::string& calib, double rate_hz,
                                                   const std::filesystem::path& topology_dir, int base_port) {
  namespace fs = std::filesystem;
  const auto at = [&](const fs::path& p) { return p.is_absolute() ? p : topology_dir / p; };
  std::vector<NodeConfig> nodes;
  std::set<std::string> names;
  std::stringstream words(list);
  for (std::string word; std::getline(words, word, ',');) {
    const fs::path dir = fs::path(word).lexically_normal();
    const std::string what = "--cameras " + word;
    std::error_code ec;
    if (word.empty() || !fs::is_directory(at(dir), ec)) {
      return invalidArgument(what + ": not a directory of camera frames (relative paths are taken from the topology file's directory, " +
                             topology_dir.string() + ")");
    }
    const std::string leaf = (dir.has_filename() ? dir : dir.parent_path()).filename().string();
    if (leaf.size() != 8 || leaf.rfind("image_0", 0) != 0 || leaf[7] < '0' || leaf[7] > '3') {
      return invalidArgument(what + ": cannot tell which camera of the calibration it is; KITTI names its frames' directories image_00 .. image_03");
    }
    const int index = leaf[7] - '0';
    const fs::path calib_file = calib.empty() ? (dir.has_filename() ? dir : dir.parent_path()).parent_path() / "calib.txt" : fs::path(calib);
    std::ifstream in(at(calib_file));
    std::stringstream text;
    text << in.rdbuf();
    if (!in) return invalidArgument(what + ": cannot read its calibration " + at(calib_file).string() + " (give one with --calib FILE)");
    const auto calibration = camera::parseKittiCalibration(text.str());
    if (!calibration) return invalidArgument(at(calib_file).string() + ": " + calibration.error().message);
    std::vector<fs::path> images;
    for (const auto& entry : fs::directory_iterator(at(dir), ec)) {
      std::string ext = entry.path().extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      if (ext == ".png" || ext == ".jpg" || ext == ".jpeg") images.push_back(entry.path());
    }
    if (images.empty()) return invalidArgument(what + ": no .png or .jpg image in " + at(dir).string());
    const fs::path first = *std::min_element(images.begin(), images.end());
    const cv::Mat image = cv::imread(first.string(), cv::IMREAD_UNCHANGED);
    if (image.empty()) return invalidArgument(what + ": cannot read the image " + first.string());
    const auto pinhole = camera::pinholeCamera(*calibration, index, image.cols, image.rows);
    if (!pinhole) return invalidArgument(at(calib_file).string() + ": " + pinhole.error().message);
    const std::string name = sim::cameraNodeFor(leaf);
    if (!names.insert(name).second) return invalidArgument(what + ": a second camera " + leaf + " (its node would be " + name + " again)");
    CameraNodeConfig c;
    c.source = dir;
    c.rate_hz = rate_hz;
    c.detector.kind = camera::DetectorKind::kHog;
    c.calibration = *pinhole;
    nodes.push_back(detectionNode(static_cast<int>(nodes.size() + 1), name, kTrackerNodeName, base_port, std::move(c)));
  }
  if (nodes.empty()) return invalidArgument("--cameras: no directory given");
  return nodes;
}

int runTopology(int argc, char** argv) {
  const auto args = Args::parse(
      argc, argv, 2,
      {"edges", "source", "scene", "base-port", "mode", "frames", "out", "fanout", "deadline-ms", "tls-ca", "association",
       "miss-rate", "box-jitter-px", "latency-ms", "cameras", "calib", "camera-rate-hz", "tracker-input", "clustering",
       "fragment-min-points", "alpha-max", "objects", "classifier"},
      {"tracker"});
  if (!args) return fail(args.error());
  const bool from_scene = args->has("scene");
  if (!from_scene && (args->has("clustering") || args->has("fragment-min-points"))) {
    return fail(invalidArgument("--clustering and --fragment-min-points go with --scene (its LiDARs name their models)"));
  }
  // Recorded scans take boxes and classes too: the mapping's other fields stay the scene's.
  const auto objects = sceneMapping(*args, sim::paperMapping());
  if (!objects) return fail(objects.error());
  std::string shape = from_scene ? "star" : "";  // a scene's topology is a star unless told
  if (args->positional().size() == 1) shape = args->positional()[0];
  if (args->positional().size() > 1 || (shape != "star" && shape != "tree")) {
    return fail(invalidArgument("usage: fogctl topology star|tree --edges K --source DIR [--base-port P] [--mode madc|baseline|ext] "
                                "[--frames N] [--fanout F] [--deadline-ms D] [--tls-ca FILE]\n"
                                "                       [--tracker [--association A] [--cameras DIR[,DIR...] [--calib FILE] "
                                "[--camera-rate-hz R]]] [--out FILE]\n"
                                "       fogctl topology [star|tree] --scene FILE [...]"));
  }
  const auto fanout = args->getInt("fanout", 2);
  if (!fanout || *fanout < 2 || *fanout > 64) return fail(invalidArgument("--fanout must be in [2, 64]"));
  if (args->has("fanout") && shape != "tree") return fail(invalidArgument("--fanout is for trees"));
  const auto edges = args->getInt("edges", 4);
  const auto base = args->getInt("base-port", 50000);
  if (!edges || *edges < 1 || *edges > 64) return fail(invalidArgument("--edges must be in [1, 64]"));
  if (!base || *base < 1024 || *base > 60000) return fail(invalidArgument("--base-port must be in [1024, 60000]"));
  const bool with_tracker = args->has("tracker");
  if (!with_tracker && args->has("association")) return fail(invalidArgument("--association goes with --tracker"));
  tracking::TrackerConfig tracking;
  if (with_tracker) {
    const auto association = tracking::parseAssociation(args->get("association", "kalman"));
    if (!association) return fail(invalidArgument("--association: " + association.error().message));
    tracking.association = *association;
  }
  // Where the topology file goes: its paths are relative to it.
  const std::filesystem::path topology_dir =
      args->has("out") ? std::filesystem::absolute(args->get("out")).parent_path() : std::filesystem::current_path();
  TopologyConfig t;
  if (from_scene) {
    if (args->has("edges") || args->has("source")) {
      return fail(invalidArgument("--scene makes one edge per LiDAR of the scene, simulated: give neither --edges nor --source"));
    }
    const std::filesystem::path scene_file = args->get("scene");
    const auto scene = sim::loadScene(scene_file);
    if (!scene) return fail(scene.error());
    if (scene->lidars.size() > 64) {
      return fail(invalidArgument(scene_file.string() + ": " + std::to_string(scene->lidars.size()) +
                                  " LiDARs; a topology has at most 64 edges"));
    }
    sim::SceneTopologyOptions options;
    const auto mapping = sceneMapping(*args, options.mapping);
    if (!mapping) return fail(mapping.error());
    options.mapping = *mapping;
    options.tree = shape == "tree";
    options.fanout = static_cast<int>(*fanout);
    options.base_port = static_cast<int>(*base);
    if (args->has("cameras") || args->has("calib") || args->has("camera-rate-hz")) {
      return fail(invalidArgument("--scene brings its own cameras (with --tracker): no --cameras, --calib or --camera-rate-hz"));
    }
    options.tracker = with_tracker;
    if (!options.tracker && (args->has("miss-rate") || args->has("box-jitter-px") || args->has("latency-ms") || args->has("tracker-input"))) {
      return fail(invalidArgument("--miss-rate, --box-jitter-px, --latency-ms and --tracker-input go with --tracker"));
    }
    if (options.tracker) {
      options.tracking = tracking;
      const auto input = parseTrackerInput(args->get("tracker-input", "global_map"));
      if (!input) return fail(invalidArgument("--tracker-input " + input.error().message));
      options.tracker_input = *input;
      options.displacement = trackingEvalDisplacement();  // the moving scene's VLP-16s (tracking_eval.cpp says why)
      const auto miss = args->getDouble("miss-rate", 0.0);
      const auto jitter = args->getDouble("box-jitter-px", 0.0);
      const auto latency = args->getDouble("latency-ms", 0.0);
      if (!miss || !(*miss >= 0.0 && *miss <= 1.0)) return fail(invalidArgument("--miss-rate must be in [0, 1]"));
      if (!jitter || !(*jitter >= 0.0 && *jitter <= 1000.0)) return fail(invalidArgument("--box-jitter-px must be in [0, 1000]"));
      if (!latency || !(*latency >= 0.0 && *latency <= 60000.0)) return fail(invalidArgument("--latency-ms must be in [0, 60000]"));
      options.truth = TruthReplayConfig{*miss, *jitter, *latency};
    }
    // The topology names the scene and the classifier relative to its own directory, as services resolve them.
    if (options.mapping.objects.classifier) {
      options.mapping.objects.classifier = relativeTo(*options.mapping.objects.classifier, topology_dir);
    }
    t = sim::sceneTopology(*scene, relativeTo(scene_file, topology_dir), options);
  } else {
    if (args->has("miss-rate") || args->has("box-jitter-px") || args->has("latency-ms")) {
      return fail(invalidArgument("--miss-rate, --box-jitter-px and --latency-ms replay a scene's truth: they go with --scene"));
    }
    if (args->has("tracker-input")) {
      return fail(invalidArgument("--tracker-input goes with --scene: displacement centroids need LiDARs that stand still"));
    }
    if (!args->has("cameras") && (args->has("calib") || args->has("camera-rate-hz"))) {
      return fail(invalidArgument("--calib and --camera-rate-hz go with --cameras"));
    }
    if (args->has("cameras") && !with_tracker) {
      return fail(invalidArgument("--cameras needs --tracker: a detection node sends its detections to a tracker"));
    }
    const std::string source = args->get("source", "../data/kitti_raw_seq_a");
    t = shape == "star" ? makeStarTopology(static_cast<int>(*edges), source, static_cast<int>(*base))
                        : makeTreeTopology(static_cast<int>(*edges), source, static_cast<int>(*base), static_cast<int>(*fanout));
    t.objects = objects->objects;
    t.madc.alpha_max = objects->alpha_max;
    if (t.objects.classifier) t.objects.classifier = relativeTo(*t.objects.classifier, topology_dir);
    if (with_tracker) t.nodes.push_back(trackerNode(static_cast<int>(*base), tracking));
    if (args->has("cameras")) {
      const auto rate = args->getDouble("camera-rate-hz", 10.0);
      if (!rate || !(*rate > 0.0 && *rate <= 1000.0)) return fail(invalidArgument("--camera-rate-hz must be in (0, 1000]"));
      const auto cameras = kittiCameraNodes(args->get("cameras"), args->get("calib"), *rate, topology_dir, static_cast<int>(*base));
      if (!cameras) return fail(cameras.error());
      t.nodes.insert(t.nodes.end(), cameras->begin(), cameras->end());
    }
  }
  if (args->has("deadline-ms")) {
    const auto deadline = args->getDouble("deadline-ms", t.deadline_ms);
    if (!deadline || !(*deadline > 0.0) || *deadline > 60'000.0) return fail(invalidArgument("--deadline-ms must be in (0, 60000]"));
    t.deadline_ms = *deadline;
  }
  if (args->has("tls-ca")) {
    const std::filesystem::path ca = args->get("tls-ca");
    t.tls = TlsConfig{ca, ca.parent_path(), {}};
  }
  const std::string mode = args->get("mode", "madc");
  if (mode == "baseline") {
    t.mode = Mode::kBaseline;
  } else if (mode == "ext") {
    t.mode = Mode::kExt;
  } else if (mode != "madc") {
    return fail(invalidArgument("--mode must be madc, baseline or ext"));
  }
  if (args->has("frames")) {
    const auto frames = args->getInt("frames", 0);
    if (!frames || *frames < 1) return fail(invalidArgument("--frames must be positive"));
    for (auto& n : t.nodes) {
      if (n.sensor) n.sensor->frames = static_cast<std::uint64_t>(*frames);
      if (n.camera) n.camera->frames = static_cast<std::uint64_t>(*frames);
    }
  }
  std::string command = "fogctl topology";
  for (int i = 2; i < argc; ++i) {
    if (std::string_view(argv[i]) == "--out") {
      ++i;  // where it was written is not part of what it is
      continue;
    }
    command += std::string(" ") + argv[i];
  }
  const std::string text = "# fogmap topology, generated by: " + command + "\n" + toYaml(t);
  // Read back as the services read it: flags that make a topology they would refuse (e.g.
  // --alpha-max below the topology's alpha) are refused here, with the services' message.
  const std::filesystem::path out_dir =
      args->has("out") ? std::filesystem::absolute(args->get("out")).parent_path() : std::filesystem::current_path();
  if (const auto read_back = parseTopology(text, out_dir); !read_back) return fail(read_back.error());
  if (!args->has("out")) {
    std::cout << text;
    return 0;
  }
  std::ofstream out(args->get("out"));
  out << text;
  if (!out) return fail(ioError("cannot write " + args->get("out")));
  return 0;
}

}  // namespace

Command topologyCommand() {
  return {"topology",
          "star|tree --edges K --source DIR | --scene FILE [--base-port P] [--mode madc|baseline|ext] [--frames N] [--out FILE]",
          std::string("usage: fogctl topology star|tree --edges K --source DIR [--base-port 50000] [--mode madc|baseline|ext]\n"
          "                       [--frames N] [--fanout 2] [--deadline-ms 80] [--tls-ca FILE]\n"
          "                       [--tracker [--association paper|kalman] [--cameras DIR[,DIR...] [--calib FILE]\n"
          "                       [--camera-rate-hz 10]]] [--out FILE]\n"
          "       fogctl topology [star|tree] --scene FILE [the same flags but --edges, --source and --cameras]\n"
          "Writes a topology file: K virtual LiDARs cut from the scans in DIR, under one sink (star) or a\n"
          "tree of aggregators; to stdout unless --out. Paths are relative to the topology file, whose\n"
          "directory is --out's (the working directory without --out).\n"
          "  --tracker        also a tracker (named tracker, port P+300, metrics P+301) that reads the root's\n"
          "                   global maps and publishes tracks (fogctl watch --tracks); --association paper|kalman\n"
          "                   (default kalman)\n"
          "  --cameras DIRS   with --tracker: a detection node per directory of KITTI camera frames named\n"
          "                   image_0N (node cam-image_0N, metrics P+401, ...), running OpenCV's HOG people\n"
          "                   detector on them at --camera-rate-hz R (10), calibrated as camera N of --calib FILE\n"
          "                   (default: calib.txt beside DIR, KITTI raw's layout) in the scans' frame; the files\n"
          "                   are read now (the calibration, the first image's size)\n"
          "  --scene FILE     instead of scans: one edge per LiDAR of the scene (fogctl scene), named\n"
          "                   edge-<LiDAR name>, ids 1..K, each simulating its LiDAR (sensor source sim) at the\n"
          "                   LiDAR's pose in the scene, at 10 Hz; a star unless tree is given. The scene is\n"
          "                   written relative to --out's directory (the working directory without --out)\n"
          "  --tracker        with --scene: the tracker and a detection node per camera of the scene\n"
          "                   (cam-<camera>), calibrated as the scene says, replaying the scene's objects as\n"
          "                   detections (detector truth) with --miss-rate R (0), --box-jitter-px S (0) and\n"
          "                   --latency-ms L (0); --tracker-input centroids: every edge streams the tracker\n"
          "                   the displacement centroids of its scans instead of the root's maps (global_map)\n"
          "  --clustering, --fragment-min-points   with --scene: how the edges make their maps (below)\n"
          "  --objects, --classifier, --alpha-max   the edges' boxes, classes and ellipsoids (below; also for --source)\n"
          "  --fanout F       a tree's aggregators have at most F children (default 2)\n"
          "  --deadline-ms D  an aggregator's deadline per level (default 80)\n"
          "  --tls-ca FILE    mutual TLS on every link, certificates next to FILE (fogctl certs)\n")
              .append(kSceneMappingUsage),
          runTopology};
}

}  // namespace fogmap::cli
