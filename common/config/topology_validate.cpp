#include "common/config/topology_sections.hpp"

#include <arpa/inet.h>

#include <algorithm>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "common/config/displacement_node.hpp"
#include "common/config/tracker_node.hpp"

namespace fogmap::topology_detail {
namespace {

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

}  // namespace

Status validateTopology(const TopologyConfig& t) {
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

}  // namespace fogmap::topology_detail
