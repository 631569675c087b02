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

#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "common/io/messages.hpp"
#include "common/scoring/rand_index.hpp"
#include "harness/launcher.hpp"

namespace fogmap::harness {

double percentile(std::vector<double> v, double q);
// Sum of every sample of a metric family in a Prometheus text exposition.
double sumMetric(const std::string& text, const std::string& name);

struct RunResult {
  std::map<std::uint64_t, GlobalMapMessage> epochs;  // by epoch
  double bytes_moved = 0.0;                         // over every link of the cluster
  std::map<std::string, std::string> metrics;       // node name -> its /metrics page at the end
};

// An epoch every sensor contributed to.
bool completeEpoch(const GlobalMapMessage& global);
// The complete epochs of a run, in order.
std::vector<std::uint64_t> completeEpochs(const RunResult& run);

struct RunOptions {
  std::uint64_t frames = 20;          // epochs to wait for
  std::uint64_t complete_frames = 0;  // if > 0: also stop once this many epochs had every sensor
  // If set: also stop once it says the epochs so far suffice (called under the collector's lock).
  std::function<bool(const RunResult&)> enough;
  std::chrono::milliseconds timeout{60000};
  bool point_labels = false;          // ask the root for per-point labels
  // With TLS, the client certificate the subscriber presents: <cert_dir>/<identity>.crt and .key.
  std::string identity = "operator";
  // Per node, a command prefix that runs it (e.g. inside a network namespace: ShapedLinks).
  std::map<std::string, std::vector<std::string>> prefixes;
};

// Writes the topology to dir/<name>.yaml, starts it (logs under dir/<name>/), subscribes to the
// root (with TLS as options.identity), waits for `frames` epochs or the timeout, scrapes every
// service's metrics and stops it. The epochs are every epoch's first publication (late ones
// flagged), revisions left out.
// `during` (may be empty) runs once the cluster is up, e.g. to kill a node; the subscriber keeps
// collecting until it has returned, whatever `frames` says.
Expected<RunResult> runCluster(const std::filesystem::path& dir, const TopologyConfig& topology, const RunOptions& options,
                               const std::function<void(const Cluster&)>& during = {});

// The edges' view of one epoch, recomputed with the same library code as the edges: pre-processed
// points and local cluster labels per sensor, their local maps, and the bytes each edge ships.
struct EdgeView {
  std::map<std::uint32_t, std::vector<std::int32_t>> local_labels;
  std::map<std::uint32_t, Cloud> points;
  std::vector<Map> local_maps;  // as the parent decodes them
  // Simulated sensors only: the true object of every point (-1: none, e.g. ground).
  std::map<std::uint32_t, std::vector<std::int64_t>> truth;
  std::size_t madc_bytes = 0;          // the local maps' uploads, on the compact wire
  std::size_t madc_view_bytes = 0;     // of those, what the ellipsoids' views (boxes, classes) add
  std::size_t madc_ellipsoids = 0;     // in those local maps
  std::size_t madc_views = 0;          // of those, the ones with a box or a class
  std::size_t madc_exact_bytes = 0;    // the uploads without views, every ellipsoid exact (EllipsoidWire::kExact)
  std::size_t baseline_bytes = 0;  // the pre-processed points (what fogmap's baseline ships)
  std::size_t raw_bytes = 0;       // the scans before pre-processing, in the same wire format
};

// What the edges' map uploads cost, summed over edge views. An ellipsoid's bytes are its record and
// its share of the upload (header, blocks); its view (box, class) is counted apart, as what the
// ellipsoids carry beside them.
struct MapWireCost {
  std::size_t bytes = 0;
  std::size_t view_bytes = 0;
  std::size_t exact_bytes = 0;
  std::size_t ellipsoids = 0;
  std::size_t views = 0;

  void add(const EdgeView& view);
  double bytesPerEllipsoid() const;       // the uploads without their views, over the ellipsoids
  double exactBytesPerEllipsoid() const;  // the same with every ellipsoid exact (float32)
  double viewBytesPerEllipsoid() const;   // what the views add, over all ellipsoids
  double viewShare() const;               // the share of the ellipsoids that carry a view
  double bytesPerFrame(std::size_t frames) const;      // the uploads, views included
  double viewBytesPerFrame(std::size_t frames) const;  // what the views add to them
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

}  // namespace fogmap::harness
