#include "common/config/topology_sections.hpp"

#include <algorithm>
#include <utility>

#include "common/perception/lidar_models.hpp"

namespace fogmap::topology_detail {

Expected<SensorConfig> parseSensor(const YAML::Node& node, const std::string& where, const std::filesystem::path& base_dir) {
  if (const Status st = checkSection(node, where,
                                     {"source", "scene", "lidar", "rate_hz", "loop", "frames", "split", "pose", "clustering",
                                      "model"});
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
  const auto clustering = scalar<std::string>(node, "clustering", where, clusteringModeName(s.clustering));
  if (!clustering) return clustering.error();
  const auto mode = parseClusteringMode(*clustering);
  if (!mode) return bad(where + ".clustering", mode.error().message);
  s.clustering = *mode;
  const auto model = scalar<std::string>(node, "model", where, "");
  if (!model) return model.error();
  if (s.clustering == ClusteringMode::kSensor && model->empty()) {
    std::string known;
    for (const auto& n : lidarModelNames()) known += (known.empty() ? "" : ", ") + n;
    return bad(where + ".model", "is required with clustering: sensor (the LiDAR model whose beam table links the rings: " +
                                     known + ")");
  }
  if (!model->empty()) {
    if (s.clustering != ClusteringMode::kSensor) {
      return bad(where + ".model", "goes with clustering: sensor only (clustering is " +
                                       std::string(clusteringModeName(s.clustering)) + ")");
    }
    if (const auto known = lidarModel(*model); !known) return bad(where + ".model", known.error().message);
  }
  s.model = *model;
  return s;
}

namespace {

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

}  // namespace

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
                                                    "confirm_hits", "tentative_timeout_s", "track_timeout_s", "publish_lost_s",
                                                    "max_buffered_frames", "max_detection_wait_s", "lidar_class_weight"});
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
           {"publish_lost_s", &c.publish_lost_s},
           {"max_detection_wait_s", &c.max_detection_wait_s}, {"lidar_class_weight", &c.lidar_class_weight}}) {
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

namespace {

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

}  // namespace

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

}  // namespace fogmap::topology_detail
