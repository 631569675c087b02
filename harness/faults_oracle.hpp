#pragma once
// The fault harness's oracle (harness/faults.hpp): mergeSpecification over the local maps every
// edge computes for an epoch, recomputed from the same scans with the edges' own code
// (fogmap::edge). Maps are compared with every ellipsoid's frame set to 0: the edges stamp the
// epoch there, and the scan shown (hence the geometry) repeats. No processes, no sockets.
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

#include "common/base/epochs.hpp"
#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "common/geometry/map.hpp"
#include "common/io/messages.hpp"
#include "services/edge_cluster/scan_source.hpp"

namespace fogmap::harness {

class Oracle {
 public:
  // Opens every edge's scans (looped, no frame limit). `topology` must outlive the oracle.
  static Expected<Oracle> create(const TopologyConfig& topology, const EpochSchedule& schedule);

  // Whether `global` equals the specification's map over its contributing nodes.
  Expected<bool> matches(const GlobalMapMessage& global);

  // Fills the cache for complete epochs [first_epoch, first_epoch + epochs) of every scan file,
  // before the clock starts.
  Expected<bool> warm(std::uint64_t first_epoch, std::uint64_t epochs);

 private:
  Oracle(const TopologyConfig& topology, const EpochSchedule& schedule) : topology_(topology), schedule_(schedule) {}

  // The map `node` ships for scan `file`, as its parent decodes it, frames cleared.
  Expected<const Map*> localMap(std::uint32_t node, std::uint64_t file);

  const TopologyConfig& topology_;
  EpochSchedule schedule_;
  std::map<std::uint32_t, ScanSource> sources_;
  std::map<std::pair<std::uint32_t, std::uint64_t>, Map> local_;
  std::map<std::vector<std::pair<std::uint32_t, std::uint64_t>>, Map> expected_;
};

}  // namespace fogmap::harness
