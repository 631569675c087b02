#include "common/config/topology_presets.hpp"

#include <algorithm>
#include <functional>
#include <utility>

#include "common/config/camera_node.hpp"
#include "common/config/tracker_node.hpp"

namespace fogmap {
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

}  // namespace fogmap
