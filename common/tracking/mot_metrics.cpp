#include "common/tracking/mot_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "common/base/angles.hpp"
#include "common/geometry/oriented_box.hpp"
#include "common/tracking/assignment.hpp"

namespace fogmap::tracking {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kNotAllowed = std::numeric_limits<double>::infinity();

double ratio(double numerator, double denominator) {
  return denominator == 0.0 ? kNaN : numerator / denominator;
}

bool withinGate(double distance_m, const MotConfig& config) { return distance_m < config.match_distance_m; }

// Shortest form of a number for a message ("-1", "0.5", "nan").
std::string numberText(double value) {
  std::ostringstream out;
  out << value;
  return out.str();
}

Status validateObjects(const std::vector<MotObject>& objects, std::size_t frame, const char* kind) {
  std::unordered_set<std::int64_t> seen;
  for (const MotObject& object : objects) {
    const std::string where =
        "mot metrics: frame " + std::to_string(frame) + ": " + kind + " id " + std::to_string(object.id);
    if (!object.position.allFinite()) return invalidArgument(where + " has a non-finite position");
    if (object.heading_rad && !std::isfinite(*object.heading_rad)) return invalidArgument(where + " has a non-finite heading");
    if (!seen.insert(object.id).second) return invalidArgument(where + " appears twice");
  }
  return {};
}

// Per truth trajectory: what mostly tracked / mostly lost and fragmentations are made of.
struct TrajectoryRecord {
  std::size_t present = 0;  // frames in which the truth object exists
  std::size_t tracked = 0;  // of those, frames in which it is matched
  bool ever_tracked = false;
  bool tracked_last_time = false;  // in the last frame in which it existed
};

ClearMot clearMotOf(std::span<const MotFrame> frames, const MotConfig& config) {
  ClearMot out;
  // truth id -> hypothesis id: the previous frame's correspondences (the only ones CLEAR MOT keeps)
  // and the latest correspondence in any earlier frame (what an ID switch is measured against).
  std::unordered_map<std::int64_t, std::int64_t> previous;
  std::unordered_map<std::int64_t, std::int64_t> last_match;
  std::map<std::int64_t, TrajectoryRecord> trajectories;

  for (const MotFrame& frame : frames) {
    const std::size_t n_truth = frame.truth.size();
    const std::size_t n_hyp = frame.hypotheses.size();
    std::unordered_map<std::int64_t, std::size_t> hyp_index;
    for (std::size_t h = 0; h < n_hyp; ++h) hyp_index.emplace(frame.hypotheses[h].id, h);
    const auto distance = [&](std::size_t t, std::size_t h) {
      return (frame.truth[t].position - frame.hypotheses[h].position).norm();
    };

    std::vector<std::optional<std::size_t>> match(n_truth);
    std::vector<char> kept(n_truth, 0);
    std::vector<char> hyp_taken(n_hyp, 0);
    // 1. Correspondences of the previous frame that still hold, even if another hypothesis is now
    //    closer: this is what keeps a sound track from being penalised by a passing one.
    for (std::size_t t = 0; t < n_truth; ++t) {
      const auto before = previous.find(frame.truth[t].id);
      if (before == previous.end()) continue;
      const auto h = hyp_index.find(before->second);
      if (h == hyp_index.end() || !withinGate(distance(t, h->second), config)) continue;
      match[t] = h->second;
      kept[t] = 1;
      hyp_taken[h->second] = 1;
    }
    // 2. The rest by least total distance among the matchings with the most pairs.
    std::vector<std::size_t> free_truth;
    std::vector<std::size_t> free_hyp;
    for (std::size_t t = 0; t < n_truth; ++t) {
      if (!match[t]) free_truth.push_back(t);
    }
    for (std::size_t h = 0; h < n_hyp; ++h) {
      if (!hyp_taken[h]) free_hyp.push_back(h);
    }
    if (!free_truth.empty() && !free_hyp.empty()) {
      std::vector<std::vector<double>> cost(free_truth.size(), std::vector<double>(free_hyp.size()));
      for (std::size_t r = 0; r < free_truth.size(); ++r) {
        for (std::size_t c = 0; c < free_hyp.size(); ++c) {
          const double d = distance(free_truth[r], free_hyp[c]);
          cost[r][c] = withinGate(d, config) ? d : kNotAllowed;
        }
      }
      const auto assigned = assignMinCost(cost);
      for (std::size_t r = 0; r < free_truth.size(); ++r) {
        if (assigned[r]) match[free_truth[r]] = free_hyp[*assigned[r]];
      }
    }
    // 3. Count, and remember the correspondences for the next frame.
    std::unordered_map<std::int64_t, std::int64_t> current;
    for (std::size_t t = 0; t < n_truth; ++t) {
      const std::int64_t truth_id = frame.truth[t].id;
      TrajectoryRecord& record = trajectories[truth_id];
      ++record.present;
      const bool tracked = match[t].has_value();
      if (tracked) {
        const std::int64_t hyp_id = frame.hypotheses[*match[t]].id;
        const double d = distance(t, *match[t]);
        ++out.matches;
        out.total_distance_m += d;
        out.match_distances_m.push_back(d);
        const auto& truth_heading = frame.truth[t].heading_rad;
        const auto& hyp_heading = frame.hypotheses[*match[t]].heading_rad;
        if (truth_heading && hyp_heading) {
          out.match_heading_errors_deg.push_back(headingAngleBetween(*truth_heading, *hyp_heading) * kRadToDeg);
        }
        const auto last = last_match.find(truth_id);
        if (!kept[t] && last != last_match.end() && last->second != hyp_id) ++out.id_switches;
        last_match[truth_id] = hyp_id;
        current.emplace(truth_id, hyp_id);
        ++record.tracked;
        if (record.ever_tracked && !record.tracked_last_time) ++out.fragmentations;
        record.ever_tracked = true;
      }
      record.tracked_last_time = tracked;
    }
    previous = std::move(current);
    out.truth_count += n_truth;
    out.hypothesis_count += n_hyp;
  }

  out.misses = out.truth_count - out.matches;
  out.false_positives = out.hypothesis_count - out.matches;
  out.mota = 1.0 - ratio(static_cast<double>(out.misses + out.false_positives + out.id_switches),
                         static_cast<double>(out.truth_count));
  out.motp_m = ratio(out.total_distance_m, static_cast<double>(out.matches));
  out.trajectories = trajectories.size();
  for (const auto& [id, record] : trajectories) {
    // In integers, so that exactly 80 % and 20 % fall on the stated side.
    if (5 * record.tracked >= 4 * record.present) {
      ++out.mostly_tracked;
    } else if (5 * record.tracked <= record.present) {
      ++out.mostly_lost;
    } else {
      ++out.partially_tracked;
    }
  }
  return out;
}

IdScores idScoresOf(std::span<const MotFrame> frames, const MotConfig& config) {
  // Trajectories indexed in id order, so that the matching (and its ties) is reproducible.
  std::map<std::int64_t, std::size_t> truth_index;
  std::map<std::int64_t, std::size_t> hyp_index;
  std::size_t truth_detections = 0;
  std::size_t hyp_detections = 0;
  for (const MotFrame& frame : frames) {
    for (const MotObject& o : frame.truth) truth_index.emplace(o.id, 0);
    for (const MotObject& h : frame.hypotheses) hyp_index.emplace(h.id, 0);
    truth_detections += frame.truth.size();
    hyp_detections += frame.hypotheses.size();
  }
  std::size_t next = 0;
  for (auto& [id, index] : truth_index) index = next++;
  next = 0;
  for (auto& [id, index] : hyp_index) index = next++;

  // idtp[i][j]: frames in which truth trajectory i and hypothesis trajectory j are both present and
  // within the gate.
  std::vector<std::vector<std::size_t>> idtp(truth_index.size(), std::vector<std::size_t>(hyp_index.size(), 0));
  for (const MotFrame& frame : frames) {
    for (const MotObject& o : frame.truth) {
      const std::size_t i = truth_index.at(o.id);
      for (const MotObject& h : frame.hypotheses) {
        if (withinGate((o.position - h.position).norm(), config)) ++idtp[i][hyp_index.at(h.id)];
      }
    }
  }

  // Ristani et al. minimise IDFN + IDFP over a padded matrix; since IDFN + IDFP = (truth detections
  // + hypothesis detections) - 2 IDTP, that is the matching of most IDTP. Every pair is allowed
  // (cost -IDTP <= 0), so the solver's "most pairs first" never forces a worse total.
  IdScores out;
  if (!truth_index.empty() && !hyp_index.empty()) {
    std::vector<std::vector<double>> cost(truth_index.size(), std::vector<double>(hyp_index.size()));
    for (std::size_t i = 0; i < cost.size(); ++i) {
      for (std::size_t j = 0; j < cost[i].size(); ++j) cost[i][j] = -static_cast<double>(idtp[i][j]);
    }
    const auto assigned = assignMinCost(cost);
    std::vector<std::int64_t> hyp_ids(hyp_index.size());
    for (const auto& [id, index] : hyp_index) hyp_ids[index] = id;
    for (const auto& [truth_id, i] : truth_index) {
      if (!assigned[i] || idtp[i][*assigned[i]] == 0) continue;
      out.idtp += idtp[i][*assigned[i]];
      out.matching.emplace_back(truth_id, hyp_ids[*assigned[i]]);
    }
  }
  out.idfn = truth_detections - out.idtp;
  out.idfp = hyp_detections - out.idtp;
  const auto tp = static_cast<double>(out.idtp);
  out.idp = ratio(tp, tp + static_cast<double>(out.idfp));
  out.idr = ratio(tp, tp + static_cast<double>(out.idfn));
  out.idf1 = ratio(2.0 * tp, 2.0 * tp + static_cast<double>(out.idfp + out.idfn));
  return out;
}

}  // namespace

Status validateMotInput(std::span<const MotFrame> frames, const MotConfig& config) {
  if (!std::isfinite(config.match_distance_m) || config.match_distance_m <= 0.0) {
    return invalidArgument("mot metrics: match_distance_m must be positive and finite, got " +
                           numberText(config.match_distance_m));
  }
  for (std::size_t f = 0; f < frames.size(); ++f) {
    if (Status s = validateObjects(frames[f].truth, f, "truth"); !s) return s;
    if (Status s = validateObjects(frames[f].hypotheses, f, "hypothesis"); !s) return s;
  }
  return {};
}

Expected<ClearMot> clearMot(std::span<const MotFrame> frames, const MotConfig& config) {
  if (Status s = validateMotInput(frames, config); !s) return s.error();
  return clearMotOf(frames, config);
}

Expected<IdScores> idScores(std::span<const MotFrame> frames, const MotConfig& config) {
  if (Status s = validateMotInput(frames, config); !s) return s.error();
  return idScoresOf(frames, config);
}

Expected<MotReport> evaluateMot(std::span<const MotFrame> frames, const MotConfig& config) {
  if (Status s = validateMotInput(frames, config); !s) return s.error();
  MotReport report;
  report.clear = clearMotOf(frames, config);
  report.identity = idScoresOf(frames, config);
  // Every match is closer than the finite threshold, so the distances are finite and this cannot fail.
  Expected<ErrorStats> stats = errorStats(report.clear.match_distances_m);
  if (!stats) return stats.error();
  report.localization = stats.value();
  // The headings are finite (validated), so are their angles.
  Expected<ErrorStats> headings = errorStats(report.clear.match_heading_errors_deg);
  if (!headings) return headings.error();
  report.heading_error_deg = headings.value();
  return report;
}

Expected<ErrorStats> errorStats(std::span<const double> errors_m) {
  ErrorStats out;
  out.count = errors_m.size();
  if (errors_m.empty()) {
    out.mean_m = out.p95_m = out.max_m = kNaN;
    return out;
  }
  for (std::size_t i = 0; i < errors_m.size(); ++i) {
    if (!std::isfinite(errors_m[i])) {
      return invalidArgument("error stats: value " + std::to_string(i) + " is not finite (" +
                             numberText(errors_m[i]) + ")");
    }
  }
  std::vector<double> sorted(errors_m.begin(), errors_m.end());
  std::sort(sorted.begin(), sorted.end());
  double sum = 0.0;
  for (const double e : sorted) sum += e;
  out.mean_m = sum / static_cast<double>(sorted.size());
  // Nearest rank: ceil(0.95 n), in integers so that n = 20 gives exactly the 19th value.
  const std::size_t rank = (95 * sorted.size() + 99) / 100;
  out.p95_m = sorted[rank - 1];
  out.max_m = sorted.back();
  return out;
}

}  // namespace fogmap::tracking
