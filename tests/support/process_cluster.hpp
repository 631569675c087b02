#pragma once
// A topology as real processes, as fogctl up starts it: written to a file and read back (what the
// services read), and stopped at the end of the test whatever happens in between.
#include <chrono>
#include <filesystem>
#include <fstream>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "common/config/topology_parse.hpp"
#include "common/config/topology_yaml.hpp"
#include "harness/launcher.hpp"

namespace fogmap::test_support {

// Writes `topology` to `file` and reads it back as the services will.
inline Expected<TopologyConfig> writeTopology(const std::filesystem::path& file, const TopologyConfig& topology) {
  {
    std::ofstream out(file);
    out << toYaml(topology);
  }
  return loadTopology(file);
}

// Stops a started cluster when it goes out of scope: SIGTERM, SIGKILL after the grace period.
class StopOnExit {
 public:
  explicit StopOnExit(const harness::Cluster& cluster, std::chrono::milliseconds grace = std::chrono::seconds(5))
      : cluster_(cluster), grace_(grace) {}
  ~StopOnExit() { harness::stopCluster(cluster_, grace_); }
  StopOnExit(const StopOnExit&) = delete;
  StopOnExit& operator=(const StopOnExit&) = delete;

 private:
  const harness::Cluster& cluster_;
  std::chrono::milliseconds grace_;
};

}  // namespace fogmap::test_support
