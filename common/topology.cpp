#include "common/topology.hpp"

#include <arpa/inet.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <set>
#include <sstream>
#include <string_view>

#include <yaml-cpp/yaml.h>

#include "common/yaml_fields.hpp"

namespace fogmap {

const NodeConfig* TopologyConfig::find(const std::string& node_name) const {
  for (const auto& n : nodes) {
    if (n.name == node_name) return &n;
  }
  return nullptr;
}

const NodeConfig* TopologyConfig::find(std::uint32_t id) const {
  for (const auto& n : nodes) {
    if (n.id == id) return &n;
  }
  return nullptr;
}

const NodeConfig* TopologyConfig::root() const {
  for (const auto& n : nodes) {
    if (n.parent.empty() && n.role == Role::kAggregator) return &n;
  }
  return nullptr;
}

std::vector<const NodeConfig*> TopologyConfig::camerasOf(const std::string& node_name) const {
  std::vector<const NodeConfig*> out;
  for (const auto& n : nodes) {
    if (n.role == Role::kDetection && n.parent == node_name) out.push_back(&n);
  }
  return out;
}

std::vector<const NodeConfig*> TopologyConfig::centroidEdgesOf(const std::string& node_name) const {
  std::vector<const NodeConfig*> out;
  for (const auto& n : nodes) {
    if (n.role == Role::kEdge && n.displacement && n.displacement->tracker == node_name) out.push_back(&n);
  }
  return out;
}

std::vector<const NodeConfig*> TopologyConfig::children(const std::string& node_name) const {
  std::vector<const NodeConfig*> out;
  for (const auto& n : nodes) {
    if (n.parent == node_name) out.push_back(&n);
  }
  return out;
}

int TopologyConfig::aggregatorLevels(const std::string& node_name) const {
  std::function<int(const std::string&, std::size_t)> levels = [&](const std::string& at, std::size_t depth) {
    const NodeConfig* n = find(at);
    if (n == nullptr || n->role == Role::kEdge || depth > nodes.size()) return 0;  // cycles are rejected at parse time
    int below = 0;
    for (const auto* c : children(at)) below = std::max(below, levels(c->name, depth + 1));
    return below + 1;
  };
  return levels(node_name, 0);
}

std::vector<std::uint32_t> TopologyConfig::sensorsBelow(const std::string& node_name) const {
  std::vector<std::uint32_t> out;
  std::function<void(const std::string&, int)> walk = [&](const std::string& at, int depth) {
    const NodeConfig* n = find(at);
    if (n == nullptr || depth > static_cast<int>(nodes.size())) return;  // cycles are rejected at parse time
    if (n->role == Role::kEdge) out.push_back(n->id);
    for (const auto* c : children(at)) walk(c->name, depth + 1);
  };
  walk(node_name, 0);
  std::sort(out.begin(), out.end());
  return out;
}

std::optional<TlsIdentity> TopologyConfig::tlsIdentity(const std::string& name) const {
  if (!tls) return std::nullopt;
  const NodeConfig* node = find(name);
  if (node != nullptr && node->tls) return TlsIdentity{tls->ca, node->tls->cert, node->tls->key};
  return TlsIdentity{tls->ca, tls->cert_dir / (name + ".crt"), tls->cert_dir / (name + ".key")};
}

namespace {
constexpr std::size_t kMaxNameChars = 64;
}  // namespace

bool isName(const std::string& name) {
  return !name.empty() && name.size() <= kMaxNameChars && name.front() != '.' &&
         std::all_of(name.begin(), name.end(), [](char c) {
           return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
                  c == '-';
         });
}

bool isCertificateName(const std::string& name) { return isName(name) && name != "ca"; }

namespace {

// Errors name the place in the file: "topology: nodes[3].sensor.rate_hz: must be positive".
const YamlFields kFields("topology");

Error bad(const std::string& where, const std::string& what) { return kFields.bad(where, what); }

template <class T>
Expected<T> scalar(const YAML::Node& node, const std::string& key, const std::string& where, T fallback) {
  return kFields.scalar<T>(node, key, where, fallback);
}

Status checkSection(const YAML::Node& node, const std::string& where, std::initializer_list<std::string_view> keys) {
  return kFields.checkSection(node, where, keys);
}

Expected<Eigen::Vector3d> vec3(const YAML::Node& node, const std::string& key, const std::string& where,
                               const Eigen::Vector3d& fallback) {
  return kFields.vec3(node, key, where, fallback);
}

// A topology's and its nodes' names become file names (the state directory, logs, pid files),
// command-line words and metric labels: letters, digits, '.', '_' and '-', not starting with '.'.
Status checkName(const std::string& name, const std::string& where) {
  constexpr std::size_t kMaxChars = kMaxNameChars;
  if (isName(name)) return {};
  std::string shown;
  for (const char c : name.substr(0, kMaxChars)) shown += std::isprint(static_cast<unsigned char>(c)) ? c : '?';
  return bad(where, "'" + shown + (name.size() > kMaxChars ? "...'" : "'") + " is not a name: use 1 to " +
                        std::to_string(kMaxChars) + " letters, digits, '.', '_' or '-', not starting with '.' "
                        "(names become file names and metric labels)");
}

Expected<Mode> parseMode(const std::string& s) {
  if (s == "madc") return Mode::kMadc;
  if (s == "baseline") return Mode::kBaseline;
  if (s == "ext") return Mode::kExt;
  return bad("mode", "must be madc, baseline or ext, got '" + s + "'");
}

Expected<Eigen::Isometry3d> parsePose(const YAML::Node& node, const std::string& where) { return kFields.pose(node, where); }

Expected<SensorConfig> parseSensor(const YAML::Node& node, const std::string& where, const std::filesystem::path& base_dir) {
  if (const Status st = checkSection(node, where, {"source", "scene", "lidar", "rate_hz", "loop", "frames", "split", "pose"});
      !st) {
    return st.error();
  }
  SensorConfig s;
  const auto source = scalar<std::string>(node, "source", where, "");
  if (!source) return source.error();
  if (source->empty()) {
    return bad(where + ".source", "is required (a directory of scans, one scan file, or sim for a simulated LiDAR)");
  }
  const auto scene = scalar<std::string>(node, "scene", where, "");
  if (!scene) return scene.error();
  const auto lidar = scalar<std::string>(node, "lidar", where, "");
  if (!lidar) return lidar.error();
  if (*source == kSimSource) {
    s.source = kSimSource;
    if (scene->empty()) return bad(where + ".scene", "is required with source sim (the scene file, common/sim)");
    if (lidar->empty()) return bad(where + ".lidar", "is required with source sim (the name of one of the scene's LiDARs)");
    if (node["split"]) {
      return bad(where + ".split", "a simulated LiDAR is not split; give each virtual LiDAR its own LiDAR in the scene");
    }
    s.scene = std::filesystem::path(*scene).is_absolute() ? std::filesystem::path(*scene) : base_dir / *scene;
    s.lidar = *lidar;
  } else {
    if (node["scene"]) return bad(where + ".scene", "goes with source sim only (source is '" + *source + "')");
    if (node["lidar"]) return bad(where + ".lidar", "goes with source sim only (source is '" + *source + "')");
    s.source = std::filesystem::path(*source).is_absolute() ? std::filesystem::path(*source) : base_dir / *source;
  }
  const auto rate = scalar<double>(node, "rate_hz", where, s.rate_hz);
  if (!rate) return rate.error();
  if (!(*rate > 0.0 && *rate <= 1000.0)) return bad(where + ".rate_hz", "must be in (0, 1000]");
  s.rate_hz = *rate;
  const auto loop = scalar<bool>(node, "loop", where, s.loop);
  if (!loop) return loop.error();
  s.loop = *loop;
  if (node["frames"]) {
    const auto frames = scalar<long long>(node, "frames", where, 0);
    if (!frames) return frames.error();
    if (*frames <= 0) return bad(where + ".frames", "must be positive");
    s.frames = static_cast<std::uint64_t>(*frames);
  }
  if (const YAML::Node split = node["split"]) {
    if (const Status st = checkSection(split, where + ".split", {"views", "index", "overlap_deg"}); !st) return st.error();
    SectorSplit sp;
    const auto views = scalar<int>(split, "views", where + ".split", sp.views);
    const auto index = scalar<int>(split, "index", where + ".split", sp.index);
    const auto overlap = scalar<double>(split, "overlap_deg", where + ".split", sp.overlap_deg);
    if (!views) return views.error();
    if (!index) return index.error();
    if (!overlap) return overlap.error();
    if (*views < 1 || *views > 64) return bad(where + ".split.views", "must be in [1, 64]");
    if (*index < 0 || *index >= *views) return bad(where + ".split.index", "must be in [0, views)");
    if (!(*overlap >= 0.0 && *overlap < 360.0 / *views)) return bad(where + ".split.overlap_deg", "must be in [0, 360 / views)");
    sp.views = *views;
    sp.index = *index;
    sp.overlap_deg = *overlap;
    s.split = sp;
  }
  const auto pose = parsePose(node["pose"], where + ".pose");
  if (!pose) return pose.error();
  s.pose = *pose;
  return s;
}

// `detector:` of a camera: {kind: hog|cascade|dnn|truth, hog: {...}, cascade: {...}, dnn: {...},
// truth: {...}}; the section of the chosen kind is read, files resolved against the topology. Values
// are checked when the detection service builds the detector (camera::validate), files included.
Status parseDetector(const YAML::Node& node, const std::string& where, const std::filesystem::path& base_dir,
                     CameraNodeConfig& c) {
  if (const Status st = checkSection(node, where, {"kind", "hog", "cascade", "dnn", "truth"}); !st) return st;
  const auto kind = scalar<std::string>(node, "kind", where, "hog");
  if (!kind) return kind.error();
  if (*kind == "truth") {
    c.truth = true;
  } else {
    const auto parsed = camera::parseDetectorKind(*kind);
    if (!parsed) return bad(where + ".kind", "must be hog, cascade, dnn or truth, got '" + *kind + "'");
    c.detector.kind = *parsed;
  }
  const auto path = [&](const YAML::Node& n, const std::string& key, const std::string& at, std::string& out) -> Status {
    const auto text = scalar<std::string>(n, key, at, "");
    if (!text) return text.error();
    if (!text->empty()) out = (std::filesystem::path(*text).is_absolute() ? std::filesystem::path(*text) : base_dir / *text).string();
    return {};
  };
  if (const YAML::Node h = node["hog"]) {
    const std::string at = where + ".hog";
    if (const Status st = checkSection(h, at, {"hit_threshold", "scale", "win_stride_px", "upscale", "min_height_px", "nms_iou"}); !st) return st;
    auto& d = c.detector.hog;
    const auto a = scalar<double>(h, "hit_threshold", at, d.hit_threshold);
    const auto b = scalar<double>(h, "scale", at, d.scale);
    const auto w = scalar<int>(h, "win_stride_px", at, d.win_stride_px);
    const auto u = scalar<double>(h, "upscale", at, d.upscale);
    const auto m = scalar<double>(h, "min_height_px", at, d.min_height_px);
    const auto n = scalar<double>(h, "nms_iou", at, d.nms_iou);
    for (const auto* e : {&a, &b, &u, &m, &n}) {
      if (!*e) return e->error();
    }
    if (!w) return w.error();
    d.hit_threshold = *a;
    d.scale = *b;
    d.win_stride_px = *w;
    d.upscale = *u;
    d.min_height_px = *m;
    d.nms_iou = *n;
  }
  if (const YAML::Node k = node["cascade"]) {
    const std::string at = where + ".cascade";
    if (const Status st = checkSection(k, at, {"cascade_path", "label", "scale_factor", "min_neighbors", "min_size_px", "nms_iou"}); !st) return st;
    auto& d = c.detector.cascade;
    if (const Status st = path(k, "cascade_path", at, d.cascade_path); !st) return st;
    const auto label = scalar<std::string>(k, "label", at, d.label);
    const auto f = scalar<double>(k, "scale_factor", at, d.scale_factor);
    const auto nb = scalar<int>(k, "min_neighbors", at, d.min_neighbors);
    const auto sz = scalar<int>(k, "min_size_px", at, d.min_size_px);
    const auto n = scalar<double>(k, "nms_iou", at, d.nms_iou);
    if (!label) return label.error();
    if (!f) return f.error();
    if (!nb) return nb.error();
    if (!sz) return sz.error();
    if (!n) return n.error();
    d.label = *label;
    d.scale_factor = *f;
    d.min_neighbors = *nb;
    d.min_size_px = *sz;
    d.nms_iou = *n;
  }
  if (const YAML::Node k = node["dnn"]) {
    const std::string at = where + ".dnn";
    if (const Status st = checkSection(k, at, {"model_path", "config_path", "names_path", "output", "input_width", "input_height",
                                                "mean", "scale", "swap_rb", "confidence_threshold", "nms_threshold"});
        !st) {
      return st;
    }
    auto& d = c.detector.dnn;
    if (const Status st = path(k, "model_path", at, d.model_path); !st) return st;
    if (const Status st = path(k, "config_path", at, d.config_path); !st) return st;
    if (const Status st = path(k, "names_path", at, d.names_path); !st) return st;
    const auto output = scalar<std::string>(k, "output", at, camera::dnnOutputName(d.output));
    if (!output) return output.error();
    const auto parsed = camera::parseDnnOutput(*output);
    if (!parsed) return bad(at + ".output", parsed.error().message);
    d.output = *parsed;
    const auto iw = scalar<int>(k, "input_width", at, d.input_width);
    const auto ih = scalar<int>(k, "input_height", at, d.input_height);
    const auto mean = vec3(k, "mean", at, Eigen::Vector3d(d.mean[0], d.mean[1], d.mean[2]));
    const auto sc = scalar<double>(k, "scale", at, d.scale);
    const auto rb = scalar<bool>(k, "swap_rb", at, d.swap_rb);
    const auto ct = scalar<double>(k, "confidence_threshold", at, d.confidence_threshold);
    const auto nt = scalar<double>(k, "nms_threshold", at, d.nms_threshold);
    if (!iw) return iw.error();
    if (!ih) return ih.error();
    if (!mean) return mean.error();
    if (!sc) return sc.error();
    if (!rb) return rb.error();
    if (!ct) return ct.error();
    if (!nt) return nt.error();
    d.input_width = *iw;
    d.input_height = *ih;
    d.mean = {mean->x(), mean->y(), mean->z()};
    d.scale = *sc;
    d.swap_rb = *rb;
    d.confidence_threshold = *ct;
    d.nms_threshold = *nt;
  }
  if (const YAML::Node t = node["truth"]) {
    const std::string at = where + ".truth";
    if (const Status st = checkSection(t, at, {"miss_rate", "box_jitter_px", "latency_ms"}); !st) return st;
    auto& r = c.truth_replay;
    const auto miss = scalar<double>(t, "miss_rate", at, r.miss_rate);
    const auto jitter = scalar<double>(t, "box_jitter_px", at, r.box_jitter_px);
    const auto latency = scalar<double>(t, "latency_ms", at, r.latency_ms);
    if (!miss) return miss.error();
    if (!jitter) return jitter.error();
    if (!latency) return latency.error();
    if (!(*miss >= 0.0 && *miss <= 1.0)) return bad(at + ".miss_rate", "must be in [0, 1]");
    if (!(*jitter >= 0.0 && *jitter <= 1000.0)) return bad(at + ".box_jitter_px", "must be in [0, 1000] pixels");
    if (!(*latency >= 0.0 && *latency <= 60000.0)) return bad(at + ".latency_ms", "must be in [0, 60000]");
    r.miss_rate = *miss;
    r.box_jitter_px = *jitter;
    r.latency_ms = *latency;
  }
  if (c.truth && !c.simulated()) return bad(where + ".kind", "truth replays a simulated scene: it needs source sim");
  return {};
}

Expected<camera::PinholeCamera> parseCalibration(const YAML::Node& node, const std::string& where, const std::string& name) {
  if (!node) return bad(where, "is required ({fx, fy, cx, cy, width, height, distortion, pose}: where the camera is and how it maps to pixels)");
  if (const Status st = checkSection(node, where, {"fx", "fy", "cx", "cy", "width", "height", "distortion", "pose"}); !st) {
    return st.error();
  }
  camera::PinholeCamera cam;
  cam.name = name;
  const auto fx = scalar<double>(node, "fx", where, cam.fx);
  const auto fy = scalar<double>(node, "fy", where, cam.fy);
  const auto cx = scalar<double>(node, "cx", where, cam.cx);
  const auto cy = scalar<double>(node, "cy", where, cam.cy);
  const auto width = scalar<int>(node, "width", where, cam.width);
  const auto height = scalar<int>(node, "height", where, cam.height);
  const auto distortion = scalar<std::vector<double>>(node, "distortion", where, {});
  for (const auto* e : {&fx, &fy, &cx, &cy}) {
    if (!*e) return e->error();
  }
  if (!width) return width.error();
  if (!height) return height.error();
  if (!distortion) return distortion.error();
  cam.fx = *fx;
  cam.fy = *fy;
  cam.cx = *cx;
  cam.cy = *cy;
  cam.width = *width;
  cam.height = *height;
  if (!distortion->empty()) {
    if (distortion->size() != 5) return bad(where + ".distortion", "must be [k1, k2, p1, p2, k3]");
    cam.distortion = {(*distortion)[0], (*distortion)[1], (*distortion)[2], (*distortion)[3], (*distortion)[4]};
  }
  const auto pose = parsePose(node["pose"], where + ".pose");
  if (!pose) return pose.error();
  cam.world_to_camera = pose->inverse();
  if (const Status st = camera::validate(cam); !st) return bad(where, st.error().message);
  return cam;
}

Expected<CameraNodeConfig> parseCamera(const YAML::Node& node, const std::string& where, const std::filesystem::path& base_dir,
                                       const std::string& node_name) {
  if (const Status st = checkSection(node, where, {"source", "scene", "camera", "rate_hz", "loop", "frames", "queue_frames",
                                                    "max_image_pixels", "detector", "calibration"});
      !st) {
    return st.error();
  }
  CameraNodeConfig c;
  const auto source = scalar<std::string>(node, "source", where, "");
  if (!source) return source.error();
  if (source->empty()) {
    return bad(where + ".source", "is required (a directory of images, a video file, a V4L2 device such as /dev/video0, or sim)");
  }
  const auto scene = scalar<std::string>(node, "scene", where, "");
  const auto cam = scalar<std::string>(node, "camera", where, "");
  if (!scene) return scene.error();
  if (!cam) return cam.error();
  if (*source == kSimSource) {
    c.source = kSimSource;
    if (scene->empty()) return bad(where + ".scene", "is required with source sim (the scene file, common/sim)");
    if (cam->empty()) return bad(where + ".camera", "is required with source sim (the name of one of the scene's cameras)");
    c.scene = std::filesystem::path(*scene).is_absolute() ? std::filesystem::path(*scene) : base_dir / *scene;
    c.camera = *cam;
  } else {
    if (node["scene"]) return bad(where + ".scene", "goes with source sim only");
    if (node["camera"]) return bad(where + ".camera", "goes with source sim only");
    // A device stays as written; files and directories resolve against the topology.
    c.source = (std::filesystem::path(*source).is_absolute() || source->rfind("/dev/", 0) == 0)
                   ? std::filesystem::path(*source)
                   : base_dir / *source;
  }
  const auto rate = scalar<double>(node, "rate_hz", where, c.rate_hz);
  const auto loop = scalar<bool>(node, "loop", where, c.loop);
  const auto queue = scalar<long long>(node, "queue_frames", where, static_cast<long long>(c.queue_frames));
  if (!rate) return rate.error();
  if (!loop) return loop.error();
  if (!queue) return queue.error();
  if (!(*rate > 0.0 && *rate <= 1000.0)) return bad(where + ".rate_hz", "must be in (0, 1000]");
  if (*queue < 1 || *queue > 1000) return bad(where + ".queue_frames", "must be in [1, 1000]");
  c.rate_hz = *rate;
  c.loop = *loop;
  c.queue_frames = static_cast<std::size_t>(*queue);
  const auto max_pixels = scalar<long long>(node, "max_image_pixels", where, static_cast<long long>(c.max_image_pixels));
  if (!max_pixels) return max_pixels.error();
  if (*max_pixels < 1 || static_cast<unsigned long long>(*max_pixels) > camera::kMaxImagePixelsBound) {
    return bad(where + ".max_image_pixels", "must be in [1, " + std::to_string(camera::kMaxImagePixelsBound) +
                                                "] (16384 x 16384), got " + std::to_string(*max_pixels));
  }
  c.max_image_pixels = static_cast<std::uint64_t>(*max_pixels);
  if (node["frames"]) {
    const auto frames = scalar<long long>(node, "frames", where, 0);
    if (!frames) return frames.error();
    if (*frames <= 0) return bad(where + ".frames", "must be positive");
    c.frames = static_cast<std::uint64_t>(*frames);
  }
  if (const YAML::Node d = node["detector"]) {
    if (const Status st = parseDetector(d, where + ".detector", base_dir, c); !st) return st.error();
  }
  auto calibration = parseCalibration(node["calibration"], where + ".calibration", node_name);
  if (!calibration) return calibration.error();
  c.calibration = std::move(*calibration);
  return c;
}

Expected<TrackerNodeConfig> parseTracker(const YAML::Node& node, const std::string& where) {
  if (const Status st = checkSection(node, where, {"input", "centroid_merge_m", "visible_side_max_radius_m", "association", "eps_sync_s", "rho_overlay_m", "rho_purecloud_m", "gate_chi2",
                                                    "acceleration_sigma", "initial_speed_sigma", "min_measurement_sigma_m",
                                                    "confirm_hits", "tentative_timeout_s", "track_timeout_s",
                                                    "max_buffered_frames", "max_detection_wait_s"});
      !st) {
    return st.error();
  }
  TrackerNodeConfig t;
  const auto input = scalar<std::string>(node, "input", where, trackerInputName(t.input));
  if (!input) return input.error();
  const auto parsed_input = parseTrackerInput(*input);
  if (!parsed_input) return bad(where + ".input", parsed_input.error().message);
  t.input = *parsed_input;
  if (node["centroid_merge_m"]) {
    if (t.input != TrackerInput::kCentroids) return bad(where + ".centroid_merge_m", "goes with input: centroids only");
    const auto merge = scalar<double>(node, "centroid_merge_m", where, t.centroid_merge_m);
    if (!merge) return merge.error();
    if (!(*merge >= 0.0 && *merge <= 100.0)) {
      return bad(where + ".centroid_merge_m", "must be in [0, 100] metres (0: every centroid its own observation)");
    }
    t.centroid_merge_m = *merge;
  }
  if (node["visible_side_max_radius_m"]) {
    if (t.input != TrackerInput::kCentroids) return bad(where + ".visible_side_max_radius_m", "goes with input: centroids only");
    const auto radius = scalar<double>(node, "visible_side_max_radius_m", where, t.visible_side_max_radius_m);
    if (!radius) return radius.error();
    if (!(*radius >= 0.0 && *radius <= 10.0)) {
      return bad(where + ".visible_side_max_radius_m", "must be in [0, 10] metres (0: centroids left on the visible side)");
    }
    t.visible_side_max_radius_m = *radius;
  }
  auto& c = t.tracking;
  const auto association = scalar<std::string>(node, "association", where, tracking::associationName(c.association));
  if (!association) return association.error();
  const auto parsed = tracking::parseAssociation(*association);
  if (!parsed) return bad(where + ".association", parsed.error().message);
  c.association = *parsed;
  const auto number = [&](const std::string& key, double& value) -> Status {
    const auto v = scalar<double>(node, key, where, value);
    if (!v) return v.error();
    value = *v;
    return {};
  };
  for (auto [key, value] : std::initializer_list<std::pair<const char*, double*>>{
           {"eps_sync_s", &c.eps_sync_s}, {"rho_overlay_m", &c.rho_overlay_m}, {"rho_purecloud_m", &c.rho_purecloud_m},
           {"gate_chi2", &c.gate_chi2}, {"acceleration_sigma", &c.acceleration_sigma},
           {"initial_speed_sigma", &c.initial_speed_sigma}, {"min_measurement_sigma_m", &c.min_measurement_sigma_m},
           {"tentative_timeout_s", &c.tentative_timeout_s}, {"track_timeout_s", &c.track_timeout_s},
           {"max_detection_wait_s", &c.max_detection_wait_s}}) {
    if (const Status st = number(key, *value); !st) return st.error();
  }
  const auto hits = scalar<int>(node, "confirm_hits", where, c.confirm_hits);
  const auto buffered = scalar<long long>(node, "max_buffered_frames", where, static_cast<long long>(c.max_buffered_frames));
  if (!hits) return hits.error();
  if (!buffered) return buffered.error();
  c.confirm_hits = *hits;
  if (*buffered < 1 || *buffered > 100000) return bad(where + ".max_buffered_frames", "must be in [1, 100000]");
  c.max_buffered_frames = static_cast<std::size_t>(*buffered);
  if (const Status st = tracking::validate(c); !st) return bad(where, st.error().message);
  return t;
}

// `displacement:` of an edge: {tracker, preset, voxel_m, neighbour_m, min_neighbours, min_points,
// min_z_variance_m2}; the preset gives the starting values, the keys given override them.
Expected<DisplacementNodeConfig> parseDisplacement(const YAML::Node& node, const std::string& where) {
  if (const Status st = checkSection(node, where, {"tracker", "preset", "voxel_m", "neighbour_m", "min_neighbours",
                                                    "min_points", "min_z_variance_m2"});
      !st) {
    return st.error();
  }
  DisplacementNodeConfig d;
  const auto tracker = scalar<std::string>(node, "tracker", where, "");
  if (!tracker) return tracker.error();
  if (tracker->empty()) return bad(where + ".tracker", "is required (the tracker node that fuses this edge's centroids)");
  d.tracker = *tracker;
  const auto preset = scalar<std::string>(node, "preset", where, "indoor");
  if (!preset) return preset.error();
  if (*preset == "indoor") {
    d.params = tracking::DisplacementParams::indoor();
  } else if (*preset == "outdoor") {
    d.params = tracking::DisplacementParams::outdoor();
  } else {
    return bad(where + ".preset", "must be indoor (0.1 m voxels) or outdoor (1.0 m voxels), got '" + *preset + "'");
  }
  auto& p = d.params;
  for (auto [key, value] : std::initializer_list<std::pair<const char*, double*>>{
           {"voxel_m", &p.voxel_m}, {"neighbour_m", &p.neighbour_m}, {"min_z_variance_m2", &p.min_z_variance_m2}}) {
    const auto v = scalar<double>(node, key, where, *value);
    if (!v) return v.error();
    *value = *v;
  }
  for (auto [key, value] : std::initializer_list<std::pair<const char*, std::size_t*>>{
           {"min_neighbours", &p.min_neighbours}, {"min_points", &p.min_points}}) {
    const auto v = scalar<long long>(node, key, where, static_cast<long long>(*value));
    if (!v) return v.error();
    if (*v < 0 || *v > 1'000'000) return bad(where + "." + key, "must be in [0, 1000000], got " + std::to_string(*v));
    *value = static_cast<std::size_t>(*v);
  }
  if (const Status st = tracking::validateDisplacementParams(p); !st) return bad(where, st.error().message);
  return d;
}

std::filesystem::path resolve(const std::string& path, const std::filesystem::path& base_dir) {
  return std::filesystem::path(path).is_absolute() ? std::filesystem::path(path) : base_dir / path;
}

// A required path: present, a string, not empty.
Expected<std::filesystem::path> requiredPath(const YAML::Node& node, const std::string& key, const std::string& where,
                                             const std::filesystem::path& base_dir, const std::string& what) {
  const auto text = scalar<std::string>(node, key, where, "");
  if (!text) return text.error();
  if (text->empty()) return bad(where + "." + key, "is required (" + what + ")");
  return resolve(*text, base_dir);
}

Expected<TlsConfig> parseTls(const YAML::Node& node, const std::filesystem::path& base_dir) {
  if (const Status s = checkSection(node, "tls", {"ca", "cert_dir", "geofence_clients"}); !s) return s.error();
  TlsConfig tls;
  const auto ca = requiredPath(node, "ca", "tls", base_dir, "the CA certificate every certificate must chain to");
  if (!ca) return ca.error();
  tls.ca = *ca;
  tls.cert_dir = tls.ca.parent_path();
  if (node["cert_dir"]) {
    const auto dir = requiredPath(node, "cert_dir", "tls", base_dir, "the directory of <name>.crt and <name>.key");
    if (!dir) return dir.error();
    tls.cert_dir = *dir;
  }
  if (const YAML::Node clients = node["geofence_clients"]) {
    if (!clients.IsSequence()) return bad("tls.geofence_clients", "expected a list of certificate names");
    for (std::size_t i = 0; i < clients.size(); ++i) {
      const std::string where = "tls.geofence_clients[" + std::to_string(i) + "]";
      if (!clients[i].IsScalar()) return bad(where, "expected a certificate name");
      const std::string name = clients[i].Scalar();
      if (!isCertificateName(name)) {
        return bad(where, "'" + name + "' is not a certificate name (letters, digits, '.', '_', '-'; not 'ca')");
      }
      if (std::find(tls.geofence_clients.begin(), tls.geofence_clients.end(), name) != tls.geofence_clients.end()) {
        return bad(where, "'" + name + "' is listed twice");
      }
      tls.geofence_clients.push_back(name);
    }
  }
  return tls;
}

Expected<TlsFiles> parseNodeTls(const YAML::Node& node, const std::string& where, const std::filesystem::path& base_dir) {
  if (const Status s = checkSection(node, where, {"cert", "key"}); !s) return s.error();
  const auto cert = requiredPath(node, "cert", where, base_dir, "the node's certificate; give it with key, or neither");
  if (!cert) return cert.error();
  const auto key = requiredPath(node, "key", where, base_dir, "the certificate's private key; give it with cert, or neither");
  if (!key) return key.error();
  return TlsFiles{*cert, *key};
}

// The services listen on and connect to "host:port" as written, and fogctl polls /metrics over
// IPv4, so a name such as localhost (or an IPv6 address, which would need brackets) would pass
// here and then time out at start-up.
bool isIpv4Address(const std::string& host) {
  in_addr address{};
  return host.find('\0') == std::string::npos && ::inet_pton(AF_INET, host.c_str(), &address) == 1;
}

// The parent chain from `start` (every parent exists): the cycle it runs into, or empty when it
// reaches a root.
std::vector<std::string> parentCycle(const TopologyConfig& t, const NodeConfig& start) {
  std::vector<std::string> chain;
  for (const NodeConfig* at = &start; at != nullptr && !at->parent.empty(); at = t.find(at->parent)) {
    const auto seen = std::find(chain.begin(), chain.end(), at->name);
    if (seen != chain.end()) {
      std::vector<std::string> cycle(seen, chain.end());
      cycle.push_back(at->name);
      return cycle;
    }
    chain.push_back(at->name);
  }
  return {};
}

Status validate(const TopologyConfig& t) {
  if (t.nodes.empty()) return bad("nodes", "at least one node is required");
  std::set<std::string> names;
  std::set<std::uint32_t> ids;
  std::set<std::pair<std::string, std::uint16_t>> ports;
  int roots = 0;
  for (std::size_t i = 0; i < t.nodes.size(); ++i) {
    const auto& n = t.nodes[i];
    const std::string where = "nodes[" + std::to_string(i) + "] (" + n.name + ")";
    if (!names.insert(n.name).second) return bad(where, "duplicate node name");
    if (!ids.insert(n.id).second) return bad(where, "duplicate node id " + std::to_string(n.id));
    if (!isIpv4Address(n.host)) {
      return bad(where + ".host", "host '" + n.host + "': give an IPv4 address such as 127.0.0.1 (the services listen on "
                                  "and connect to numeric addresses, not names)");
    }
    for (const auto p : {n.port, n.metrics_port}) {
      if (p != 0 && !ports.insert({n.host, p}).second) return bad(where, "port " + std::to_string(p) + " used twice on " + n.host);
    }
    if (n.metrics_port == 0) return bad(where, "metrics_port is required");
    if ((n.role == Role::kAggregator || n.role == Role::kTracker) && n.port == 0) {
      return bad(where, std::string("a") + (n.role == Role::kTracker ? " tracker" : "n aggregator") + " needs a port");
    }
    if (n.role == Role::kEdge && !n.sensor) return bad(where, "an edge needs a sensor");
    if (n.role != Role::kEdge && n.sensor) return bad(where + ".sensor", "only edges have a sensor");
    if (n.role == Role::kDetection && !n.camera) return bad(where, "a detection node needs a camera");
    if (n.role != Role::kDetection && n.camera) return bad(where + ".camera", "only detection nodes have a camera");
    if (n.role != Role::kTracker && n.tracker) return bad(where + ".tracker", "only tracker nodes have a tracker section");
    if (n.role != Role::kEdge && n.displacement) return bad(where + ".displacement", "only edges have a displacement section");
    if (n.role == Role::kEdge && n.parent.empty()) return bad(where, "an edge needs a parent aggregator");
    if (n.role == Role::kDetection && n.parent.empty()) return bad(where, "a detection node needs a parent tracker");
    if (n.role == Role::kTracker) {
      if (!n.parent.empty()) return bad(where + ".parent", "a tracker has no parent (it reads the root's global map)");
      continue;
    }
    if (n.parent.empty()) {
      ++roots;
      continue;
    }
    if (n.parent == n.name) return bad(where + ".parent", "node '" + n.name + "' is its own parent");
    const NodeConfig* parent = t.find(n.parent);
    if (parent == nullptr) return bad(where + ".parent", "no node named '" + n.parent + "'");
    if (n.role == Role::kDetection) {
      if (parent->role != Role::kTracker) return bad(where + ".parent", "'" + n.parent + "' is not a tracker");
      continue;
    }
    if (parent->role != Role::kAggregator) return bad(where + ".parent", "'" + n.parent + "' is not an aggregator");
  }
  // Cycles first: a cycle with no way out also leaves the tree without a root.
  for (const auto& n : t.nodes) {
    const std::vector<std::string> cycle = parentCycle(t, n);
    if (cycle.empty()) continue;
    std::string path = cycle.front();
    for (std::size_t i = 1; i < cycle.size(); ++i) path += " -> " + cycle[i];
    return bad("nodes", "the parents of '" + cycle.front() + "' form a cycle: " + path);
  }
  if (roots != 1) return bad("nodes", "exactly one node (the root aggregator) must have no parent, found " + std::to_string(roots));
  if (t.root() == nullptr) return bad("nodes", "the node without a parent must be an aggregator (the root)");
  // Centroids go to a tracker that takes them, and a tracker that takes them gets some.
  for (std::size_t i = 0; i < t.nodes.size(); ++i) {
    const auto& n = t.nodes[i];
    const std::string where = "nodes[" + std::to_string(i) + "] (" + n.name + ")";
    if (n.displacement) {
      const std::string& name = n.displacement->tracker;
      const NodeConfig* tracker = t.find(name);
      if (tracker == nullptr) return bad(where + ".displacement.tracker", "no node named '" + name + "'");
      if (tracker->role != Role::kTracker) {
        return bad(where + ".displacement.tracker", "'" + name + "' is not a tracker (role " +
                                                        roleName(tracker->role) + ")");
      }
      if (tracker->tracker->input != TrackerInput::kCentroids) {
        return bad(where + ".displacement.tracker", "tracker '" + name + "' reads the root's global map; give it "
                                                    "tracker: {input: centroids} to fuse this edge's centroids");
      }
    }
    if (n.role == Role::kTracker && n.tracker->input == TrackerInput::kCentroids && t.centroidEdgesOf(n.name).empty()) {
      return bad(where + ".tracker.input", "is centroids, but no edge sends this tracker any (give edges "
                                           "displacement: {tracker: " + n.name + "})");
    }
  }
  for (std::size_t i = 0; i < t.nodes.size(); ++i) {
    const auto& n = t.nodes[i];
    const std::string where = "nodes[" + std::to_string(i) + "] (" + n.name + ")";
    if (n.tls && !t.tls) return bad(where + ".tls", "the topology has no tls section (add tls: {ca: ...})");
    // The name is the certificate's common name, and (without an override) a file name.
    if (t.tls && !n.tls && !isCertificateName(n.name)) {
      return bad(where + ".name", "with tls, a node name is its certificate's file name: letters, digits, '.', '_', '-', "
                                  "not 'ca' (or give the node tls: {cert, key})");
    }
  }
  return {};
}

Expected<TopologyConfig> parseDocument(const YAML::Node& root, const std::filesystem::path& base_dir) {
  if (!root.IsMap()) return invalidArgument("topology: the document must be a mapping with 'nodes'");
  if (const Status s = checkSection(root, "", {"name", "mode", "baseline_ships", "deadline_ms", "period_ms", "max_message_bytes",
                                               "max_scan_bytes", "admission", "madc", "preprocess", "tls", "nodes"});
      !s) {
    return s.error();
  }
  TopologyConfig t;
  const auto name = scalar<std::string>(root, "name", "", "topology");
  if (!name) return name.error();
  if (const Status s = checkName(*name, "name"); !s) return s.error();
  t.name = *name;
  const auto mode = scalar<std::string>(root, "mode", "", "madc");
  if (!mode) return mode.error();
  const auto parsed_mode = parseMode(*mode);
  if (!parsed_mode) return parsed_mode.error();
  t.mode = *parsed_mode;
  const auto ships = scalar<std::string>(root, "baseline_ships", "", "processed");
  if (!ships) return ships.error();
  if (*ships != "processed" && *ships != "raw") {
    return bad("baseline_ships", "must be processed or raw, got '" + *ships + "'");
  }
  t.baseline_ships_raw = *ships == "raw";
  const auto deadline = scalar<double>(root, "deadline_ms", "", t.deadline_ms);
  if (!deadline) return deadline.error();
  if (!(*deadline > 0.0 && *deadline <= 60000.0)) return bad("deadline_ms", "must be in (0, 60000]");
  t.deadline_ms = *deadline;
  const auto period = scalar<double>(root, "period_ms", "", t.period_ms);
  if (!period) return period.error();
  if (!(*period > 0.0 && *period <= 60000.0)) return bad("period_ms", "must be in (0, 60000]");
  t.period_ms = *period;
  const auto max_bytes = scalar<long long>(root, "max_message_bytes", "", static_cast<long long>(t.max_message_bytes));
  if (!max_bytes) return max_bytes.error();
  if (*max_bytes < (1 << 20) || *max_bytes > (1LL << 30)) return bad("max_message_bytes", "must be in [1 MiB, 1 GiB]");
  t.max_message_bytes = static_cast<std::size_t>(*max_bytes);
  const auto scan_bytes = scalar<long long>(root, "max_scan_bytes", "", static_cast<long long>(t.max_scan_bytes));
  if (!scan_bytes) return scan_bytes.error();
  if (*scan_bytes <= 0) return bad("max_scan_bytes", "must be a positive number of bytes, got " + std::to_string(*scan_bytes));
  t.max_scan_bytes = static_cast<std::uintmax_t>(*scan_bytes);
  if (const YAML::Node a = root["admission"]) {
    if (const Status s = checkSection(a, "admission", {"window_periods", "world_extent_m", "max_ellipsoids_per_map",
                                                       "max_map_bytes", "min_eigenvalue_m2", "max_eigenvalue_m2",
                                                       "max_condition", "max_subscribers"});
        !s) {
      return s.error();
    }
    AdmissionLimits& limits = t.admission;
    for (const auto& [key, value] : {std::pair{"window_periods", &limits.window_periods},
                                     std::pair{"world_extent_m", &limits.world_extent_m},
                                     std::pair{"min_eigenvalue_m2", &limits.min_eigenvalue_m2},
                                     std::pair{"max_eigenvalue_m2", &limits.max_eigenvalue_m2},
                                     std::pair{"max_condition", &limits.max_condition}}) {
      const auto read = scalar<double>(a, key, "admission", *value);
      if (!read) return read.error();
      *value = *read;
    }
    for (const auto& [key, value] : {std::pair{"max_ellipsoids_per_map", &limits.max_ellipsoids_per_map},
                                     std::pair{"max_map_bytes", &limits.max_map_bytes},
                                     std::pair{"max_subscribers", &limits.max_subscribers}}) {
      const auto read = scalar<long long>(a, key, "admission", static_cast<long long>(*value));
      if (!read) return read.error();
      // Only what a count cannot hold; the value rules are validateAdmissionLimits's.
      if (*read < 0) return bad(std::string("admission.") + key, "must be a positive integer, got " + std::to_string(*read));
      *value = static_cast<std::size_t>(*read);
    }
  }
  // Its messages name the key ("admission window_periods must be ...").
  if (const Status s = validateAdmissionLimits(t.admission); !s) return invalidArgument("topology: " + s.error().message);

  if (const YAML::Node m = root["madc"]) {
    if (const Status s = checkSection(m, "madc", {"eps_m", "min_points", "alpha", "threads"}); !s) return s.error();
    const auto eps = scalar<double>(m, "eps_m", "madc", t.madc.clustering.eps_m);
    const auto min_points = scalar<long long>(m, "min_points", "madc", static_cast<long long>(t.madc.clustering.min_points));
    const auto alpha = scalar<double>(m, "alpha", "madc", t.madc.alpha);
    const auto threads = scalar<long long>(m, "threads", "madc", static_cast<long long>(t.madc.clustering.threads));
    if (!eps) return eps.error();
    if (!min_points) return min_points.error();
    if (!alpha) return alpha.error();
    if (!threads) return threads.error();
    if (*min_points < 1 || *min_points > std::numeric_limits<std::int32_t>::max()) {
      return bad("madc.min_points", "must be in [1, 2^31)");
    }
    if (!(*alpha > 0.0 && *alpha < 10.0)) return bad("madc.alpha", "must be in (0, 10)");
    if (*threads < 1 || *threads > 256) return bad("madc.threads", "must be in [1, 256]");
    t.madc.clustering.eps_m = *eps;
    t.madc.clustering.min_points = static_cast<std::size_t>(*min_points);
    t.madc.alpha = *alpha;
    t.madc.clustering.threads = static_cast<std::size_t>(*threads);
  }
  // eps_m's range is validateClusteringParams's; its messages start with the field's name.
  if (const Status s = validateClusteringParams(t.madc.clustering); !s) {
    return invalidArgument("topology: madc." + s.error().message);
  }
  if (const YAML::Node p = root["preprocess"]) {
    if (const Status s = checkSection(p, "preprocess", {"crop", "voxel_leaf_m", "ground"}); !s) return s.error();
    if (const YAML::Node crop = p["crop"]) {
      if (const Status s = checkSection(crop, "preprocess.crop", {"min_m", "max_m"}); !s) return s.error();
      CropBox box;
      const auto lo = vec3(crop, "min_m", "preprocess.crop", box.min_m);
      const auto hi = vec3(crop, "max_m", "preprocess.crop", box.max_m);
      if (!lo) return lo.error();
      if (!hi) return hi.error();
      if (((*lo).array() >= (*hi).array()).any()) return bad("preprocess.crop", "min_m must be below max_m on every axis");
      box.min_m = *lo;
      box.max_m = *hi;
      t.preprocess.crop = box;
    }
    if (p["voxel_leaf_m"]) {
      const auto leaf = scalar<double>(p, "voxel_leaf_m", "preprocess", 0.0);
      if (!leaf) return leaf.error();
      if (!(*leaf > 0.0)) return bad("preprocess.voxel_leaf_m", "must be positive");
      t.preprocess.voxel_leaf_m = *leaf;
    }
    if (const YAML::Node g = p["ground"]) {
      if (const Status s = checkSection(g, "preprocess.ground", {"distance_threshold_m", "max_tilt_deg", "ground_z_hint_m"}); !s) {
        return s.error();
      }
      GroundParams ground;
      const auto threshold = scalar<double>(g, "distance_threshold_m", "preprocess.ground", ground.distance_threshold_m);
      const auto tilt = scalar<double>(g, "max_tilt_deg", "preprocess.ground", ground.max_tilt_deg);
      if (!threshold) return threshold.error();
      if (!tilt) return tilt.error();
      if (!(*threshold > 0.0 && *threshold < 5.0)) return bad("preprocess.ground.distance_threshold_m", "must be in (0, 5)");
      if (!(*tilt > 0.0 && *tilt < 90.0)) return bad("preprocess.ground.max_tilt_deg", "must be in (0, 90)");
      ground.distance_threshold_m = *threshold;
      ground.max_tilt_deg = *tilt;
      if (g["ground_z_hint_m"]) {
        const auto hint = scalar<double>(g, "ground_z_hint_m", "preprocess.ground", 0.0);
        if (!hint) return hint.error();
        if (!std::isfinite(*hint)) return bad("preprocess.ground.ground_z_hint_m", "must be finite");
        ground.ground_z_hint_m = *hint;
      }
      t.preprocess.ground = ground;
    }
  }

  if (const YAML::Node tls = root["tls"]) {
    auto parsed = parseTls(tls, base_dir);
    if (!parsed) return parsed.error();
    t.tls = std::move(*parsed);
  }

  const YAML::Node nodes = root["nodes"];
  if (!nodes || !nodes.IsSequence()) return bad("nodes", "a list of nodes is required");
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const YAML::Node n = nodes[i];
    const std::string where = "nodes[" + std::to_string(i) + "]";
    if (!n.IsMap()) return bad(where, "each node must be a mapping");
    if (const Status s =
            checkSection(n, where, {"name", "id", "role", "parent", "host", "port", "metrics_port", "sensor", "camera", "tracker",
                                    "displacement", "tls"});
        !s) {
      return s.error();
    }
    NodeConfig node;
    const auto node_name = scalar<std::string>(n, "name", where, "");
    if (!node_name) return node_name.error();
    if (node_name->empty()) return bad(where + ".name", "is required");
    if (const Status s = checkName(*node_name, where + ".name"); !s) return s.error();
    node.name = *node_name;
    const auto id = scalar<long long>(n, "id", where, -1);
    if (!id) return id.error();
    if (*id < 0 || *id > 0xFFFFFFFFLL) return bad(where + ".id", "a node id in [0, 2^32) is required");
    node.id = static_cast<std::uint32_t>(*id);
    const auto role = scalar<std::string>(n, "role", where, "");
    if (!role) return role.error();
    if (*role == "edge") {
      node.role = Role::kEdge;
    } else if (*role == "aggregator") {
      node.role = Role::kAggregator;
    } else if (*role == "detection") {
      node.role = Role::kDetection;
    } else if (*role == "tracker") {
      node.role = Role::kTracker;
    } else {
      return bad(where + ".role", "must be edge, aggregator, detection or tracker, got '" + *role + "'");
    }
    const auto parent = scalar<std::string>(n, "parent", where, "");
    const auto host = scalar<std::string>(n, "host", where, node.host);
    const auto port = scalar<long long>(n, "port", where, 0);
    const auto metrics_port = scalar<long long>(n, "metrics_port", where, 0);
    if (!parent) return parent.error();
    if (!host) return host.error();
    if (!port) return port.error();
    if (!metrics_port) return metrics_port.error();
    if (*port < 0 || *port > 65535) return bad(where + ".port", "must be a TCP port");
    if (*metrics_port < 0 || *metrics_port > 65535) return bad(where + ".metrics_port", "must be a TCP port");
    node.parent = *parent;
    node.host = *host;
    node.port = static_cast<std::uint16_t>(*port);
    node.metrics_port = static_cast<std::uint16_t>(*metrics_port);
    if (const YAML::Node sensor = n["sensor"]) {
      auto s = parseSensor(sensor, where + ".sensor", base_dir);
      if (!s) return s.error();
      node.sensor = std::move(*s);
    }
    if (const YAML::Node camera = n["camera"]) {
      auto c = parseCamera(camera, where + ".camera", base_dir, node.name);
      if (!c) return c.error();
      node.camera = std::move(*c);
    }
    if (const YAML::Node tracker = n["tracker"]) {
      auto c = parseTracker(tracker, where + ".tracker");
      if (!c) return c.error();
      node.tracker = std::move(*c);
    } else if (node.role == Role::kTracker) {
      node.tracker = TrackerNodeConfig{};
    }
    if (const YAML::Node displacement = n["displacement"]) {
      auto d = parseDisplacement(displacement, where + ".displacement");
      if (!d) return d.error();
      node.displacement = std::move(*d);
    }
    if (const YAML::Node tls = n["tls"]) {
      auto files = parseNodeTls(tls, where + ".tls", base_dir);
      if (!files) return files.error();
      node.tls = std::move(*files);
    }
    t.nodes.push_back(std::move(node));
  }
  if (const Status s = validate(t); !s) return s.error();
  return t;
}

}  // namespace

Expected<TopologyConfig> parseTopology(const std::string& yaml_text, const std::filesystem::path& base_dir) {
  try {
    return parseDocument(YAML::Load(yaml_text), base_dir);
  } catch (const YAML::Exception& e) {
    return invalidArgument(std::string("topology: not valid YAML: ") + e.what());
  }
}

Expected<TopologyConfig> loadTopology(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) return notFound("topology: cannot open " + path.string());
  std::stringstream text;
  text << in.rdbuf();
  auto t = parseTopology(text.str(), path.parent_path());
  if (!t) return Error{t.error().code, path.string() + ": " + t.error().message};
  return t;
}

const char* serviceName(Role role) {
  switch (role) {
    case Role::kEdge:
      return "edge-cluster";
    case Role::kAggregator:
      return "merge-aggregator";
    case Role::kDetection:
      return "detection";
    case Role::kTracker:
      return "tracker";
  }
  return "unknown";
}

const char* trackerInputName(TrackerInput input) {
  switch (input) {
    case TrackerInput::kGlobalMap:
      return "global_map";
    case TrackerInput::kCentroids:
      return "centroids";
  }
  return "unknown";
}

Expected<TrackerInput> parseTrackerInput(const std::string& name) {
  if (name == "global_map") return TrackerInput::kGlobalMap;
  if (name == "centroids") return TrackerInput::kCentroids;
  return invalidArgument("must be global_map (the root's global map) or centroids (its edges' displacement centroids), got '" +
                         name + "'");
}

const char* roleName(Role role) {
  switch (role) {
    case Role::kEdge:
      return "edge";
    case Role::kAggregator:
      return "aggregator";
    case Role::kDetection:
      return "detection";
    case Role::kTracker:
      return "tracker";
  }
  return "unknown";
}

namespace {

TopologyConfig baseTopology(const std::string& name) {
  TopologyConfig t;
  t.name = name;
  t.preprocess.crop = CropBox{{-40.0, -40.0, -3.0}, {40.0, 40.0, 3.0}};
  t.preprocess.ground = GroundParams{};
  // The ready-made topologies replay KITTI: the HDL-64E sits 1.73 m above the road, so the ground
  // lies near z = -1.73 m in the common (first sensor's) frame.
  t.preprocess.ground->ground_z_hint_m = -1.73;
  return t;
}

NodeConfig edgeNode(int index, int edges, const std::filesystem::path& source, const std::string& parent, int base_port) {
  NodeConfig n;
  n.id = static_cast<std::uint32_t>(index + 1);
  n.name = "edge-" + std::to_string(index + 1);
  n.role = Role::kEdge;
  n.parent = parent;
  n.metrics_port = static_cast<std::uint16_t>(base_port + 100 + index + 1);
  SensorConfig s;
  s.source = source;
  s.split = SectorSplit{edges, index, 10.0};
  n.sensor = s;
  return n;
}

NodeConfig aggregatorNode(int index, const std::string& name, const std::string& parent, int base_port) {
  NodeConfig n;
  n.id = static_cast<std::uint32_t>(100 + index);
  n.name = name;
  n.role = Role::kAggregator;
  n.parent = parent;
  n.port = static_cast<std::uint16_t>(base_port + index);
  n.metrics_port = static_cast<std::uint16_t>(base_port + 200 + index);
  return n;
}

}  // namespace

TopologyConfig makeStarTopology(int edges, const std::filesystem::path& source, int base_port) {
  TopologyConfig t = baseTopology("star-" + std::to_string(edges));
  t.nodes.push_back(aggregatorNode(0, "sink", "", base_port));
  for (int i = 0; i < edges; ++i) t.nodes.push_back(edgeNode(i, edges, source, "sink", base_port));
  return t;
}

TopologyConfig makeTreeTopology(int edges, const std::filesystem::path& source, int base_port, int fanout) {
  fanout = std::max(fanout, 2);
  if (edges <= 1) return makeStarTopology(1, source, base_port);  // a lone edge still needs a sink
  TopologyConfig t = baseTopology("tree-" + std::to_string(edges) + (fanout == 2 ? "" : "-f" + std::to_string(fanout)));
  int aggregators = 0;
  // A balanced tree: an aggregator over at most `fanout` subtrees of sizes that differ by at most
  // one (the larger first); a subtree of one edge is the edge itself.
  std::function<void(int, int, const std::string&)> build = [&](int first, int count, const std::string& parent) {
    if (count == 1) {
      t.nodes.push_back(edgeNode(first, edges, source, parent, base_port));
      return;
    }
    const int index = aggregators++;
    const std::string name = index == 0 ? "sink" : "agg-" + std::to_string(index);
    t.nodes.push_back(aggregatorNode(index, name, parent, base_port));
    // As few levels as `fanout` allows (capacity = fanout^levels >= count); here as many subtrees
    // as the level below needs, at most `fanout`: tree-7 with fanout 4 is a sink over 4 + 3 edges.
    int below = 1;  // edges a subtree one level down can hold
    while (below * fanout < count) below *= fanout;
    const int parts = std::min(fanout, (count + below - 1) / below);
    for (int part = 0, start = first; part < parts; ++part) {
      const int size = count / parts + (part < count % parts ? 1 : 0);
      build(start, size, name);
      start += size;
    }
  };
  build(0, edges, "");
  return t;
}

NodeConfig trackerNode(int base_port, const tracking::TrackerConfig& tracking) {
  NodeConfig n;
  n.id = 300;
  n.name = kTrackerNodeName;
  n.role = Role::kTracker;
  n.port = static_cast<std::uint16_t>(base_port + 300);
  n.metrics_port = static_cast<std::uint16_t>(base_port + 301);
  n.tracker = TrackerNodeConfig{tracking};
  return n;
}

NodeConfig detectionNode(int number, const std::string& name, const std::string& tracker, int base_port,
                         CameraNodeConfig camera) {
  NodeConfig n;
  n.id = static_cast<std::uint32_t>(400 + number);
  n.name = name;
  n.role = Role::kDetection;
  n.parent = tracker;
  n.metrics_port = static_cast<std::uint16_t>(base_port + 400 + number);
  camera.calibration.name = name;
  n.camera = std::move(camera);
  return n;
}

std::string toYaml(const TopologyConfig& t) {
  YAML::Emitter out;
  out.SetDoublePrecision(12);  // 0.35, not 0.34999999999999998
  out << YAML::BeginMap;
  out << YAML::Key << "name" << YAML::Value << t.name;
  out << YAML::Key << "mode" << YAML::Value << modeName(t.mode);
  if (t.baseline_ships_raw) out << YAML::Key << "baseline_ships" << YAML::Value << "raw";
  out << YAML::Key << "deadline_ms" << YAML::Value << t.deadline_ms;
  out << YAML::Key << "period_ms" << YAML::Value << t.period_ms;
  out << YAML::Key << "max_message_bytes" << YAML::Value << t.max_message_bytes;
  out << YAML::Key << "max_scan_bytes" << YAML::Value << t.max_scan_bytes;
  const AdmissionLimits& a = t.admission;
  out << YAML::Key << "admission" << YAML::Value << YAML::BeginMap << YAML::Key << "window_periods" << YAML::Value
      << a.window_periods << YAML::Key << "world_extent_m" << YAML::Value << a.world_extent_m << YAML::Key
      << "max_ellipsoids_per_map" << YAML::Value << a.max_ellipsoids_per_map << YAML::Key << "max_map_bytes"
      << YAML::Value << a.max_map_bytes << YAML::Key << "min_eigenvalue_m2" << YAML::Value << a.min_eigenvalue_m2
      << YAML::Key << "max_eigenvalue_m2" << YAML::Value << a.max_eigenvalue_m2 << YAML::Key << "max_condition"
      << YAML::Value << a.max_condition << YAML::Key << "max_subscribers" << YAML::Value << a.max_subscribers
      << YAML::EndMap;
  out << YAML::Key << "madc" << YAML::Value << YAML::BeginMap << YAML::Key << "eps_m" << YAML::Value << t.madc.clustering.eps_m
      << YAML::Key << "min_points" << YAML::Value << t.madc.clustering.min_points << YAML::Key << "alpha" << YAML::Value
      << t.madc.alpha << YAML::Key << "threads" << YAML::Value << t.madc.clustering.threads << YAML::EndMap;
  out << YAML::Key << "preprocess" << YAML::Value << YAML::BeginMap;
  auto list3 = [&](const Eigen::Vector3d& v) {
    out << YAML::Flow << YAML::BeginSeq << v.x() << v.y() << v.z() << YAML::EndSeq;
  };
  if (t.preprocess.crop) {
    out << YAML::Key << "crop" << YAML::Value << YAML::BeginMap << YAML::Key << "min_m" << YAML::Value;
    list3(t.preprocess.crop->min_m);
    out << YAML::Key << "max_m" << YAML::Value;
    list3(t.preprocess.crop->max_m);
    out << YAML::EndMap;
  }
  if (t.preprocess.voxel_leaf_m) out << YAML::Key << "voxel_leaf_m" << YAML::Value << *t.preprocess.voxel_leaf_m;
  if (t.preprocess.ground) {
    out << YAML::Key << "ground" << YAML::Value << YAML::BeginMap << YAML::Key << "distance_threshold_m" << YAML::Value
        << t.preprocess.ground->distance_threshold_m << YAML::Key << "max_tilt_deg" << YAML::Value
        << t.preprocess.ground->max_tilt_deg;
    if (t.preprocess.ground->ground_z_hint_m) {
      out << YAML::Key << "ground_z_hint_m" << YAML::Value << *t.preprocess.ground->ground_z_hint_m;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  if (t.tls) {
    out << YAML::Key << "tls" << YAML::Value << YAML::BeginMap << YAML::Key << "ca" << YAML::Value << t.tls->ca.string();
    // Left to its default when it is the CA's directory (which may be "", not a valid value).
    if (t.tls->cert_dir != t.tls->ca.parent_path()) {
      out << YAML::Key << "cert_dir" << YAML::Value << t.tls->cert_dir.string();
    }
    out << YAML::Key << "geofence_clients" << YAML::Value << YAML::Flow << t.tls->geofence_clients << YAML::EndMap;
  }
  out << YAML::Key << "nodes" << YAML::Value << YAML::BeginSeq;
  for (const auto& n : t.nodes) {
    out << YAML::BeginMap;
    out << YAML::Key << "name" << YAML::Value << n.name;
    out << YAML::Key << "id" << YAML::Value << n.id;
    out << YAML::Key << "role" << YAML::Value << roleName(n.role);
    if (!n.parent.empty()) out << YAML::Key << "parent" << YAML::Value << n.parent;
    out << YAML::Key << "host" << YAML::Value << n.host;
    if (n.port != 0) out << YAML::Key << "port" << YAML::Value << n.port;
    out << YAML::Key << "metrics_port" << YAML::Value << n.metrics_port;
    if (n.sensor) {
      const auto& s = *n.sensor;
      out << YAML::Key << "sensor" << YAML::Value << YAML::BeginMap;
      out << YAML::Key << "source" << YAML::Value << s.source.string();
      if (s.simulated()) {
        out << YAML::Key << "scene" << YAML::Value << s.scene.string();
        out << YAML::Key << "lidar" << YAML::Value << s.lidar;
      }
      out << YAML::Key << "rate_hz" << YAML::Value << s.rate_hz;
      out << YAML::Key << "loop" << YAML::Value << s.loop;
      if (s.frames) out << YAML::Key << "frames" << YAML::Value << *s.frames;
      if (s.split) {
        out << YAML::Key << "split" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "views" << YAML::Value
            << s.split->views << YAML::Key << "index" << YAML::Value << s.split->index << YAML::Key << "overlap_deg"
            << YAML::Value << s.split->overlap_deg << YAML::EndMap;
      }
      if (!s.pose.isApprox(Eigen::Isometry3d::Identity())) {
        out << YAML::Key << "pose" << YAML::Value << YAML::BeginMap << YAML::Key << "translation_m" << YAML::Value;
        list3(s.pose.translation());
        out << YAML::Key << "rpy_deg" << YAML::Value;
        list3(rpyDegrees(s.pose.rotation()));
        out << YAML::EndMap;
      }
      out << YAML::EndMap;
    }
    if (n.displacement) {
      const auto& d = *n.displacement;
      out << YAML::Key << "displacement" << YAML::Value << YAML::BeginMap << YAML::Key << "tracker" << YAML::Value
          << d.tracker << YAML::Key << "voxel_m" << YAML::Value << d.params.voxel_m << YAML::Key << "neighbour_m"
          << YAML::Value << d.params.neighbour_m << YAML::Key << "min_neighbours" << YAML::Value << d.params.min_neighbours
          << YAML::Key << "min_points" << YAML::Value << d.params.min_points << YAML::Key << "min_z_variance_m2"
          << YAML::Value << d.params.min_z_variance_m2 << YAML::EndMap;
    }
    if (n.camera) {
      const auto& c = *n.camera;
      out << YAML::Key << "camera" << YAML::Value << YAML::BeginMap;
      out << YAML::Key << "source" << YAML::Value << c.source.string();
      if (c.simulated()) {
        out << YAML::Key << "scene" << YAML::Value << c.scene.string();
        out << YAML::Key << "camera" << YAML::Value << c.camera;
      }
      out << YAML::Key << "rate_hz" << YAML::Value << c.rate_hz;
      out << YAML::Key << "loop" << YAML::Value << c.loop;
      if (c.frames) out << YAML::Key << "frames" << YAML::Value << *c.frames;
      out << YAML::Key << "queue_frames" << YAML::Value << c.queue_frames;
      if (c.max_image_pixels != camera::kDefaultMaxImagePixels) {
        out << YAML::Key << "max_image_pixels" << YAML::Value << c.max_image_pixels;
      }
      out << YAML::Key << "detector" << YAML::Value << YAML::BeginMap;
      if (c.truth) {
        out << YAML::Key << "kind" << YAML::Value << "truth";
        out << YAML::Key << "truth" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "miss_rate" << YAML::Value
            << c.truth_replay.miss_rate << YAML::Key << "box_jitter_px" << YAML::Value << c.truth_replay.box_jitter_px
            << YAML::Key << "latency_ms" << YAML::Value << c.truth_replay.latency_ms << YAML::EndMap;
      } else {
        const auto& d = c.detector;
        out << YAML::Key << "kind" << YAML::Value << camera::detectorKindName(d.kind);
        switch (d.kind) {
          case camera::DetectorKind::kHog:
            out << YAML::Key << "hog" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key << "hit_threshold"
                << YAML::Value << d.hog.hit_threshold << YAML::Key << "scale" << YAML::Value << d.hog.scale << YAML::Key
                << "win_stride_px" << YAML::Value << d.hog.win_stride_px << YAML::Key << "upscale" << YAML::Value
                << d.hog.upscale << YAML::Key << "min_height_px" << YAML::Value << d.hog.min_height_px << YAML::Key
                << "nms_iou" << YAML::Value << d.hog.nms_iou << YAML::EndMap;
            break;
          case camera::DetectorKind::kCascade:
            out << YAML::Key << "cascade" << YAML::Value << YAML::BeginMap << YAML::Key << "cascade_path" << YAML::Value
                << d.cascade.cascade_path << YAML::Key << "label" << YAML::Value << d.cascade.label << YAML::Key
                << "scale_factor" << YAML::Value << d.cascade.scale_factor << YAML::Key << "min_neighbors" << YAML::Value
                << d.cascade.min_neighbors << YAML::Key << "min_size_px" << YAML::Value << d.cascade.min_size_px
                << YAML::Key << "nms_iou" << YAML::Value << d.cascade.nms_iou << YAML::EndMap;
            break;
          case camera::DetectorKind::kDnn:
            out << YAML::Key << "dnn" << YAML::Value << YAML::BeginMap << YAML::Key << "model_path" << YAML::Value
                << d.dnn.model_path;
            if (!d.dnn.config_path.empty()) out << YAML::Key << "config_path" << YAML::Value << d.dnn.config_path;
            out << YAML::Key << "names_path" << YAML::Value << d.dnn.names_path << YAML::Key << "output" << YAML::Value
                << camera::dnnOutputName(d.dnn.output) << YAML::Key << "input_width" << YAML::Value << d.dnn.input_width
                << YAML::Key << "input_height" << YAML::Value << d.dnn.input_height << YAML::Key << "mean" << YAML::Value;
            list3(Eigen::Vector3d(d.dnn.mean[0], d.dnn.mean[1], d.dnn.mean[2]));
            out << YAML::Key << "scale" << YAML::Value << d.dnn.scale << YAML::Key << "swap_rb" << YAML::Value
                << d.dnn.swap_rb << YAML::Key << "confidence_threshold" << YAML::Value << d.dnn.confidence_threshold
                << YAML::Key << "nms_threshold" << YAML::Value << d.dnn.nms_threshold << YAML::EndMap;
            break;
        }
      }
      out << YAML::EndMap;
      const auto& k = c.calibration;
      out << YAML::Key << "calibration" << YAML::Value << YAML::BeginMap << YAML::Key << "fx" << YAML::Value << k.fx
          << YAML::Key << "fy" << YAML::Value << k.fy << YAML::Key << "cx" << YAML::Value << k.cx << YAML::Key << "cy"
          << YAML::Value << k.cy << YAML::Key << "width" << YAML::Value << k.width << YAML::Key << "height" << YAML::Value
          << k.height;
      if (!k.distortion.none()) {
        out << YAML::Key << "distortion" << YAML::Value << YAML::Flow << YAML::BeginSeq << k.distortion.k1
            << k.distortion.k2 << k.distortion.p1 << k.distortion.p2 << k.distortion.k3 << YAML::EndSeq;
      }
      const Eigen::Isometry3d pose = k.world_to_camera.inverse();
      out << YAML::Key << "pose" << YAML::Value << YAML::BeginMap << YAML::Key << "translation_m" << YAML::Value;
      list3(pose.translation());
      out << YAML::Key << "rpy_deg" << YAML::Value;
      list3(rpyDegrees(pose.rotation()));
      out << YAML::EndMap << YAML::EndMap;
      out << YAML::EndMap;
    }
    if (n.tracker) {
      const auto& c = n.tracker->tracking;
      out << YAML::Key << "tracker" << YAML::Value << YAML::BeginMap;
      if (n.tracker->input == TrackerInput::kCentroids) {
        out << YAML::Key << "input" << YAML::Value << trackerInputName(n.tracker->input) << YAML::Key << "centroid_merge_m"
            << YAML::Value << n.tracker->centroid_merge_m << YAML::Key << "visible_side_max_radius_m" << YAML::Value
            << n.tracker->visible_side_max_radius_m;
      }
      out << YAML::Key << "association" << YAML::Value
          << tracking::associationName(c.association) << YAML::Key << "eps_sync_s" << YAML::Value << c.eps_sync_s
          << YAML::Key << "rho_overlay_m" << YAML::Value << c.rho_overlay_m << YAML::Key << "rho_purecloud_m" << YAML::Value
          << c.rho_purecloud_m << YAML::Key << "gate_chi2" << YAML::Value << c.gate_chi2 << YAML::Key
          << "acceleration_sigma" << YAML::Value << c.acceleration_sigma << YAML::Key << "initial_speed_sigma"
          << YAML::Value << c.initial_speed_sigma << YAML::Key << "min_measurement_sigma_m" << YAML::Value
          << c.min_measurement_sigma_m << YAML::Key << "confirm_hits" << YAML::Value << c.confirm_hits << YAML::Key
          << "tentative_timeout_s" << YAML::Value << c.tentative_timeout_s << YAML::Key << "track_timeout_s"
          << YAML::Value << c.track_timeout_s << YAML::Key << "max_buffered_frames" << YAML::Value
          << c.max_buffered_frames << YAML::Key << "max_detection_wait_s" << YAML::Value << c.max_detection_wait_s
          << YAML::EndMap;
    }
    if (n.tls) {
      out << YAML::Key << "tls" << YAML::Value << YAML::BeginMap << YAML::Key << "cert" << YAML::Value
          << n.tls->cert.string() << YAML::Key << "key" << YAML::Value << n.tls->key.string() << YAML::EndMap;
    }
    out << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace fogmap
