#pragma once
// The latencies fogctl demo reports for a run's global maps: merge time at the sink, and the
// end-to-end latency from an epoch's sensor timestamp to its global map. Pure: no processes.
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/io/messages.hpp"

namespace fogmap::harness {

// From the sensor timestamp of the global map's data to its publication, in ms; none when the map
// has no sensor time (no node contributed to its epoch).
std::optional<double> endToEndLatencyMs(const GlobalMapMessage& global);

struct EpochLatencies {
  std::vector<double> merge_ms;    // every epoch
  std::vector<double> e2e_ms;      // epochs with no node missing
  std::vector<double> e2e_all_ms;  // every epoch with a sensor time (start-up and late nodes included)
  std::size_t without_sensor_time = 0;  // epochs no node contributed to: no end-to-end latency
  std::string incomplete_list;          // a line per epoch with a node missing: which, and its latency
};
// The latencies of every epoch of a run (by epoch).
EpochLatencies epochLatencies(const std::map<std::uint64_t, GlobalMapMessage>& epochs);

}  // namespace fogmap::harness
