#pragma once
// What `fogctl demo` reports. On recorded scans: MAD-C's and the baseline's runs over the same scans,
// paired epoch by epoch (the same scan replayed), and scored: objects, bytes, latencies, the Rand
// index against the baseline. On a simulated scene: the scores of scoreSceneRuns. Each as the text
// the terminal shows and as the JSON report. The pairing and the texts are pure.
#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "common/io/messages.hpp"
#include "harness/cluster_run.hpp"
#include "harness/epoch_latency.hpp"
#include "harness/report_text.hpp"
#include "harness/scene_run.hpp"

namespace fogmap::harness {

// The complete MAD-C epochs that a complete baseline epoch of the same scan (epoch mod `scans`)
// can be compared with, in order, with that baseline epoch; and the MAD-C epochs with a node missing.
struct EpochPairing {
  std::vector<std::pair<std::uint64_t, std::uint64_t>> compared;  // (MAD-C epoch, baseline epoch)
  std::size_t incomplete = 0;
};
EpochPairing pairEpochsByScan(const std::map<std::uint64_t, GlobalMapMessage>& madc,
                              const std::map<std::uint64_t, GlobalMapMessage>& baseline, std::size_t scans);

// One compared epoch.
struct RecordedEpoch {
  std::uint64_t epoch = 0;
  std::size_t scan = 0;
  std::size_t objects = 0;           // MAD-C's global objects
  std::size_t baseline_objects = 0;  // the baseline's
  std::size_t madc_bytes = 0;        // what the edges shipped (their local maps)
  std::size_t baseline_bytes = 0;    // the pre-processed points the baseline ships
  double merge_ms = 0.0;
  double e2e_ms = 0.0;
  Accuracy accuracy;
};

struct RecordedScores {
  std::vector<RecordedEpoch> epochs;  // compared, in order
  std::size_t published = 0;          // epochs MAD-C published
  std::size_t incomplete = 0;         // of which with a node missing
  EpochLatencies latencies;           // of every MAD-C epoch
  double madc_bytes_per_frame = 0.0;  // over every link, per published epoch
  double baseline_bytes_per_frame = 0.0;
  MapWireCost wire;                   // the edges' map uploads (compared epochs)
  // Means over the compared epochs whose labels matched (Accuracy::ok).
  double rand_index = 0.0;         // elements = local clusters (the paper)
  double adjusted_rand_index = 0.0;
  double rand_index_points = 0.0;  // elements = points
  EdgeView last_view;              // the edges' view of the last compared epoch (for its picture)
};

// Pairs the runs' epochs (by the scans the topology's sensors replay), recomputes what the edges saw
// in each compared epoch and scores it; an error when no epoch can be compared.
Expected<RecordedScores> scoreRecordedRuns(const TopologyConfig& madc_topology, const RunResult& madc,
                                           const RunResult& baseline);

// The table of compared epochs and the summary under it.
std::string recordedScoresText(const RecordedScores& scores);
// The JSON report's figures (the caller adds the run's parameters).
Json recordedReport(const RecordedScores& scores);

// The scene demo's summary of scoreSceneRuns, and its JSON report's figures.
std::string sceneScoresText(const SceneScores& scores);
Json sceneScoresReport(const SceneScores& scores);

}  // namespace fogmap::harness
