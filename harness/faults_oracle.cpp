#include "harness/faults_oracle.hpp"

#include <string>

#include "common/geometry/map.hpp"
#include "services/common/proto_convert.hpp"
#include "services/edge_cluster/edge_node.hpp"
#include "services/edge_cluster/edge_runner.hpp"

namespace fogmap::harness {
namespace {

Map withoutFrames(Map map) {
  for (MapObject& o : map.objects) {
    for (Ellipsoid& e : o.ellipsoids) e.id.frame = 0;
  }
  return map;
}

}  // namespace

Expected<Oracle> Oracle::create(const TopologyConfig& topology, const EpochSchedule& schedule) {
  Oracle oracle(topology, schedule);
  for (const NodeConfig& n : topology.nodes) {
    if (n.role != Role::kEdge) continue;
    SensorConfig sensor = *n.sensor;
    sensor.frames.reset();
    sensor.loop = true;
    auto source = ScanSource::open(sensor, ReadLimits{topology.max_scan_bytes});
    if (!source) return source.error();
    oracle.sources_.emplace(n.id, std::move(*source));
  }
  return oracle;
}

Expected<bool> Oracle::matches(const GlobalMapMessage& global) {
  std::vector<std::pair<std::uint32_t, std::uint64_t>> key;  // (node, scan file)
  for (std::uint32_t node : global.header.contributing_nodes) {
    const NodeConfig* n = topology_.find(node);
    if (n == nullptr || n->role != Role::kEdge) return invalidArgument("unknown contributing node " + std::to_string(node));
    const auto files = sources_.at(node).files().size();
    key.emplace_back(node, scanNumberAt(schedule_, n->sensor->rate_hz, global.header.epoch) % files);
  }
  auto cached = expected_.find(key);
  if (cached == expected_.end()) {
    std::vector<Ellipsoid> all;
    for (const auto& [node, file] : key) {
      auto local = localMap(node, file);
      if (!local) return local.error();
      for (const MapObject& o : (*local)->objects) all.insert(all.end(), o.ellipsoids.begin(), o.ellipsoids.end());
    }
    // As the root publishes it: through the global map's wire.
    auto published = throughGlobalWire(mergeSpecification(all));
    if (!published) return published.error();
    cached = expected_.emplace(key, std::move(*published)).first;
  }
  return withoutFrames(global.map) == cached->second;
}

Expected<bool> Oracle::warm(std::uint64_t first_epoch, std::uint64_t epochs) {
  GlobalMapMessage probe;
  for (const auto& [node, source] : sources_) probe.header.contributing_nodes.push_back(node);
  for (std::uint64_t e = first_epoch; e < first_epoch + epochs; ++e) {
    probe.header.epoch = e;
    auto ok = matches(probe);
    if (!ok) return ok.error();
  }
  return true;
}

Expected<const Map*> Oracle::localMap(std::uint32_t node, std::uint64_t file) {
  const auto key = std::make_pair(node, file);
  if (const auto it = local_.find(key); it != local_.end()) return &it->second;
  auto frame = sources_.at(node).at(file);
  if (!frame) return frame.error();
  EdgeNode edge(edgeConfigFor(topology_, *topology_.find(node)));
  auto output = edge.processFrame(frame->points, 0, 0);
  if (!output) return output.error();
  if (!output->map) return invalidArgument("the oracle needs mode madc");
  // What the parent receives: the map after its trip through the wire format.
  auto received = fromProto(toProto(*output->map));
  if (!received) return received.error();
  return &local_.emplace(key, withoutFrames(received->map)).first->second;
}

}  // namespace fogmap::harness
