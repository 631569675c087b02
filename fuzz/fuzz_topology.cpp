// libFuzzer target: parseTopology over arbitrary text. A document it accepts must describe a
// tree every service can start from: one root, every node's subtree answerable, every aggregator's
// core created from it, every edge's centroids going to a tracker that takes them, and the document
// it writes back (toYaml) accepted again with the same settings. And what fogctl does with it
// before starting anything must answer, never throw: up's checks and plan (fogctl up --dry-run)
// and the compose deployment (fogctl compose), with the topology read from a scratch project
// directory (holding the files the seeds name) and from the working directory (loadTopology of a
// bare file name). Nothing is started, written or sent.
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>
#include <vector>

#include "common/config/camera_node.hpp"
#include "common/config/displacement_node.hpp"
#include "common/config/topology.hpp"
#include "common/config/topology_parse.hpp"
#include "common/config/topology_yaml.hpp"
#include "common/config/tracker_node.hpp"
#include "fuzz/fuzz_check.hpp"
#include "services/merge_aggregator/aggregator_core.hpp"
#include "harness/compose.hpp"
#include "harness/launcher.hpp"

namespace {

namespace fs = std::filesystem;
using namespace fogmap;

// A scratch project directory, made once and removed at exit, holding the files the seeds name
// (scans/, images/, s.yaml, cascade.xml, m.onnx, m.cfg, n.txt) so that their topologies get past
// the checks to the plan and the compose file.
struct Project {
  Project() {
    std::string pattern = (fs::temp_directory_path() / "fogmap-fuzz-topology-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) std::abort();
    dir = pattern;
    for (const char* d : {"scans", "images"}) fs::create_directories(dir / d);
    for (const char* f : {"s.yaml", "cascade.xml", "m.onnx", "m.cfg", "n.txt"}) std::ofstream(dir / f) << "x\n";
  }
  ~Project() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  fs::path dir;
};

const Project& project() {
  static const Project p;
  return p;
}

// The checks fogctl up, up --dry-run and compose make before anything starts, on a topology whose
// relative paths were resolved against `project_dir`.
void checkDeployment(const TopologyConfig& topology, const fs::path& project_dir) {
  const Status startable = harness::checkStartable(topology);
  if (!startable) {
    const Error& e = startable.error();
    fuzz::check(e.code == ErrorCode::kInvalidArgument || e.code == ErrorCode::kNotFound || e.code == ErrorCode::kIo,
                "a topology that cannot start is refused as bad input, a missing file or an unreadable one");
    fuzz::check(e.message.starts_with("node '") && e.message.find("': ") != std::string::npos && e.message.size() > 16,
                "a topology that cannot start is refused naming the node and the field");
  }
  const fs::path state = project_dir / ".fogmap" / topology.name;
  const auto plan = harness::planCluster(project_dir / "topology.yaml", topology, state);
  fuzz::check(plan.ok() == startable.ok(), "up --dry-run refuses exactly what checkStartable refuses");
  if (plan) {
    fuzz::check(plan->size() == topology.nodes.size(), "up starts every node once");
    const auto serves = [](Role r) { return r == Role::kAggregator || r == Role::kTracker; };
    fuzz::check(std::is_partitioned(plan->begin(), plan->end(), [&](const harness::PlannedNode& n) { return serves(n.role); }),
                "up starts the aggregators and trackers before the edges and cameras");
    for (const harness::PlannedNode& n : *plan) {
      const auto node = std::find(n.command.begin(), n.command.end(), "--node");
      fuzz::check(node != n.command.end() && node + 1 != n.command.end() && *(node + 1) == n.name &&
                      topology.find(n.name) != nullptr && n.log.parent_path() == state / "logs",
                  "each planned service runs its node and logs under the state directory");
    }
  }

  harness::ComposeOptions options;
  options.topology_file = project_dir / "topology.yaml";
  options.project_dir = project_dir;
  options.prometheus_config = "prometheus.yml";
  options.command = "fogctl compose topology.yaml";
  const auto compose = harness::composeFile(topology, options);
  if (!compose) {
    fuzz::check(compose.error().code == ErrorCode::kInvalidArgument && compose.error().message.size() > 8,
                "compose refuses what it cannot deploy as bad input, saying what");
  } else {
    for (const NodeConfig& node : topology.nodes) {
      fuzz::check(compose->find("\n  " + node.name + ":\n") != std::string::npos, "compose runs every node as a service");
    }
  }
  const std::string scrape = harness::prometheusConfig(topology, {});
  fuzz::check(scrape.find("scrape_configs:") != std::string::npos, "the Prometheus configuration scrapes");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace fogmap;
  const std::string text(reinterpret_cast<const char*>(data), size);
  const Expected<TopologyConfig> topology = parseTopology(text, "scans");
  if (!topology) {
    fuzz::checkRejection(topology.error(), "topology: ");
    return 0;
  }
  // Where the topology file lies does not decide whether it is valid, only where its files are.
  const Expected<TopologyConfig> in_project = parseTopology(text, project().dir);
  fuzz::check(in_project.ok(), "a topology valid in one directory is valid in another");
  checkDeployment(*in_project, project().dir);
  const Expected<TopologyConfig> in_working_dir = parseTopology(text, "");
  fuzz::check(in_working_dir.ok(), "a topology valid in one directory is valid in the working directory");
  checkDeployment(*in_working_dir, ".");
  fuzz::check(topology->root() != nullptr, "a valid topology has a root");
  for (const NodeConfig& node : topology->nodes) {
    fuzz::check(topology->find(node.id) == &node && topology->find(node.name) == &node, "ids and names are unique");
    if (node.role == Role::kEdge) {
      fuzz::check(node.sensor.has_value() && topology->children(node.name).empty(), "an edge is a leaf with a sensor");
      if (node.displacement) {
        const NodeConfig* tracker = topology->find(node.displacement->tracker);
        fuzz::check(tracker != nullptr && tracker->role == Role::kTracker && tracker->tracker.has_value() &&
                        tracker->tracker->input == TrackerInput::kCentroids,
                    "an edge's centroids go to a tracker whose input is centroids");
        fuzz::check(tracking::validateDisplacementParams(node.displacement->params).ok(),
                    "an edge's displacement settings are valid");
      }
      continue;
    }
    fuzz::check(!node.displacement.has_value(), "only edges have a displacement section");
    if (node.role == Role::kDetection) {
      const NodeConfig* parent = topology->find(node.parent);
      fuzz::check(node.camera.has_value() && parent != nullptr && parent->role == Role::kTracker,
                  "a detection node has a camera and sends to a tracker");
      fuzz::check(camera::validate(node.camera->calibration).ok(), "a detection node's calibration is valid");
      continue;
    }
    if (node.role == Role::kTracker) {
      fuzz::check(node.tracker.has_value() && node.parent.empty(), "a tracker has its settings and no parent");
      fuzz::check(tracking::validate(node.tracker->tracking).ok(), "a tracker's settings are valid");
      for (const NodeConfig* c : topology->camerasOf(node.name)) {
        fuzz::check(c->camera.has_value(), "a tracker's cameras have calibrations");
      }
      const bool centroids = node.tracker->input == TrackerInput::kCentroids;
      fuzz::check(centroids != topology->centroidEdgesOf(node.name).empty(),
                  "a tracker gets centroids from some edge exactly when its input is centroids");
      continue;
    }
    fuzz::check(topology->aggregatorLevels(node.name) >= 1, "an aggregator is at least one level");
    const Expected<AggregatorConfig> config = aggregatorConfigFor(*topology, node.name);
    fuzz::check(config.ok(), "every aggregator of a valid topology has a configuration");
    fuzz::check(MergeAggregator::create(*config).ok(), "every aggregator of a valid topology starts");
  }
  const Expected<TopologyConfig> again = parseTopology(toYaml(*topology), "scans");
  fuzz::check(again.ok(), "a valid topology written back as YAML is valid");
  fuzz::check(again->nodes.size() == topology->nodes.size() && again->mode == topology->mode,
              "a topology written back as YAML has the same mode and nodes");
  for (std::size_t i = 0; i < topology->nodes.size(); ++i) {
    const NodeConfig& a = topology->nodes[i];
    const NodeConfig& b = again->nodes[i];
    fuzz::check(a.name == b.name && a.id == b.id && a.role == b.role && a.parent == b.parent && a.host == b.host &&
                    a.port == b.port && a.metrics_port == b.metrics_port,
                "a node written back as YAML reads the same");
    fuzz::check(a.camera.has_value() == b.camera.has_value() && a.tracker.has_value() == b.tracker.has_value() &&
                    a.displacement.has_value() == b.displacement.has_value(),
                "a node's camera, tracker and displacement sections survive YAML");
    // Numbers are written with 12 significant digits.
    const auto close = [](double x, double y) { return std::abs(x - y) <= 1e-11 * std::abs(x); };
    if (a.tracker) {
      fuzz::check(a.tracker->tracking.association == b.tracker->tracking.association &&
                      a.tracker->tracking.confirm_hits == b.tracker->tracking.confirm_hits &&
                      a.tracker->input == b.tracker->input && close(a.tracker->centroid_merge_m, b.tracker->centroid_merge_m) &&
                      close(a.tracker->visible_side_max_radius_m, b.tracker->visible_side_max_radius_m),
                  "a tracker's settings survive YAML");
    }
    if (a.displacement) {
      const auto& p = a.displacement->params;
      const auto& q = b.displacement->params;
      fuzz::check(a.displacement->tracker == b.displacement->tracker && p.min_neighbours == q.min_neighbours &&
                      p.min_points == q.min_points && close(p.voxel_m, q.voxel_m) && close(p.neighbour_m, q.neighbour_m) &&
                      close(p.min_z_variance_m2, q.min_z_variance_m2),
                  "an edge's displacement settings survive YAML");
    }
    if (a.camera) {
      fuzz::check(a.camera->truth == b.camera->truth && a.camera->detector.kind == b.camera->detector.kind &&
                      a.camera->calibration.width == b.camera->calibration.width,
                  "a camera's settings survive YAML");
    }
  }
  return 0;
}
