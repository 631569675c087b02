#pragma once
// Multi-object tracking metrics: how well tracks (hypotheses) follow the simulated truth on the
// ground plane. CLEAR MOT (Bernardin and Stiefelhagen 2008) with fragmentations and mostly
// tracked / mostly lost (Li, Huang and Nevatia 2009), the identity scores IDP, IDR, IDF1 (Ristani
// et al. 2016), and localization error statistics over matched pairs. Pure.
//
// A truth object and a hypothesis may be paired in a frame when their distance is strictly below
// `match_distance_m` (the CLEAR MOT gate; IDF1 uses the same gate so that both metrics agree on
// what counts as a hit). Ratios whose denominator is zero (MOTA without truth, MOTP without
// matches, ...) are NaN.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "common/base/status.hpp"

namespace fogmap::tracking {

// A truth object or a hypothesis (track) in one frame; ids are unique per frame and per kind.
struct MotObject {
  std::int64_t id = 0;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // m, ground plane
  // Where its front points (rad), when it has one: vehicles in the truth, vehicle tracks. Scored
  // over the matches where both have one; it never decides a match.
  std::optional<double> heading_rad{};
};

struct MotFrame {
  std::vector<MotObject> truth;
  std::vector<MotObject> hypotheses;
};

struct MotConfig {
  double match_distance_m = 1.0;  // a pair at this distance or farther is never a match
};

// Summary of a list of errors (m). p95 is the nearest-rank percentile: the ceil(0.95 n)-th
// smallest value. All NaN for an empty list.
struct ErrorStats {
  std::size_t count = 0;
  double mean_m = 0.0;
  double p95_m = 0.0;
  double max_m = 0.0;
};

struct ClearMot {
  std::size_t truth_count = 0;      // truth objects summed over frames (MOTA's denominator)
  std::size_t hypothesis_count = 0;  // hypotheses summed over frames
  std::size_t matches = 0;
  std::size_t misses = 0;            // FN
  std::size_t false_positives = 0;   // FP
  std::size_t id_switches = 0;       // IDSW: a truth object matched to another hypothesis than last time
  std::size_t fragmentations = 0;    // resumptions of a truth trajectory after it went untracked
  double total_distance_m = 0.0;     // summed over matches
  double mota = 0.0;                 // 1 - (FN + FP + IDSW) / truth_count
  double motp_m = 0.0;               // total_distance_m / matches
  // Truth trajectories by the share of their frames that are matched.
  std::size_t trajectories = 0;
  std::size_t mostly_tracked = 0;      // >= 80 %
  std::size_t partially_tracked = 0;   // between
  std::size_t mostly_lost = 0;         // <= 20 %
  std::vector<double> match_distances_m;  // every match's distance, frame by frame
  // Of the matches where both have a heading: the angle between the two headings, in degrees
  // within [0, 180], frame by frame.
  std::vector<double> match_heading_errors_deg;
};

struct IdScores {
  std::size_t idtp = 0;
  std::size_t idfp = 0;
  std::size_t idfn = 0;
  double idp = 0.0;   // IDTP / (IDTP + IDFP)
  double idr = 0.0;   // IDTP / (IDTP + IDFN)
  double idf1 = 0.0;  // 2 IDTP / (2 IDTP + IDFP + IDFN)
  // The optimal one-to-one matching, as (truth id, hypothesis id), only pairs with a positive IDTP,
  // ordered by truth id.
  std::vector<std::pair<std::int64_t, std::int64_t>> matching;
};

struct MotReport {
  ClearMot clear;
  IdScores identity;
  ErrorStats localization;  // over ClearMot's matches
  // Over ClearMot's matches where both have a heading; in degrees, although the fields say _m.
  ErrorStats heading_error_deg;
};

// Ok, or an invalid-argument error naming the first problem: a threshold that is not positive and
// finite, or the frame and id of a non-finite position or heading or an id that appears twice in a
// frame.
Status validateMotInput(std::span<const MotFrame> frames, const MotConfig& config);

// CLEAR MOT over the frames in order: keeps last frame's still valid correspondences, matches the
// rest by least total distance (the most pairs first), counts misses, false positives, switches.
Expected<ClearMot> clearMot(std::span<const MotFrame> frames, const MotConfig& config = {});

// IDP, IDR, IDF1 from the one-to-one matching of truth and hypothesis trajectories with the most
// IDTP (frames in which both exist and are closer than the threshold).
Expected<IdScores> idScores(std::span<const MotFrame> frames, const MotConfig& config = {});

// CLEAR MOT, identity scores and localization statistics, with the input validated once.
Expected<MotReport> evaluateMot(std::span<const MotFrame> frames, const MotConfig& config = {});

// Count, mean, nearest-rank p95 and max of `errors_m`; an error naming the index of a non-finite value.
Expected<ErrorStats> errorStats(std::span<const double> errors_m);

}  // namespace fogmap::tracking
