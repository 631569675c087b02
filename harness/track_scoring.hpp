#pragma once
// Tracks scored against a simulated scene's truth on the ground plane: the one scoring that
// `fogctl track-eval` (the tracker in process), `fogctl demo --scene` and the tracking cluster test
// (the tracker service's published tracks) share. The truth of a frame is every moving object's
// ground position at the frame's scene instant; the hypotheses are the confirmed and lost tracks (a
// tentative track claims nothing yet); both are scored with CLEAR MOT, IDF1 and the localization
// error, overall and per label. Published tracks are placed at their scene instant through the
// cluster's epochs and scored over a window inside one cycle of the scene. Pure: no processes.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "common/base/epochs.hpp"
#include "common/base/status.hpp"
#include "common/sim/scene.hpp"
#include "common/tracking/mot_metrics.hpp"
#include "common/tracking/track.hpp"

namespace fogmap::harness {

// The scene's objects that move, in the scene's order: the truth a tracker is scored against.
std::vector<const sim::SceneObject*> movingObjects(const sim::Scene& scene);

// A track counts as a hypothesis once it is confirmed, and stays one while lost.
bool isHypothesis(const tracking::Track& track);

// People this close to their nearest LiDAR (on the ground) are also scored apart: near a sensor a
// person is seen from one side, and where it is placed shows.
inline constexpr double kNearRangeM = 15.0;

// One frame to score.
struct TrackingFrame {
  tracking::MotFrame mot;                       // truth: movingObjects in order; hypotheses: isHypothesis tracks
  std::vector<std::string> truth_labels;        // per mot.truth entry
  std::vector<bool> truth_near;                 // per mot.truth entry: within kNearRangeM of a LiDAR
  std::vector<std::string> hypothesis_labels;   // per mot.hypotheses entry: the track's label
  std::vector<std::uint64_t> confirmed;         // ids of the tracks confirmed in this frame
};

// The frame at scene instant `time_s` with the tracks a tracker held after it.
TrackingFrame trackingFrame(const sim::Scene& scene, double time_s, std::span<const tracking::Track> tracks);

// The entries of `hypotheses` closer than `gate_m` to some entry of `truth`. The others can only be
// false positives: leaving them out changes no match, distance or switch and keeps the assignment
// small (the paper association leaves hundreds of lost tracks in a crowded scene).
std::vector<tracking::MotObject> withinGateOf(std::span<const tracking::MotObject> truth,
                                              std::span<const tracking::MotObject> hypotheses, double gate_m);

struct TrackScores {
  tracking::MotReport mot;
  // Per label of the truth, in name order: the objects of that label against the tracks given it.
  std::vector<std::pair<std::string, tracking::MotReport>> by_label;
  // The people within kNearRangeM of a LiDAR against the tracks labelled person (its localization
  // error is what counts: a person further out, or a car, is none of its truth); none without such
  // people.
  std::optional<tracking::MotReport> people_near;
  std::size_t tracks_confirmed = 0;  // distinct tracks confirmed in some frame
};

// CLEAR MOT, IDF1 and localization over the frames in order; an error for invalid input.
Expected<TrackScores> scoreTracking(std::span<const TrackingFrame> frames, const tracking::MotConfig& config = {});

// The tracks a tracker service published after fusing one global map.
struct PublishedTracks {
  std::int64_t lidar_time_ns = 0;      // the global map's sensor time (unix ns)
  std::int64_t published_time_ns = 0;  // when the tracker published them (unix ns, the same clock)
  std::vector<tracking::Track> tracks;
};

// The scene instant of a LiDAR frame stamped `lidar_time_ns` in a cluster of `schedule` whose
// simulated sensors run at `rate_hz`: the scan its epoch replays (scanNumberAt, as the edges pick
// it) at sim::sceneTime.
double sceneTimeOf(const sim::Scene& scene, const EpochSchedule& schedule, double rate_hz, std::int64_t lidar_time_ns);

// The first `frames` consecutive entries of `scene_times_s` that follow `warmup` entries without a
// wrap of the scene's cycle anywhere from the warm-up's start to the window's end (a scene time
// below its predecessor's: every object jumps back to its start, which no tracker should follow),
// as [begin, end); none while there is no such window yet. With `from_s`, the window starts where
// the scene time reaches from_s (the first entry at or after it whose predecessor in the stretch
// lies before it, or that opens the stretch), with `warmup` entries of its stretch before it: runs
// of one scene then score the same stretch of it whenever they start.
std::optional<std::pair<std::size_t, std::size_t>> scoringWindow(std::span<const double> scene_times_s,
                                                                 std::size_t warmup, std::size_t frames,
                                                                 std::optional<double> from_s = std::nullopt);

// A tracker service's published tracks scored against the scene.
struct PublishedScores {
  TrackScores scores;
  std::size_t frames = 0;        // track lists scored
  double first_time_s = 0.0;     // the scene instants of the first and last of them
  double last_time_s = 0.0;
  std::size_t first_list = 0;    // the window in the lists given: [first_list, first_list + frames)
  // From the LiDAR frame's sensor time to the publication of its tracks, over the lists scored.
  double latency_p50_ms = 0.0;
  double latency_p95_ms = 0.0;
  double latency_max_ms = 0.0;
};

// Scores the scoringWindow(warmup, frames, from_s) of `lists` (in the order read); an error naming
// what is missing when the lists hold no such window.
Expected<PublishedScores> scorePublishedTracks(const sim::Scene& scene, const EpochSchedule& schedule, double rate_hz,
                                               std::span<const PublishedTracks> lists, std::size_t warmup,
                                               std::size_t frames, const tracking::MotConfig& config = {},
                                               std::optional<double> from_s = std::nullopt);

}  // namespace fogmap::harness
