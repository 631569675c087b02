#include "harness/track_scoring.hpp"

#include <algorithm>
#include <set>

#include "common/base/clock.hpp"
#include "common/geometry/object_class.hpp"
#include "harness/cluster_run.hpp"
#include "services/edge_cluster/edge_runner.hpp"

namespace fogmap::harness {

std::vector<const sim::SceneObject*> movingObjects(const sim::Scene& scene) {
  std::vector<const sim::SceneObject*> out;
  for (const auto& o : scene.objects) {
    if (o.motion.moves()) out.push_back(&o);
  }
  return out;
}

bool isHypothesis(const tracking::Track& track) { return track.state != tracking::TrackState::kTentative; }

TrackingFrame trackingFrame(const sim::Scene& scene, double time_s, std::span<const tracking::Track> tracks) {
  TrackingFrame frame;
  for (const auto* o : movingObjects(scene)) {
    const sim::ObjectPose pose = sim::poseAt(*o, time_s);
    // A vehicle's heading is scored (its box's length lies along its path); a person has none.
    const auto object_class = parseObjectClass(o->label);
    const bool vehicle = object_class && isVehicle(*object_class);
    frame.mot.truth.push_back({static_cast<std::int64_t>(o->id), pose.xy, vehicle ? std::optional<double>(pose.yaw_rad) : std::nullopt});
    frame.truth_labels.push_back(o->label);
    const bool near = std::any_of(scene.lidars.begin(), scene.lidars.end(), [&](const auto& lidar) {
      return (lidar.pose.translation().template head<2>() - pose.xy).norm() <= kNearRangeM;
    });
    frame.truth_near.push_back(near);
  }
  for (const auto& track : tracks) {
    if (!isHypothesis(track)) continue;
    if (track.state == tracking::TrackState::kConfirmed) frame.confirmed.push_back(track.id);
    frame.mot.hypotheses.push_back({static_cast<std::int64_t>(track.id), track.position, track.heading_rad});
    frame.hypothesis_labels.push_back(track.label);
  }
  return frame;
}

std::vector<tracking::MotObject> withinGateOf(std::span<const tracking::MotObject> truth,
                                              std::span<const tracking::MotObject> hypotheses, double gate_m) {
  std::vector<tracking::MotObject> out;
  for (const auto& h : hypotheses) {
    const bool reachable = std::any_of(truth.begin(), truth.end(),
                                       [&](const tracking::MotObject& t) { return (t.position - h.position).norm() < gate_m; });
    if (reachable) out.push_back(h);
  }
  return out;
}

Expected<TrackScores> scoreTracking(std::span<const TrackingFrame> frames, const tracking::MotConfig& config) {
  TrackScores out;
  std::vector<tracking::MotFrame> all;
  std::vector<tracking::MotFrame> people_near;
  bool any_near = false;
  std::set<std::string> labels;
  std::set<std::uint64_t> confirmed;
  for (const auto& f : frames) {
    if (f.truth_labels.size() != f.mot.truth.size() || f.hypothesis_labels.size() != f.mot.hypotheses.size() ||
        (!f.truth_near.empty() && f.truth_near.size() != f.mot.truth.size())) {
      return invalidArgument("track scoring: a frame's labels do not match its truth and hypotheses");
    }
    all.push_back(f.mot);
    tracking::MotFrame near;
    for (std::size_t j = 0; j < f.mot.truth.size() && j < f.truth_near.size(); ++j) {
      if (f.truth_near[j] && f.truth_labels[j] == "person") near.truth.push_back(f.mot.truth[j]);
    }
    for (std::size_t j = 0; j < f.mot.hypotheses.size(); ++j) {
      if (f.hypothesis_labels[j] == "person") near.hypotheses.push_back(f.mot.hypotheses[j]);
    }
    any_near = any_near || !near.truth.empty();
    people_near.push_back(std::move(near));
    labels.insert(f.truth_labels.begin(), f.truth_labels.end());
    confirmed.insert(f.confirmed.begin(), f.confirmed.end());
  }
  auto report = tracking::evaluateMot(all, config);
  if (!report) return report.error();
  out.mot = std::move(report).value();
  for (const std::string& label : labels) {
    std::vector<tracking::MotFrame> of_label;
    for (const auto& f : frames) {
      tracking::MotFrame m;
      for (std::size_t j = 0; j < f.mot.truth.size(); ++j) {
        if (f.truth_labels[j] == label) m.truth.push_back(f.mot.truth[j]);
      }
      for (std::size_t j = 0; j < f.mot.hypotheses.size(); ++j) {
        if (f.hypothesis_labels[j] == label) m.hypotheses.push_back(f.mot.hypotheses[j]);
      }
      of_label.push_back(std::move(m));
    }
    auto scored = tracking::evaluateMot(of_label, config);
    if (!scored) return scored.error();
    out.by_label.emplace_back(label, std::move(scored).value());
  }
  if (any_near) {
    auto scored = tracking::evaluateMot(people_near, config);
    if (!scored) return scored.error();
    out.people_near = std::move(scored).value();
  }
  out.tracks_confirmed = confirmed.size();
  return out;
}

double sceneTimeOf(const sim::Scene& scene, const EpochSchedule& schedule, double rate_hz, std::int64_t lidar_time_ns) {
  return sim::sceneTime(scene, scanNumberAt(schedule, rate_hz, schedule.epochAt(lidar_time_ns)), rate_hz);
}

std::optional<std::pair<std::size_t, std::size_t>> scoringWindow(std::span<const double> scene_times_s,
                                                                 std::size_t warmup, std::size_t frames,
                                                                 std::optional<double> from_s) {
  if (frames == 0) return std::nullopt;
  std::size_t start = 0;                // where the current stretch without a wrap begins
  std::optional<std::size_t> begin;     // with from_s: the window's first entry, once found
  for (std::size_t i = 0; i < scene_times_s.size(); ++i) {
    if (i > start && scene_times_s[i] < scene_times_s[i - 1]) {
      start = i;
      begin.reset();
    }
    if (!from_s) {
      if (i + 1 - start >= warmup + frames) return std::pair{start + warmup, start + warmup + frames};
      continue;
    }
    const bool crosses = scene_times_s[i] >= *from_s && (i == start || scene_times_s[i - 1] < *from_s);
    if (!begin && crosses && i - start >= warmup) begin = i;
    if (begin && i + 1 - *begin >= frames) return std::pair{*begin, *begin + frames};
  }
  return std::nullopt;
}

Expected<PublishedScores> scorePublishedTracks(const sim::Scene& scene, const EpochSchedule& schedule, double rate_hz,
                                               std::span<const PublishedTracks> lists, std::size_t warmup,
                                               std::size_t frames, const tracking::MotConfig& config,
                                               std::optional<double> from_s) {
  std::vector<double> times;
  times.reserve(lists.size());
  for (const auto& l : lists) times.push_back(sceneTimeOf(scene, schedule, rate_hz, l.lidar_time_ns));
  const auto window = scoringWindow(times, warmup, frames, from_s);
  if (!window) {
    return Error{ErrorCode::kInternal, "track scoring: " + std::to_string(lists.size()) + " track lists hold no " +
                                           std::to_string(frames) + " consecutive ones after a warm-up of " +
                                           std::to_string(warmup) + " within one cycle of the scene" +
                                           (from_s ? " from scene time " + std::to_string(*from_s) + " s" : std::string())};
  }
  PublishedScores out;
  std::vector<TrackingFrame> scored;
  std::vector<double> latency_ms;
  for (std::size_t i = window->first; i < window->second; ++i) {
    scored.push_back(trackingFrame(scene, times[i], lists[i].tracks));
    latency_ms.push_back(nsToMs(lists[i].published_time_ns - lists[i].lidar_time_ns));
  }
  auto scores = scoreTracking(scored, config);
  if (!scores) return scores.error();
  out.scores = std::move(scores).value();
  out.frames = scored.size();
  out.first_list = window->first;
  out.first_time_s = times[window->first];
  out.last_time_s = times[window->second - 1];
  out.latency_p50_ms = percentile(latency_ms, 0.5);
  out.latency_p95_ms = percentile(latency_ms, 0.95);
  out.latency_max_ms = *std::max_element(latency_ms.begin(), latency_ms.end());
  return out;
}

}  // namespace fogmap::harness
