#include "harness/epoch_latency.hpp"

#include "common/base/clock.hpp"

namespace fogmap::harness {

std::optional<double> endToEndLatencyMs(const GlobalMapMessage& global) {
  // An epoch no node contributed to carries no sensor time (0): its "latency" would be the time
  // since 1970.
  if (global.header.sensor_time_ns <= 0) return std::nullopt;
  return nsToMs(global.published_time_ns - global.header.sensor_time_ns);
}

EpochLatencies epochLatencies(const std::map<std::uint64_t, GlobalMapMessage>& epochs) {
  EpochLatencies out;
  for (const auto& [e, g] : epochs) {
    out.merge_ms.push_back(g.merge_seconds * 1e3);
    const std::optional<double> e2e = endToEndLatencyMs(g);
    if (e2e) {
      out.e2e_all_ms.push_back(*e2e);
    } else {
      ++out.without_sensor_time;
    }
    if (g.header.missing_nodes.empty()) {
      if (e2e) out.e2e_ms.push_back(*e2e);
      continue;
    }
    std::string line = "\n    epoch ";
    line.append(std::to_string(e)).append(": missing nodes");
    for (const auto n : g.header.missing_nodes) line.append(" ").append(std::to_string(n));
    if (e2e) {
      line.append(", published ").append(std::to_string(static_cast<long long>(*e2e))).append(" ms after the sensor time");
    } else {
      line.append(", no sensor time (no node contributed)");
    }
    out.incomplete_list += line;
  }
  return out;
}

}  // namespace fogmap::harness
