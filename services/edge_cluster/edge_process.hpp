#pragma once
// One edge-cluster process as its topology node says: its sensor's scans, the upload link to its
// parent, the centroid link to its tracker (with a displacement section), the delivery journal
// (--journal FILE), and the replay loop (EdgeRunner) that ships every epoch on them.
//
// How it ends (docs/design.md "Delivery"): on the stop request the wait for the next epoch ends at
// once, the frame in progress is finished and shipped, the centroids get kStopFlush to be taken,
// the uploads not yet answered kStopFlush to be answered (what is still unanswered then goes with
// the process), exit 0. At the end of the recording the last uploads get kDoneFlush; exit
// kExitRuntimeError when not one scan was readable.
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "common/base/epochs.hpp"
#include "common/base/status.hpp"
#include "services/common/parent_link.hpp"
#include "services/common/service_main.hpp"
#include "services/common/tracker_link.hpp"
#include "services/edge_cluster/edge_metrics.hpp"
#include "services/edge_cluster/edge_node.hpp"
#include "services/edge_cluster/edge_runner.hpp"
#include "services/edge_cluster/scan_source.hpp"

namespace fogmap {

class DeliveryJournal;  // services/common/delivery_journal.hpp

class EdgeProcess {
 public:
  static constexpr std::chrono::nanoseconds kStopPoll = std::chrono::milliseconds(50);  // clock steps
  static constexpr std::chrono::milliseconds kStopFlush{1000};
  static constexpr std::chrono::milliseconds kDoneFlush{5000};

  // Checks the node (an edge with a sensor, a parent, a positive rate, a valid pose; the topology's
  // schedule) and opens its scans and journal; an error says what is wrong (a configuration error).
  // `context` must outlive the process.
  static Expected<std::unique_ptr<EdgeProcess>> create(const ServiceContext& context);
  ~EdgeProcess();
  EdgeProcess(const EdgeProcess&) = delete;
  EdgeProcess& operator=(const EdgeProcess&) = delete;

  // Replays until the recording ends or the stop request, then ends as above; the exit code.
  int run();

 private:
  EdgeProcess(const ServiceContext& context, const NodeConfig& parent, EdgeConfig edge_config, EpochSchedule schedule,
              std::unique_ptr<ScanProvider> scans, std::unique_ptr<DeliveryJournal> journal);
  EdgeRunnerHooks runnerHooks();
  TrackerLinkHooks centroidLinkHooks();
  // Queues everything an epoch produced on the links; with a journal, records how each upload ends.
  void ship(const EdgeOutput& output);

  const ServiceContext& context_;
  const NodeConfig& parent_;
  const NodeConfig* tracker_;  // with a displacement section
  std::unique_ptr<ScanProvider> scans_;
  std::unique_ptr<DeliveryJournal> journal_;  // with --journal
  const EdgeConfig edge_config_;
  ParentLink link_;
  MetricsObserver observer_;
  std::optional<CentroidLink> centroid_link_;  // after the observer its hooks count with
  EdgeRunner runner_;
};

}  // namespace fogmap
