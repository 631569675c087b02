// openScanProvider (declared in scan_source.hpp): the one place that chooses an edge's scan source.
#include <memory>
#include <utility>

#include "services/edge_cluster/scan_source.hpp"
#include "services/edge_cluster/sim_scan_source.hpp"

namespace fogmap {

Expected<std::unique_ptr<ScanProvider>> openScanProvider(const SensorConfig& sensor, ReadLimits limits) {
  if (sensor.simulated()) {
    Expected<SimScanSource> sim = SimScanSource::open(sensor);
    if (!sim) return sim.error();
    return std::unique_ptr<ScanProvider>(std::make_unique<SimScanSource>(std::move(*sim)));
  }
  Expected<ScanSource> recorded = ScanSource::open(sensor, limits);
  if (!recorded) return recorded.error();
  return std::unique_ptr<ScanProvider>(std::make_unique<ScanSource>(std::move(*recorded)));
}

}  // namespace fogmap
