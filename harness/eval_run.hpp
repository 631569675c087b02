#pragma once
// fogctl eval: the MAD-C paper's evaluation reproduced with the running services on simulated
// random scenes (Figs. 6 to 9, Tables 1 and 2), and the tracking evaluation of the camera-LiDAR
// fusion paper's association against fogmap's on a moving scene (fogctl track-eval), written as
// CSV, eval.json and a Markdown report with the command that made it and the papers' figures
// beside ours. The report's PNG figures are drawn by pictures/eval_figures (drawEvaluationFigures)
// from the EvalResult, under the file names the report links to.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "common/io/messages.hpp"
#include "common/sim/scene.hpp"
#include "harness/cluster_run.hpp"
#include "harness/scene_run.hpp"
#include "harness/tracking_eval.hpp"

namespace fogmap::harness {

// The paper's alpha: the scene-size runs, the shaped links and the baseline's line in Fig. 8.
inline constexpr double kPaperAlpha = 1.5;

struct EvalPlan {
  std::vector<int> lidar_counts{2, 3, 5, 7};           // the paper's Lambda_2, 3, 5, 7
  std::vector<int> object_counts{10, 50, 100};         // scene sizes (Table 1, bytes, times)
  int accuracy_objects = 50;                           // the scene size of the alpha sweep (Figs. 7, 8)
  std::vector<double> alphas{0.8, 1.4, 1.5, 1.8, 2.4};  // run by the services
  std::vector<double> precision_alphas;                // Fig. 6 (default: 0.2 to 3.0 by 0.2)
  std::uint64_t frames = 5;                            // complete frames per run (a cycle of the scene)
  std::uint64_t seed = 1;
  std::optional<double> link_mbit = 10.0;              // Fig. 9: every edge link limited; none: skipped
  int link_lidars = 7;
  int link_objects = 100;
  double link_rate_hz = 1.0;                           // slow enough for whole scans to get through
  // The tracking section: paper and kalman at every miss rate on one moving scene (people and
  // vehicles, 4 LiDARs, 4 cameras), in process; none: skipped.
  std::optional<TrackingEvalConfig> tracking = TrackingEvalConfig{};
  std::filesystem::path out = ".fogmap/eval";          // CSV, PNG, eval.json
  std::filesystem::path work = ".fogmap/eval-work";    // the runs' topologies, scenes and logs
  std::filesystem::path doc;                           // the Markdown report (default: out/evaluation.md)
  std::string command;                                 // how it was run, for the report
  bool quick = false;
};

// The plan of `fogctl eval --quick`: two LiDAR counts, two scene sizes, three alphas, a shaped
// run of 3 LiDARs, a short tracking run; under two minutes on two cores.
EvalPlan quickEvalPlan();

struct AlphaRow {  // one MAD-C run of the accuracy sweep
  int lidars = 0;
  double alpha = 0.0;
  SceneScores scores;
};
struct SizeRow {  // MAD-C (alpha 1.5) and the baseline on one scene size
  int objects = 0;
  int lidars = 0;
  SceneScores scores;
};
struct PrecisionRow {
  int lidars = 0;
  double alpha = 0.0;
  bool aura = false;
  double precision = 0.0;
  double recall = 0.0;
  std::size_t clusters = 0;
};
struct LinkResult {
  bool ran = false;
  std::string skipped;  // why not, when it did not run
  int lidars = 0;
  int objects = 0;
  double mbit = 0.0;
  double rate_hz = 0.0;
  SceneScores scores;
  double raw_baseline_e2e_p50_ms = 0.0;  // the baseline that ships whole scans (the paper's)
  double raw_baseline_merge_ms = 0.0;    // its root: pre-processing every scan and clustering
};
// A bird's-eye picture of one scenario of the alpha sweep, and what it shows: MAD-C's global map
// of the scenario's last complete frame with the edges' points then, over the scene's truth.
struct EvalPicture {
  std::string file;     // in EvalPlan::out
  std::string caption;
  std::string title;    // starts the picture's title
  GlobalMapMessage global;
  EdgeView view;
  sim::Scene scene;
  TopologyConfig topology;
};
struct EvalResult {
  std::vector<EvalPicture> pictures;  // a bird's-eye view per scenario of the alpha sweep
  std::vector<AlphaRow> alphas;
  std::vector<SizeRow> sizes;
  std::vector<PrecisionRow> precision;
  LinkResult links;
  std::optional<TrackingEvalResult> tracking;
  double seconds = 0.0;
};

// Runs the plan (each run a real cluster of local processes on free loopback ports; the shaped
// runs in network namespaces). `log` gets one line per run.
Expected<EvalResult> runEvaluation(const EvalPlan& plan, const std::function<void(const std::string&)>& log);

// Writes out/accuracy.csv, precision_recall.csv, costs.csv, links.csv, tracking.csv (with a
// tracking run), eval.json and the report (the figures it links to: drawEvaluationFigures).
Status writeEvaluation(const EvalPlan& plan, const EvalResult& result);

}  // namespace fogmap::harness
