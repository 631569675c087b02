#pragma once
// Running a local cluster to completion and judging its output: collect the global maps of every
// epoch, scrape the services' metrics, recompute what each edge saw, and score MAD-C against the
// baseline. Used by `fogctl demo` and the integration tests.
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "common/messages.hpp"
#include "common/rand_index.hpp"
#include "common/status.hpp"
#include "common/topology.hpp"
#include "tools/fogctl/launcher.hpp"

namespace fogmap::cli {

double percentile(std::vector<double> v, double q);
// Sum of every sample of a metric family in a Prometheus text exposition.
double sumMetric(const std::string& text, const std::string& name);

struct RunResult {
  std::map<std::uint64_t, GlobalMapMessage> epochs;  // by epoch
  double bytes_moved = 0.0;                         // over every link of the cluster
};

struct RunOptions {
  std::uint64_t frames = 20;          // epochs to wait for
  std::chrono::milliseconds timeout{60000};
  bool point_labels = false;          // ask the root for per-point labels
  // With TLS, the client certificate the subscriber presents: <cert_dir>/<identity>.crt and .key.
  std::string identity = "operator";
};

// Writes the topology to dir/<name>.yaml, starts it (logs under dir/<name>/), subscribes to the
// root (with TLS as options.identity), waits for `frames` epochs or the timeout, scrapes every
// service's metrics and stops it.
// `during` (may be empty) runs once the cluster is up, e.g. to kill a node.
Expected<RunResult> runCluster(const std::filesystem::path& dir, const TopologyConfig& topology, const RunOptions& options,
                               const std::function<void(const Cluster&)>& during = {});

// The edges' view of one epoch, recomputed with the same library code as the edges: pre-processed
// points and local cluster labels per sensor, their local maps, and the bytes each edge ships.
struct EdgeView {
  std::map<std::uint32_t, std::vector<std::int32_t>> local_labels;
  std::map<std::uint32_t, Cloud> points;
  std::vector<Map> local_maps;  // as the parent decodes them
  std::size_t madc_bytes = 0;
  std::size_t baseline_bytes = 0;
};
Expected<std::map<std::uint64_t, EdgeView>> recomputeEdges(const TopologyConfig& topology,
                                                           const std::vector<std::uint64_t>& epochs);

struct Accuracy {
  RandScores clusters;  // elements = local clusters (the paper)
  RandScores points;    // elements = points
  bool ok = false;      // false when the baseline's labels do not match the edges' points
  std::string problem;  // why not ok
};
// MAD-C's global objects against the baseline's central clustering of the same points.
Accuracy accuracy(const GlobalMapMessage& madc, const GlobalMapMessage& baseline, const EdgeView& view);

}  // namespace fogmap::cli
