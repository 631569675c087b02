#pragma once
// Small topologies for the fault harness's unit tests, built by hand so that every figure of a
// test can be worked out on paper: period 100 ms, deadline 80 ms (the defaults).
#include <string>

#include "common/config/topology.hpp"

namespace fogmap::harness::fault_fixtures {

inline NodeConfig faultNode(std::uint32_t id, const std::string& name, Role role, const std::string& parent) {
  NodeConfig n;
  n.id = id;
  n.name = name;
  n.role = role;
  n.parent = parent;
  return n;
}

// sink (100) over agg-1 (101) and agg-2 (102); edge-1 and edge-2 (ids 1, 2) under agg-1, edge-3
// and edge-4 (3, 4) under agg-2. The root has 2 levels of aggregators: it emits at k P + 160 ms.
inline TopologyConfig treeOfFour() {
  TopologyConfig t;
  t.name = "tree-4";
  t.nodes = {faultNode(100, "sink", Role::kAggregator, ""),      faultNode(101, "agg-1", Role::kAggregator, "sink"),
             faultNode(102, "agg-2", Role::kAggregator, "sink"), faultNode(1, "edge-1", Role::kEdge, "agg-1"),
             faultNode(2, "edge-2", Role::kEdge, "agg-1"),       faultNode(3, "edge-3", Role::kEdge, "agg-2"),
             faultNode(4, "edge-4", Role::kEdge, "agg-2")};
  return t;
}

// sink (100) over edge-1 .. edge-3: no aggregator but the root.
inline TopologyConfig starOfThree() {
  TopologyConfig t;
  t.name = "star-3";
  t.nodes = {faultNode(100, "sink", Role::kAggregator, ""), faultNode(1, "edge-1", Role::kEdge, "sink"),
             faultNode(2, "edge-2", Role::kEdge, "sink"), faultNode(3, "edge-3", Role::kEdge, "sink")};
  return t;
}

}  // namespace fogmap::harness::fault_fixtures
