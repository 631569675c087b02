#pragma once
// Ready-made topologies and nodes, for fogctl, the simulator's scenes and the tests.
#include <filesystem>
#include <string>

#include "common/config/topology.hpp"

namespace fogmap {
namespace tracking {
struct TrackerConfig;  // common/tracking/tracker_config.hpp
}  // namespace tracking

// Ready-made topologies (the repository's topologies/ files are generated from these).
// Star: one sink, `edges` edges. Tree: a balanced tree of aggregators over the edges, each over at
// most `fanout` subtrees (binary by default; tree-7 with fanout 4 is a sink over two aggregators of
// four and three edges).
TopologyConfig makeStarTopology(int edges, const std::filesystem::path& source, int base_port);
TopologyConfig makeTreeTopology(int edges, const std::filesystem::path& source, int base_port, int fanout = 2);
// The tracker of a ready-made topology: named kTrackerNodeName, id 300, gRPC port base_port + 300,
// metrics base_port + 301 (after the aggregators' ports and the edges' and aggregators' metrics).
inline constexpr const char* kTrackerNodeName = "tracker";
NodeConfig trackerNode(int base_port, const tracking::TrackerConfig& tracking);
// Camera `number` (1, 2, ...) of a ready-made topology: a detection node named `name` sending to
// the tracker `tracker`, id 400 + number, metrics base_port + 400 + number; its calibration takes
// the node's name.
NodeConfig detectionNode(int number, const std::string& name, const std::string& tracker, int base_port,
                         CameraNodeConfig camera);

}  // namespace fogmap
