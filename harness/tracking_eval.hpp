#pragma once
// fogctl track-eval: the fusion tracker (DESIGN.md 2.5) run on a simulated moving scene through the
// real chain, scored against the scene's truth. Per 10 Hz instant every static LiDAR's simulated
// frame goes through its own displacement detector (Algorithm 1); the centroids, moved to the common
// frame, are merged into one LiDAR observation frame; every camera's truth-replay detections (with
// seeded misses, jitter and latency) reach the tracker before it, in arrival order. Both
// associations (paper, kalman) run for every miss rate on the same centroids and detections, and
// are scored with CLEAR MOT, IDF1 and localization error. Pure: no processes, no files.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "common/base/status.hpp"
#include "common/perception/preprocess.hpp"
#include "common/tracking/centroid_merge.hpp"
#include "common/tracking/displacement.hpp"
#include "common/tracking/mot_metrics.hpp"
#include "common/tracking/tracker.hpp"
#include "harness/report_text.hpp"
#include "harness/track_scoring.hpp"

namespace fogmap::harness {

// The ground removal and displacement settings for the moving scene's VLP-16s, and the tracker
// settings of each association this evaluation runs by default (why: in tracking_eval.cpp).
GroundParams trackingEvalGround();
tracking::DisplacementParams trackingEvalDisplacement();
tracking::TrackerConfig trackingEvalPaper();
tracking::TrackerConfig trackingEvalKalman();

struct TrackingEvalConfig {
  // The scene: movingScene(people, vehicles, lidars, cameras, seed).
  int people = 6;
  int vehicles = 2;
  int lidars = 4;   // 1 to 7 (the MAD-C paper's spots)
  int cameras = 4;  // 0 to 6
  int frames = 200;  // scored LiDAR instants, after one warm-up frame that only primes the detectors
  std::uint64_t seed = 1;
  double rate_hz = 10.0;
  std::vector<double> miss_rates = {0.0, 0.3, 0.6};
  double box_jitter_px = 2.0;
  double camera_latency_ms = 50.0;
  // A spinning LiDAR's frame, stamped at the start of its revolution, is complete one revolution
  // later: detections with less latency than this arrive before the LiDAR frame they fuse with.
  double lidar_delivery_ms = 100.0;
  // Centroids of one instant closer than this on the ground (from any LiDARs) are one observation:
  // one object seen by several LiDARs must be one measurement, and the mean of views from
  // different sides cancels each view's bias towards its LiDAR. 0: every centroid is kept.
  double merge_radius_m = 1.0;
  // Each LiDAR's centroids narrower than this radius are placed on the object's axis instead of
  // the side it sees (tracking::visibleSideCorrected; the merge still groups them as seen); 0: as
  // Algorithm 1 gives them.
  double visible_side_max_radius_m = tracking::kVisibleSideMaxRadiusM;
  double near_range_m = kNearRangeM;   // people this close to their nearest LiDAR are scored apart
  double match_distance_m = 1.0;  // the CLEAR MOT gate
  // The edge's ground removal before the displacement detector (none: the raw frame, as the paper).
  std::optional<GroundParams> ground = trackingEvalGround();
  tracking::DisplacementParams displacement = trackingEvalDisplacement();
  tracking::TrackerConfig paper = trackingEvalPaper();
  tracking::TrackerConfig kalman = trackingEvalKalman();
};

// Ok, or an invalid-argument error naming the first setting out of range.
Status validate(const TrackingEvalConfig& config);

inline constexpr double kOffsetReachM = 3.0;

// Where overlaid detections land: shares of the detections.
struct OverlayShares {
  double own = 0.0;    // an observation within the gate of the detection's own object (the nearest object)
  double other = 0.0;  // an observation nearest another object, within the gate
  double stray = 0.0;  // an observation within the gate of no object
  double none = 0.0;   // no observation in the box
};

// The LiDAR side, the same for every run.
struct ObservationStats {
  double centroids_per_frame = 0.0;     // displacement centroids of all LiDARs, per instant
  double observations_per_frame = 0.0;  // after merging
  // Share of (instant, moving object) with an observation within match_distance_m of it.
  double object_recall = 0.0;
  double person_recall_near = 0.0;  // the same for people within near_range_m of a LiDAR
  // Ground distance from a near person to the nearest centroid / observation within
  // match_distance_m: a single LiDAR's view against the merged views.
  tracking::ErrorStats centroid_error_near;
  tracking::ErrorStats observation_error_near;
  // The mean component of a single view's error along the direction to its LiDAR: a view of a
  // solid sees the side facing the sensor, so its centroid lies in front of the object's centre.
  double centroid_bias_to_lidar_m = 0.0;
  // Per label: the distance from each object's centre to the nearest merged observation within
  // kOffsetReachM, wider than the gate so that offsets beyond it show.
  std::vector<std::pair<std::string, tracking::ErrorStats>> observation_offset_by_label;
  // Overlay (Algorithm 3) of every detection at the first miss rate against the merged observations,
  // as the tracker runs it (nearest the frame's sensor position, the LiDARs' mean) and nearest the
  // camera's centre instead.
  std::size_t detections = 0;
  OverlayShares overlay, overlay_camera_centre;
};

// Per moving object: ID switches scored against it alone, and how close another object came.
struct ObjectSwitches {
  std::uint32_t object = 0;
  std::string label;
  double closest_approach_m = 0.0;  // to any other moving object over the run
  std::size_t id_switches = 0;
};

struct TrackingRun {
  std::string association;  // paper or kalman
  double miss_rate = 0.0;
  tracking::MotReport mot;
  // Per label of the moving objects: its objects against the tracks of that label.
  std::vector<std::pair<std::string, tracking::MotReport>> by_label;
  tracking::ErrorStats near_people;  // localization error of people within near_range_m of a LiDAR
  std::size_t tracks_confirmed = 0;  // distinct tracks that were ever confirmed
  double step_mean_ms = 0.0;         // Tracker::addCloud, per LiDAR instant
  double step_max_ms = 0.0;
  std::vector<ObjectSwitches> switches;
  tracking::TrackerCounters counters;
};

struct TrackingEvalResult {
  TrackingEvalConfig config;
  std::string scene;
  int moving_objects = 0;
  int lidars = 0;
  int cameras = 0;
  ObservationStats observations;
  std::vector<TrackingRun> runs;  // paper then kalman for each miss rate, in config order
  double seconds = 0.0;
};

// Simulates, detects, tracks and scores; an error for a bad config or a failing stage.
Expected<TrackingEvalResult> runTrackingEval(const TrackingEvalConfig& config);

// The runs as a Markdown table, with the settings and the observation figures under it.
std::string trackingTableMarkdown(const TrackingEvalResult& result);
// The two associations side by side: a row per miss rate, each cell "paper / kalman" (MOTA, MOTP,
// ID switches, fragmentations, IDF1, localization error mean, p95, max).
std::string trackingComparisonMarkdown(const TrackingEvalResult& result);
// Every figure of the result as one JSON object (non-finite numbers as null), and as its text.
Json trackingReport(const TrackingEvalResult& result);
std::string trackingJson(const TrackingEvalResult& result);

}  // namespace fogmap::harness
