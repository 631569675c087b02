#pragma once
// Writing a topology as a YAML file in the form parseTopology reads (every value written, defaults
// included): the files fogctl starts clusters with and the repository's topologies/.
#include <string>

#include "common/config/topology.hpp"

namespace fogmap {

std::string toYaml(const TopologyConfig& topology);

}  // namespace fogmap
