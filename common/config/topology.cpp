#include "common/config/topology.hpp"

#include <algorithm>
#include <functional>

#include "common/config/displacement_node.hpp"

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

bool isName(const std::string& name) {
  return !name.empty() && name.size() <= kMaxNameChars && name.front() != '.' &&
         std::all_of(name.begin(), name.end(), [](char c) {
           return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
                  c == '-';
         });
}

bool isCertificateName(const std::string& name) { return isName(name) && name != "ca"; }

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

const char* clusteringModeName(ClusteringMode mode) {
  switch (mode) {
    case ClusteringMode::kExact:
      return "exact";
    case ClusteringMode::kSensor:
      return "sensor";
  }
  return "unknown";
}

Expected<ClusteringMode> parseClusteringMode(const std::string& name) {
  if (name == "exact") return ClusteringMode::kExact;
  if (name == "sensor") return ClusteringMode::kSensor;
  return invalidArgument("must be exact (PCL's Euclidean partition) or sensor (with ring links from the LiDAR "
                         "model's beam table), got '" + name + "'");
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

}  // namespace fogmap
