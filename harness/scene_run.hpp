#pragma once
// A simulated scene run by real clusters, MAD-C and the baseline side by side, and scored against
// the baseline and against the truth: what `fogctl demo --scene` shows and `fogctl eval` repeats
// over scene sizes, LiDAR counts and alphas. On a moving scene with cameras, the cluster with its
// tracker and detection services, whose published tracks are scored against the truth.
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "common/base/status.hpp"
#include "common/config/camera_node.hpp"
#include "common/config/topology.hpp"
#include "common/config/tracker_node.hpp"
#include "common/scoring/object_match.hpp"
#include "common/scoring/rand_index.hpp"
#include "common/sim/scene.hpp"
#include "common/sim/scene_topology.hpp"
#include "common/tracking/tracker_config.hpp"
#include "harness/cluster_run.hpp"
#include "harness/object_breakdown.hpp"
#include "harness/report_text.hpp"
#include "harness/track_scoring.hpp"
#include "harness/tracking_eval.hpp"

namespace fogmap::harness {

struct SceneRunOptions {
  Mode mode = Mode::kExt;    // kExt, kMadc or kBaseline
  double alpha = 1.5;
  bool tree = false;
  int fanout = 2;
  int base_port = 47000;
  bool free_ports = false;   // ports the kernel says are free now instead of base_port's block
  double rate_hz = 10.0;     // the sensors' rate and the cluster's epoch rate
  std::uint64_t frames = 5;  // complete epochs to collect
  std::optional<double> link_mbit;  // every edge behind a shaped link of this rate (ShapedLinks)
  bool baseline_raw = false;        // baseline: the edges ship whole scans, the root pre-processes
  sim::SceneMapping mapping;        // the edges' clustering and fragments (MAD-C modes)
};

// One cluster run on a scene: the topology it ran (as written) and what the root published.
struct SceneRun {
  TopologyConfig topology;
  RunResult result;
};

// The scene replayed as a loop of `cycle_frames` frames at `rate_hz` (its duration_s set so),
// written to dir/scene.yaml: every run on it shows the same frames, so MAD-C and the baseline can
// be compared frame by frame. Score runs with the scene as changed here.
Expected<std::filesystem::path> writeCycledScene(const std::filesystem::path& dir, sim::Scene& scene,
                                                 std::uint64_t cycle_frames, double rate_hz);

// Starts the cluster of `scene_file` (one edge per LiDAR, sceneTopology) in the given mode, waits
// for `frames` complete epochs and stops it. With link_mbit, every edge runs behind a shaped link
// (an error saying why when that cannot be done here).
Expected<SceneRun> runScene(const std::filesystem::path& dir, const std::filesystem::path& scene_file,
                            const sim::Scene& scene, const SceneRunOptions& options);

// MAD-C (an ext run) against the baseline and the truth over the frames both published complete.
struct SceneScores {
  std::size_t frames = 0;              // complete MAD-C epochs scored against the truth, one a cycle frame
  std::size_t frames_vs_baseline = 0;  // of which paired with a complete baseline epoch of the same frame
  RandScores madc_vs_baseline;         // mean over frames, elements = local clusters (MAD-C, the paper)
  RandScores ext_vs_baseline;          // mean over frames, elements = points (MAD-C-ext)
  RandScores madc_vs_truth;            // mean over frames, elements = points
  RandScores baseline_vs_truth;        // mean over the paired frames
  ObjectMatch madc_objects;            // summed over frames
  ObjectMatch baseline_objects;        // summed over the paired frames
  ObjectBreakdown madc_breakdown;      // madc_objects by range band and kind (every band and kind of the scene)
  ObjectBreakdown baseline_breakdown;  // baseline_objects so
  double madc_bytes_per_frame = 0.0;   // what the edges ship per frame (the services' wire sizes)
  double baseline_bytes_per_frame = 0.0;
  double raw_bytes_per_frame = 0.0;    // the raw scans in the same wire format (the paper's baseline)
  MapWireCost madc_wire;               // the edges' map uploads, all frames
  double global_objects = 0.0;         // MAD-C's global objects per frame
  double true_objects = 0.0;           // true objects with points per frame
  // From the services' metrics.
  double pairs_tested_per_epoch = 0.0;  // exact ellipsoid tests after box pruning, at the root
  double pairs_all_per_epoch = 0.0;     // what an all-pairs MERGE would test
  double clustering_ms = 0.0;           // local clustering per scan at an edge (mean)
  double merge_ms = 0.0;                // MERGE per epoch at the root (mean)
  double baseline_clustering_ms = 0.0;  // central clustering per epoch at the baseline's root
  double madc_e2e_p50_ms = 0.0;         // sensor time to published global map, complete epochs
  double baseline_e2e_p50_ms = 0.0;
  double madc_bytes_measured = 0.0;     // received by every aggregator over the run
  double baseline_bytes_measured = 0.0;
};
// `baseline` may be empty (nothing to compare with); errors when no complete epoch can be scored.
Expected<SceneScores> scoreSceneRuns(const sim::Scene& scene, const SceneRun& madc, const SceneRun* baseline);

// The views of the last complete MAD-C epoch (for pictures): its number and the edges' view.
Expected<std::pair<std::uint64_t, EdgeView>> lastCompleteView(const SceneRun& run);

// Where the true objects MAD-C missed in `epoch` (matchEachObject of its global map against the
// truth of `view`, that epoch's edges' view) were at the epoch's instant: their centres on the ground.
Expected<std::vector<Eigen::Vector2d>> missedObjectCentres(const sim::Scene& scene, const SceneRun& madc, std::uint64_t epoch,
                                                           const EdgeView& view);

// The median time from a frame's sensor time to its global map, over the complete epochs.
double endToEndP50Ms(const SceneRun& run);

// A scene whose tracks can be scored: something moves and a camera looks at it.
bool tracksScene(const sim::Scene& scene);

struct SceneTrackingOptions {
  tracking::Association association = tracking::Association::kKalman;
  // The tracker's LiDAR input: the root's global maps, or the displacement centroids every edge
  // finds with `displacement` (track-eval's settings for the moving scene's VLP-16s).
  TrackerInput input = TrackerInput::kGlobalMap;
  tracking::DisplacementParams displacement = trackingEvalDisplacement();
  // The cameras replay the truth with these misses, box jitter and latency (track-eval's defaults).
  TruthReplayConfig truth{0.3, 2.0, 50.0};
  int base_port = 47800;     // ports as sceneTopology numbers them from here
  bool free_ports = false;   // ports the kernel says are free now instead
  double rate_hz = 10.0;     // the LiDARs' rate and the cluster's epoch rate
  // Track lists read before the scored ones (tracks need a few frames to be confirmed, and the
  // first maps may lack an edge that is still starting), and the track lists scored.
  std::size_t warmup_lists = 30;
  std::size_t scored_lists = 100;
  // Unset: the first window the run reaches (the wall clock picks its stretch of the scene). Set:
  // the window from this scene time on (scoringWindow's from_s), waited for up to one more cycle.
  std::optional<double> scene_start_s;
  double match_distance_m = 1.0;  // the CLEAR MOT gate
  sim::SceneMapping mapping;      // the edges' clustering and fragments
};

// A tracking run: the topology it ran, what the root published and the services' metrics, and
// every track list read from the tracker, in order.
struct SceneTrackingRun {
  TopologyConfig topology;
  RunResult result;
  std::vector<PublishedTracks> lists;
};

// Starts the cluster of `scene_file` with its tracker (sceneTopology with a tracker and one truth
// detection node per camera, the topology `fogctl topology --scene F --tracker` writes), reads the
// tracker's stream until the lists hold a scoringWindow(warmup_lists, scored_lists, scene_start_s) or the time
// runs out, and stops it.
Expected<SceneTrackingRun> runSceneTracking(const std::filesystem::path& dir, const std::filesystem::path& scene_file,
                                            const sim::Scene& scene, const SceneTrackingOptions& options);

// The run's track lists scored against the scene (scorePublishedTracks over the options' window).
Expected<PublishedScores> scoreSceneTracking(const sim::Scene& scene, const SceneTrackingRun& run,
                                             const SceneTrackingOptions& options);

// What `fogctl demo` prints about a scored tracking run: one figure per line, indented.
std::string sceneTrackingText(const PublishedScores& scores, const SceneTrackingOptions& options, std::size_t moving_objects);
// The JSON object of a demo report's "tracking" key (non-finite numbers as null), and as its text.
Json sceneTrackingReport(const PublishedScores& scores, const SceneTrackingOptions& options, std::size_t moving_objects);
std::string sceneTrackingJson(const PublishedScores& scores, const SceneTrackingOptions& options, std::size_t moving_objects);
// The scored track lists as JSON lines, one per list in order: {"list", "scene_time_s", "truth":
// [{"id", "label", "x", "y", "heading_deg"}], "tracks": [{"id", "label", "confirmed", "x", "y",
// "heading_deg"}]} (tracks as scored: confirmed and lost ones; headings where there is one), so
// that what the figures count can be looked at list by list. Errors where the run's topology has no
// valid epoch schedule (its period and deadline), as scoreSceneTracking.
Expected<std::string> sceneTrackListsJsonLines(const sim::Scene& scene, const SceneTrackingRun& run, const PublishedScores& scores,
                                               const SceneTrackingOptions& options);

}  // namespace fogmap::harness
