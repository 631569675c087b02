#include "common/config/topology_parse.hpp"

#include <cctype>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "common/config/camera_node.hpp"
#include "common/config/displacement_node.hpp"
#include "common/config/topology_sections.hpp"
#include "common/config/tracker_node.hpp"

namespace fogmap {

using namespace topology_detail;

namespace {

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

Expected<TopologyConfig> parseDocument(const YAML::Node& root, const std::filesystem::path& base_dir) {
  if (!root.IsMap()) return invalidArgument("topology: the document must be a mapping with 'nodes'");
  if (const Status s = checkSection(root, "", {"name", "mode", "baseline_ships", "deadline_ms", "period_ms", "max_message_bytes",
                                               "max_scan_bytes", "admission", "madc", "objects", "preprocess", "tls", "nodes"});
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
    if (const Status s = checkSection(m, "madc", {"eps_m", "min_points", "fragment_min_points", "alpha", "alpha_max", "threads"}); !s) return s.error();
    const auto eps = scalar<double>(m, "eps_m", "madc", t.madc.clustering.eps_m);
    const auto min_points = scalar<long long>(m, "min_points", "madc", static_cast<long long>(t.madc.clustering.min_points));
    const auto fragment_min_points = scalar<long long>(m, "fragment_min_points", "madc", 0);
    const auto alpha = scalar<double>(m, "alpha", "madc", t.madc.alpha);
    const auto alpha_max = scalar<double>(m, "alpha_max", "madc", t.madc.alpha_max);
    const auto threads = scalar<long long>(m, "threads", "madc", static_cast<long long>(t.madc.clustering.threads));
    if (!eps) return eps.error();
    if (!min_points) return min_points.error();
    if (!fragment_min_points) return fragment_min_points.error();
    if (!alpha) return alpha.error();
    if (!alpha_max) return alpha_max.error();
    if (!threads) return threads.error();
    if (*min_points < 1 || *min_points > std::numeric_limits<std::int32_t>::max()) {
      return bad("madc.min_points", "must be in [1, 2^31)");
    }
    if (m["fragment_min_points"] && (*fragment_min_points < 1 || *fragment_min_points > *min_points)) {
      return bad("madc.fragment_min_points", "must be in [1, min_points] (" + std::to_string(*min_points) + ")");
    }
    if (!(*alpha > 0.0 && *alpha < 10.0)) return bad("madc.alpha", "must be in (0, 10)");
    if (!(*alpha_max == 0.0 || (*alpha_max >= *alpha && *alpha_max < 10.0))) {
      return bad("madc.alpha_max", "must be 0 (off) or in [alpha, 10)");
    }
    if (*threads < 1 || *threads > 256) return bad("madc.threads", "must be in [1, 256]");
    t.madc.clustering.eps_m = *eps;
    t.madc.clustering.min_points = static_cast<std::size_t>(*min_points);
    if (m["fragment_min_points"]) t.madc.fragment_min_points = static_cast<std::size_t>(*fragment_min_points);
    t.madc.alpha = *alpha;
    t.madc.alpha_max = *alpha_max;
    t.madc.clustering.threads = static_cast<std::size_t>(*threads);
  }
  // eps_m's range is validateClusteringParams's; its messages start with the field's name.
  if (const Status s = validateClusteringParams(t.madc.clustering); !s) {
    return invalidArgument("topology: madc." + s.error().message);
  }
  if (const YAML::Node o = root["objects"]) {
    if (const Status s = checkSection(o, "objects", {"boxes", "classifier"}); !s) return s.error();
    const auto classifier = scalar<std::string>(o, "classifier", "objects", "");
    if (!classifier) return classifier.error();
    // A class is read from a cluster's box: a classifier implies boxes.
    const auto boxes = scalar<bool>(o, "boxes", "objects", true);
    if (!boxes) return boxes.error();
    if (!*boxes && !classifier->empty()) return bad("objects.boxes", "cannot be false with a classifier (classes are read from boxes)");
    if (o["classifier"] && classifier->empty()) return bad("objects.classifier", "must name a model file");
    t.objects.boxes = *boxes;
    if (!classifier->empty()) {
      t.objects.classifier = std::filesystem::path(*classifier).is_absolute() ? std::filesystem::path(*classifier)
                                                                              : base_dir / *classifier;
    }
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
  if (const Status s = validateTopology(t); !s) return s.error();
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

}  // namespace fogmap
