// fogctl up / down / topology / split / watch: running a local cluster and looking at it.
#include <signal.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <condition_variable>
#include <mutex>
#include <cmath>
#include <set>
#include <cstdlib>
#include <sstream>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <thread>

#include <grpcpp/grpcpp.h>
#include <opencv2/imgcodecs.hpp>

#include "common/camera/kitti.hpp"
#include "common/certs.hpp"
#include "common/cloud_io.hpp"
#include "common/geofence.hpp"
#include "common/sim/scene.hpp"
#include "common/sim/scene_topology.hpp"
#include "common/topology.hpp"
#include "common/tracking/tracker_config.hpp"
#include "common/virtual_lidar.hpp"
#include "fogmap/v1/fogmap.grpc.pb.h"
#include "services/common/grpc_options.hpp"
#include "services/common/proto_convert.hpp"
#include "tools/fogctl/epoch_latency.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"
#include "tools/fogctl/launcher.hpp"
#include "tools/fogctl/tracking_eval.hpp"

namespace fogmap::cli {
namespace {

// State directories are absolute, so that up and down find the same one from any working
// directory: --state is taken relative to where fogctl runs, the default (.fogmap/NAME) relative
// to the topology file.
Expected<std::filesystem::path> absoluteDir(const std::filesystem::path& dir) {
  std::error_code ec;
  const auto absolute = std::filesystem::absolute(dir, ec);
  if (ec || dir.empty()) return invalidArgument("cannot use '" + dir.string() + "' as a directory: " + (ec ? ec.message() : "it is empty"));
  const auto canonical = std::filesystem::weakly_canonical(absolute, ec);
  return ec ? absolute.lexically_normal() : canonical;
}

Expected<std::filesystem::path> stateDir(const Args& args, const std::filesystem::path& topology_file, const TopologyConfig& t) {
  if (args.has("state")) return absoluteDir(args.get("state"));
  std::error_code ec;
  const auto file = std::filesystem::absolute(topology_file, ec);
  if (ec) return invalidArgument("cannot resolve " + topology_file.string() + ": " + ec.message());
  return absoluteDir(file.parent_path() / ".fogmap" / t.name);
}

// A word the shell reads back unchanged: as is when it is plain, else in single quotes.
std::string shellWord(const std::string& word) {
  const bool plain = !word.empty() && word.find_first_not_of("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                                                             "0123456789_./:=@%+,-") == std::string::npos;
  if (plain) return word;
  std::string quoted = "'";
  for (const char c : word) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

// The client identity fogctl uses by default when the topology has a tls section.
constexpr const char* kDefaultIdentity = "operator";

// How fogctl reaches the root aggregator: its address and the transport credentials.
struct RootConnection {
  std::string target;
  std::shared_ptr<grpc::ChannelCredentials> credentials;
};

// The root's address: --target HOST:PORT, or the root of the topology file given. The credentials:
// --cert, --key and --ca when given; else, when the topology has a tls section, the certificate of
// --identity NAME (default: operator) in its cert_dir; else plaintext. Every file is read and
// checked here, so a problem is reported before any connection is tried.
Expected<RootConnection> rootConnection(const Args& args, const std::string& usage, Role server = Role::kAggregator) {
  std::optional<TopologyConfig> topology;
  if (!args.has("target") || args.has("identity")) {
    if (args.positional().size() != 1) {
      return invalidArgument(args.has("identity") ? "--identity needs the topology file (its tls section says where the "
                                                    "certificates are); with --target give --cert, --key and --ca"
                                                  : "usage: " + usage);
    }
    auto loaded = loadTopology(args.positional()[0]);
    if (!loaded) return loaded.error();
    topology = std::move(*loaded);
  }
  RootConnection connection;
  if (args.has("target")) {
    connection.target = args.get("target");
  } else {
    // The root, or the first tracker.
    const NodeConfig* node = topology->root();
    if (server == Role::kTracker) {
      const auto tracker = std::find_if(topology->nodes.begin(), topology->nodes.end(),
                                        [](const NodeConfig& n) { return n.role == Role::kTracker; });
      if (tracker == topology->nodes.end()) return invalidArgument(args.positional()[0] + " has no tracker");
      node = &*tracker;
    }
    connection.target = node->host + ":" + std::to_string(node->port);
  }
  const auto now = std::chrono::system_clock::now();
  const bool explicit_files = args.has("cert") || args.has("key") || args.has("ca");
  if (explicit_files) {
    if (args.has("identity")) return invalidArgument("give either --identity or --cert, --key and --ca, not both");
    for (const char* flag : {"cert", "key", "ca"}) {
      if (!args.has(flag)) return invalidArgument(std::string("--cert, --key and --ca go together: --") + flag + " is missing");
    }
    auto tls = loadTls(TlsIdentity{args.get("ca"), args.get("cert"), args.get("key")}, now);
    if (!tls) return Error{tls.error().code, "tls: " + tls.error().message};
    connection.credentials = channelCredentials(*tls);
    return connection;
  }
  if (!topology || !topology->tls) {
    if (args.has("identity")) return invalidArgument("--identity: " + args.positional()[0] + " has no tls section");
    connection.credentials = channelCredentials(std::nullopt);
    return connection;
  }
  const std::string identity = args.get("identity", kDefaultIdentity);
  const auto files = topology->tlsIdentity(identity);
  std::error_code ec;
  if (!args.has("identity") && !std::filesystem::exists(files->cert, ec)) {
    return invalidArgument(args.positional()[0] + " uses TLS, and fogctl needs a client certificate: give --identity NAME "
                           "(NAME.crt and NAME.key in " + topology->tls->cert_dir.string() + ") or --cert, --key and "
                           "--ca; the default identity '" + identity + "' has no certificate (" + files->cert.string() +
                           "; fogctl certs makes one)");
  }
  auto tls = loadTls(*topology, identity, now);
  if (!tls) return Error{tls.error().code, "tls: identity '" + identity + "': " + tls.error().message};
  connection.credentials = channelCredentials(*tls);
  return connection;
}

// "a,b,c,d,e,f": exactly `count` finite numbers separated by commas.
Expected<std::vector<double>> numberList(const std::string& text, std::size_t count, const std::string& flag) {
  std::vector<double> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (item.empty() || end != item.c_str() + item.size() || !std::isfinite(v)) {
      return invalidArgument(flag + ": '" + item + "' is not a number");
    }
    out.push_back(v);
  }
  if (out.size() != count) return invalidArgument(flag + " expects " + std::to_string(count) + " numbers separated by commas");
  return out;
}

}  // namespace

int runUp(int argc, char** argv) {
  const std::string usage = "usage: fogctl up TOPOLOGY.yaml [--detach] [--state DIR] [--timeout-s 30] [--dry-run]";
  const auto args = Args::parse(argc, argv, 2, {"state", "timeout-s"}, {"detach", "dry-run"});
  if (!args) return fail(args.error());
  if (args->positional().size() != 1) return fail(invalidArgument(usage));
  const std::filesystem::path file = args->positional()[0];
  const auto topology = loadStartableTopology(file);
  if (!topology) return fail(topology.error());
  const auto timeout_s = args->getDouble("timeout-s", 30.0);
  if (!timeout_s) return fail(timeout_s.error());
  if (!(*timeout_s > 0.0 && *timeout_s <= 24 * 3600.0)) return fail(invalidArgument("--timeout-s must be in (0, 86400]"));
  const auto state = stateDir(*args, file, *topology);
  if (!state) return fail(state.error());
  const auto plan = planCluster(file, *topology, *state);
  if (!plan) return fail(plan.error());
  if (args->has("dry-run")) {
    for (const PlannedNode& node : *plan) {
      std::string command;
      for (const std::string& word : node.command) {
        if (!command.empty()) command += ' ';
        command += shellWord(word);
      }
      std::printf("would start %s (%s): %s\n", node.name.c_str(), roleName(node.role), command.c_str());
    }
    std::printf("cluster '%s': %zu services, mode %s, %s; logs would go to %s; nothing started\n", topology->name.c_str(),
                plan->size(), modeName(topology->mode), topology->tls ? "mutual TLS" : "plaintext", (*state / "logs").c_str());
    return 0;
  }
  installStopHandlers();
  auto cluster = startCluster(file, *topology, *state, std::chrono::milliseconds(static_cast<long>(*timeout_s * 1000)));
  if (!cluster) return fail(cluster.error());
  std::printf("%-14s %-11s %-22s %-8s %s\n", "node", "role", "listen", "metrics", "parent");
  for (const auto& n : topology->nodes) {
    const std::string listen = n.port ? n.host + ":" + std::to_string(n.port) : "-";
    std::printf("%-14s %-11s %-22s %-8u %s\n", n.name.c_str(), roleName(n.role), listen.c_str(),
                n.metrics_port, n.parent.empty() ? (n.role == Role::kAggregator ? "(root)" : "-") : n.parent.c_str());
  }
  std::printf("cluster '%s' is up (%zu services, mode %s, %s); logs in %s\n", topology->name.c_str(), topology->nodes.size(),
              modeName(topology->mode), topology->tls ? "mutual TLS" : "plaintext", (*state / "logs").c_str());
  if (args->has("detach")) {
    std::printf("stop it with: fogctl down --state %s\n", shellWord(state->string()).c_str());
    return 0;
  }
  std::printf("Ctrl-C stops the cluster\n");
  while (!stopRequested() && allRunning(*cluster)) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  if (!allRunning(*cluster)) std::fprintf(stderr, "fogctl: a service exited; stopping the cluster (see %s)\n", (*state / "logs").c_str());
  stopCluster(*cluster, std::chrono::milliseconds(5000));
  std::printf("cluster '%s' stopped\n", topology->name.c_str());
  return 0;
}

int runDown(int argc, char** argv) {
  const auto args = Args::parse(argc, argv, 2, {"state"}, {});
  if (!args) return fail(args.error());
  Expected<std::filesystem::path> state = invalidArgument("usage: fogctl down TOPOLOGY.yaml | --state DIR");
  if (args->has("state")) {
    state = absoluteDir(args->get("state"));
  } else if (args->positional().size() == 1) {
    const auto topology = loadTopology(args->positional()[0]);
    if (!topology) return fail(topology.error());
    state = stateDir(*args, args->positional()[0], *topology);
  }
  if (!state) return fail(state.error());
  const auto report = stopRecorded(*state, std::chrono::milliseconds(5000));
  if (!report) return fail(report.error());
  for (const auto& n : report->gone) {
    std::fprintf(stderr, "fogctl: pid %d (%s) has already exited\n", static_cast<int>(n.pid), n.name.c_str());
  }
  for (const auto& n : report->replaced) {
    std::fprintf(stderr, "fogctl: pid %d (%s) is no longer the service fogctl started; left alone\n", static_cast<int>(n.pid),
                 n.name.c_str());
  }
  std::printf("stopped %zu service(s) of the cluster recorded in %s\n", report->stopped.size(), state->c_str());
  return 0;
}

namespace {

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

}  // namespace

int runTopology(int argc, char** argv) {
  const auto args = Args::parse(
      argc, argv, 2,
      {"edges", "source", "scene", "base-port", "mode", "frames", "out", "fanout", "deadline-ms", "tls-ca", "association",
       "miss-rate", "box-jitter-px", "latency-ms", "cameras", "calib", "camera-rate-hz", "tracker-input"},
      {"tracker"});
  if (!args) return fail(args.error());
  const bool from_scene = args->has("scene");
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
    // The topology names the scene relative to its own directory, as services resolve it.
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
  if (!args->has("out")) {
    std::cout << text;
    return 0;
  }
  std::ofstream out(args->get("out"));
  out << text;
  if (!out) return fail(ioError("cannot write " + args->get("out")));
  return 0;
}

int runSplit(int argc, char** argv) {
  const auto args = Args::parse(argc, argv, 2, {"input", "views", "overlap-deg", "out"}, {});
  if (!args) return fail(args.error());
  if (!args->has("input") || !args->has("out")) {
    return fail(invalidArgument("usage: fogctl split --input SCAN --views K [--overlap-deg 10] --out DIR"));
  }
  const auto views = args->getInt("views", 4);
  const auto overlap = args->getDouble("overlap-deg", 10.0);
  if (!views || *views < 1 || *views > 64) return fail(invalidArgument("--views must be in [1, 64]"));
  if (!overlap || *overlap < 0.0 || *overlap >= 360.0 / static_cast<double>(*views)) {
    return fail(invalidArgument("--overlap-deg must be in [0, 360 / views)"));
  }
  const auto scan = readCloud(args->get("input"));
  if (!scan) return fail(scan.error());
  const std::filesystem::path out = args->get("out");
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  if (ec) return fail(ioError("cannot create " + out.string()));
  const auto stem = std::filesystem::path(args->get("input")).stem().string();
  std::printf("# %ld virtual LiDARs cut from %s (%zu points); pose = sensor -> scan frame\n", *views,
              args->get("input").c_str(), scan->points.size());
  for (int k = 0; k < *views; ++k) {
    const SectorSplit split{static_cast<int>(*views), k, *overlap};
    const Cloud view = sectorView(scan->points, split);
    const auto file = out / (stem + "_view" + std::to_string(k) + ".bin");
    if (const Status s = writeKittiBin(file, view); !s) return fail(s.error());
    const double yaw = std::atan2(sectorPose(split).rotation()(1, 0), sectorPose(split).rotation()(0, 0)) * 180.0 / M_PI;
    std::printf("- view: %d\n  file: %s\n  points: %zu\n  pose: {translation_m: [0, 0, 0], rpy_deg: [0, 0, %.3f]}\n", k,
                file.c_str(), view.size(), yaw);
  }
  return 0;
}

namespace {

// How long watch waits for the root to accept a connection when --timeout-s does not say.
constexpr double kConnectTimeoutS = 5.0;

// Connects the channel within window_s: an empty string, or why not. A refused connection is not
// final: a root that is still starting (fogctl up, docker-compose up) is tried again, with the
// channel's capped reconnect backoff, until the window closes.
std::string connect(grpc::Channel& channel, double window_s) {
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(window_s));
  std::string last_problem = "no connection";
  auto state = channel.GetState(true);
  while (state != GRPC_CHANNEL_READY) {
    if (state == GRPC_CHANNEL_SHUTDOWN) return "the channel was shut down";
    if (state == GRPC_CHANNEL_TRANSIENT_FAILURE) last_problem = "the connection failed";
    if (stopRequested()) return "interrupted";
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline) {
      char within[48];
      std::snprintf(within, sizeof within, " within %g s", window_s);
      return last_problem + within;
    }
    // In slices, so that Ctrl-C is seen.
    const auto slice = std::min<std::chrono::steady_clock::duration>(deadline - now, std::chrono::milliseconds(100));
    channel.WaitForStateChange(state, std::chrono::system_clock::now() + slice);
    state = channel.GetState(true);
  }
  return {};
}

void printGlobalMap(const v1::GlobalMap& message, long shown) {
  auto global = fromProto(message);
  if (!global) {
    std::fprintf(stderr, "fogctl: malformed global map: %s\n", global.error().message.c_str());
    return;
  }
  const auto& h = global->header;
  const std::optional<double> e2e_ms = endToEndLatencyMs(*global);
  char e2e[32] = "no sensor time";
  if (e2e_ms) std::snprintf(e2e, sizeof e2e, "%.1f ms", *e2e_ms);
  std::string contributing;
  for (const auto n : h.contributing_nodes) contributing += std::to_string(n) + " ";
  std::string missing;
  for (const auto n : h.missing_nodes) missing += std::to_string(n) + " ";
  std::printf("epoch %lu  objects %zu  ellipsoids %zu  merge %.3f ms  e2e %s  nodes [ %s]  missing [ %s]\n",
              static_cast<unsigned long>(h.epoch), global->map.objects.size(), global->map.ellipsoidCount(),
              global->merge_seconds * 1e3, e2e, contributing.c_str(), missing.c_str());
  // The largest objects first: position (box centre) and size (box extent) in metres.
  std::vector<const MapObject*> objects;
  for (const auto& o : global->map.objects) objects.push_back(&o);
  std::sort(objects.begin(), objects.end(), [](const MapObject* a, const MapObject* b) {
    return (a->box.max - a->box.min).prod() > (b->box.max - b->box.min).prod();
  });
  for (long k = 0; k < std::min<long>(shown, static_cast<long>(objects.size())); ++k) {
    const auto& o = *objects[static_cast<std::size_t>(k)];
    const Eigen::Vector3d c = 0.5 * (o.box.min + o.box.max);
    const Eigen::Vector3d s = o.box.max - o.box.min;
    std::set<std::uint32_t> nodes;
    for (const auto& e : o.ellipsoids) nodes.insert(e.node());
    std::string from;
    for (const auto n : nodes) from += std::to_string(n) + " ";
    std::printf("  object at (%7.2f, %7.2f, %5.2f) m  size %5.2f x %5.2f x %4.2f m  %zu ellipsoids from nodes [ %s]\n",
                c.x(), c.y(), c.z(), s.x(), s.y(), s.z(), o.ellipsoids.size(), from.c_str());
  }
  std::fflush(stdout);
}

}  // namespace

namespace {

void printTrackList(const v1::TrackList& message) {
  const double e2e_ms = static_cast<double>(message.published_time_ns() - message.lidar_time_ns()) / 1e6;
  std::printf("tracks %d  association %s  e2e %.1f ms\n", message.tracks_size(), message.association().c_str(), e2e_ms);
  for (const auto& proto : message.tracks()) {
    const auto track = fromProto(proto);
    if (!track) {
      std::fprintf(stderr, "fogctl: malformed track: %s\n", track.error().message.c_str());
      continue;
    }
    std::printf("  track %4lu  %-10s %-9s at (%7.2f, %7.2f) m  velocity (%5.2f, %5.2f) m/s  sigma %.2f m%s\n",
                static_cast<unsigned long>(track->id), track->label.c_str(), tracking::trackStateName(track->state),
                track->position.x(), track->position.y(), track->velocity.x(), track->velocity.y(),
                std::sqrt(std::max(0.0, track->covariance.trace() / 2.0)), track->camera_confirmed ? "  camera" : "");
  }
  std::fflush(stdout);
}

// Reads a server stream until --count messages, Ctrl-C, --timeout-s without a message or the end
// of the stream; says so after every --idle-s without one: a silent server is reported, never
// waited on silently. `what` names the messages and `who` the server in what it prints.
template <class Message>
int follow(grpc::ClientContext& context, grpc::ClientReaderInterface<Message>& reader, const std::function<void(const Message&)>& print,
           long count, double idle_s, double timeout_s, const std::string& what, const std::string& who) {
  using Clock = std::chrono::steady_clock;
  const auto seconds = [](double s) { return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s)); };
  std::atomic<long> received{0};
  std::atomic<bool> gave_up{false};
  std::mutex mutex;
  std::condition_variable finished_cv;
  bool finished = false;
  std::thread watchdog([&] {
    long seen = 0;
    long idle_periods = 0;
    auto quiet_since = Clock::now();
    std::unique_lock<std::mutex> lock(mutex);
    while (!finished_cv.wait_for(lock, std::chrono::milliseconds(50), [&] { return finished; })) {
      if (stopRequested()) break;
      const auto now = Clock::now();
      if (received.load() != seen) {
        seen = received.load();
        idle_periods = 0;
        quiet_since = now;
        continue;
      }
      if (timeout_s > 0.0 && now - quiet_since >= seconds(timeout_s)) {
        gave_up = true;
        break;
      }
      if (now - quiet_since >= seconds(idle_s * static_cast<double>(idle_periods + 1))) {
        ++idle_periods;
        std::fprintf(stderr, "fogctl: no %s from %s for %g s\n", what.c_str(), who.c_str(), idle_s * static_cast<double>(idle_periods));
      }
    }
    context.TryCancel();
  });

  Message message;
  bool counted_out = false;
  while (reader.Read(&message)) {
    print(message);
    ++received;
    if (count > 0 && received.load() >= count) {
      counted_out = true;
      break;
    }
  }
  {
    std::lock_guard<std::mutex> lock(mutex);
    finished = true;
  }
  finished_cv.notify_all();
  watchdog.join();
  const grpc::Status status = reader.Finish();
  if (counted_out || stopRequested()) return 0;
  if (gave_up) {
    std::fprintf(stderr, "fogctl: no %s from %s for %g s; giving up\n", what.c_str(), who.c_str(), timeout_s);
    return 1;
  }
  const std::string why = status.ok() ? "it ended the stream" : status.error_message();
  std::fprintf(stderr, "fogctl: lost %s: %s\n", who.c_str(), why.empty() ? "the stream failed" : why.c_str());
  return 1;
}

}  // namespace

int runWatch(int argc, char** argv) {
  const auto args = Args::parse(argc, argv, 2, {"target", "count", "objects", "idle-s", "timeout-s", "identity", "cert", "key", "ca"},
                                {"tracks"});
  if (!args) return fail(args.error());
  const bool tracks = args->has("tracks");
  const auto connection = rootConnection(
      *args, "fogctl watch TOPOLOGY.yaml | --target HOST:PORT [--tracks] [--count N] [--objects 10] [--idle-s 10] [--timeout-s 0]",
      tracks ? Role::kTracker : Role::kAggregator);
  if (!connection) return fail(connection.error());
  const std::string target = connection->target;
  const auto count = args->getInt("count", 0);
  const auto shown = args->getInt("objects", 10);
  if (!count || *count < 0 || !shown || *shown < 0) return fail(invalidArgument("--count and --objects must be non-negative"));
  const auto idle_s = args->getDouble("idle-s", 10.0);
  if (!idle_s || !(*idle_s > 0.0)) return fail(invalidArgument("--idle-s must be a positive number of seconds"));
  const auto timeout_s = args->getDouble("timeout-s", 0.0);
  if (!timeout_s || *timeout_s < 0.0) return fail(invalidArgument("--timeout-s must be a non-negative number of seconds"));
  installStopHandlers();
  const std::string who = std::string(tracks ? "the tracker" : "the root") + " at " + target;
  auto channel = makeChannel(target, connection->credentials, 64U << 20);
  if (const std::string problem = connect(*channel, *timeout_s > 0.0 ? *timeout_s : kConnectTimeoutS); !problem.empty()) {
    if (stopRequested()) return 0;
    std::fprintf(stderr, "fogctl: cannot reach %s: %s (is the cluster up?)\n", who.c_str(), problem.c_str());
    return 1;
  }
  grpc::ClientContext context;
  if (tracks) {
    auto stub = v1::TrackerService::NewStub(channel);
    v1::TrackSubscribeRequest request;
    auto reader = stub->Subscribe(&context, request);
    return follow<v1::TrackList>(context, *reader, printTrackList, *count, *idle_s, *timeout_s, "tracks", who);
  }
  auto stub = v1::GlobalMapService::NewStub(channel);
  v1::SubscribeRequest request;
  auto reader = stub->Subscribe(&context, request);
  const long objects = *shown;
  return follow<v1::GlobalMap>(
      context, *reader, [objects](const v1::GlobalMap& m) { printGlobalMap(m, objects); }, *count, *idle_s, *timeout_s,
      "global map", who);
}

int runGeofence(int argc, char** argv) {
  const std::string usage =
      "fogctl geofence set TOPOLOGY.yaml | --target HOST:PORT --name NAME --box XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX\n"
      "       fogctl geofence query TOPOLOGY.yaml | --target HOST:PORT [--name NAME]";
  if (argc < 3 || (std::string(argv[2]) != "set" && std::string(argv[2]) != "query")) {
    return fail(invalidArgument("usage: " + usage));
  }
  const bool set = std::string(argv[2]) == "set";
  const auto args = Args::parse(argc, argv, 3, {"target", "name", "box", "identity", "cert", "key", "ca"}, {});
  if (!args) return fail(args.error());
  const auto connection = rootConnection(*args, usage);
  if (!connection) return fail(connection.error());
  const std::string& target = connection->target;
  auto stub = v1::GlobalMapService::NewStub(makeChannel(target, connection->credentials, 64U << 20));
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));

  if (set) {
    if (!args->has("name") || !args->has("box")) return fail(invalidArgument("usage: " + usage));
    const auto box = numberList(args->get("box"), 6, "--box");
    if (!box) return fail(box.error());
    const Eigen::Vector3d lo((*box)[0], (*box)[1], (*box)[2]);
    const Eigen::Vector3d hi((*box)[3], (*box)[4], (*box)[5]);
    if ((lo.array() >= hi.array()).any()) return fail(invalidArgument("--box: the minimum must be below the maximum on every axis"));
    v1::SetGeofenceReply reply;
    const grpc::Status status = stub->SetGeofence(&context, toProto(boxGeofence(args->get("name"), lo, hi)), &reply);
    if (!status.ok()) return fail(fromGrpcStatus(status, "SetGeofence at " + target));
    std::printf("geofence '%s' set on %s (%u geofences)\n", args->get("name").c_str(), target.c_str(), reply.geofence_count());
    return 0;
  }
  v1::GeofenceQuery query;
  query.set_name(args->get("name"));
  v1::GeofenceReport report;
  const grpc::Status status = stub->QueryGeofences(&context, query, &report);
  if (!status.ok()) return fail(fromGrpcStatus(status, "QueryGeofences at " + target));
  if (report.epoch() == 0) {
    std::printf("no global map yet\n");
    return 0;
  }
  std::printf("epoch %lu: %d intrusions\n", static_cast<unsigned long>(report.epoch()), report.intrusions_size());
  for (const auto& hit : report.intrusions()) {
    const auto containment = fromProto(hit.containment());
    const auto& lo = hit.box().min();
    const auto& hi = hit.box().max();
    std::printf("%s object %u %s box [%.2f %.2f %.2f]..[%.2f %.2f %.2f] ellipsoids %d\n", hit.geofence().c_str(),
                hit.object_index(), containment ? containmentName(*containment) : "unknown", lo.x(), lo.y(), lo.z(), hi.x(), hi.y(), hi.z(),
                hit.ellipsoids_size());
  }
  return 0;
}

}  // namespace fogmap::cli
