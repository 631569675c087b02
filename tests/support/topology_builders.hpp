#pragma once
// Nodes of hand-made topologies for tests: the fields every node has (a test adds its sensor,
// camera or tracker section), and the root's id in the aggregators' hand-made configurations.
#include <cstdint>
#include <string>

#include "common/config/topology.hpp"

namespace fogmap::test_support {

inline constexpr std::uint32_t kRoot = 100;

// Node `id` named `name` in role `role`, under `parent` (empty for a root or a tracker).
inline NodeConfig node(std::uint32_t id, const std::string& name, Role role, const std::string& parent) {
  NodeConfig n;
  n.id = id;
  n.name = name;
  n.role = role;
  n.parent = parent;
  return n;
}

}  // namespace fogmap::test_support
