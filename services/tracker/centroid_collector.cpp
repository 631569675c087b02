#include "services/tracker/centroid_collector.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "common/config/tracker_node.hpp"
#include "common/tracking/centroid_merge.hpp"

namespace fogmap {

const char* centroidVerdictName(CentroidVerdict verdict) {
  switch (verdict) {
    case CentroidVerdict::kAccepted:
      return "accepted";
    case CentroidVerdict::kUnknownEdge:
      return "unknown_edge";
    case CentroidVerdict::kLate:
      return "late";
    case CentroidVerdict::kClockSkew:
      return "clock_skew";
    case CentroidVerdict::kDuplicate:
      return "duplicate";
  }
  return "unknown";
}

CentroidCollector::CentroidCollector(CentroidCollectorConfig config, EpochSchedule schedule)
    : config_(std::move(config)), schedule_(schedule), edges_(config_.edges.begin(), config_.edges.end()) {
  config_.max_open_epochs = std::max<std::size_t>(config_.max_open_epochs, 1);
}

CentroidCollectorConfig centroidCollectorConfigFor(const TopologyConfig& topology, const NodeConfig& tracker) {
  CentroidCollectorConfig config;
  for (const NodeConfig* e : topology.centroidEdgesOf(tracker.name)) config.edges.push_back(e->name);
  if (tracker.tracker) {
    config.merge_radius_m = tracker.tracker->centroid_merge_m;
    config.visible_side_max_radius_m = tracker.tracker->visible_side_max_radius_m;
  }
  config.window_periods = topology.admission.window_periods;
  return config;
}

tracking::CloudFrame CentroidCollector::merged(const std::vector<tracking::CentroidFrame>& frames) const {
  tracking::CloudFrame out;
  if (!frames.empty()) out.time_ns = frames.front().time_ns;
  std::vector<tracking::DisplacementCentroid> centroids;
  std::vector<tracking::DisplacementCentroid> located;  // each moved to its object's axis (narrow ones)
  for (const auto& f : frames) {
    out.time_ns = std::min(out.time_ns, f.time_ns);
    out.sensor_position += f.sensor_position;
    for (const auto& c : f.centroids) {
      centroids.push_back(c);
      located.push_back(tracking::visibleSideCorrected(c, f.sensor_position, config_.visible_side_max_radius_m));
    }
  }
  if (!frames.empty()) out.sensor_position /= static_cast<double>(frames.size());
  out.observations = tracking::mergeCentroids(centroids, config_.merge_radius_m, located);
  return out;
}

std::int64_t CentroidCollector::windowNs() const {
  return static_cast<std::int64_t>(std::llround(config_.window_periods * static_cast<double>(schedule_.periodNs())));
}

std::optional<std::string> CentroidCollector::clockSkew(std::uint64_t epoch, std::int64_t time_ns,
                                                        std::int64_t now_ns) const {
  const std::int64_t window = windowNs();
  // In double: a forged time may lie anywhere in the int64 range.
  const auto ms = [](double ns) { return std::to_string(std::llround(ns * 1e-6)) + " ms"; };
  const auto apart = [](std::int64_t a, std::int64_t b) { return static_cast<double>(a) - static_cast<double>(b); };
  const std::string beyond = ", beyond the admission window of " + ms(static_cast<double>(window));
  const std::int64_t start = schedule_.startNs(epoch);
  if (start > now_ns && start - now_ns > window) {
    return "the epoch starts " + ms(apart(start, now_ns)) + " ahead of the tracker's clock" + beyond +
           " (check the edge's clock)";
  }
  const std::int64_t deadline = schedule_.deadlineNs(epoch, 1);
  if (deadline < now_ns && now_ns - deadline > window) {
    return "the epoch's deadline passed " + ms(apart(now_ns, deadline)) + " ago" + beyond;
  }
  if (time_ns > now_ns && time_ns - now_ns > window) {
    return "the sensor time lies " + ms(apart(time_ns, now_ns)) + " ahead of the tracker's clock" + beyond +
           " (check the edge's clock)";
  }
  if (time_ns < now_ns - schedule_.deadlineNs() - window) {
    return "the sensor time lies " + ms(apart(now_ns, time_ns)) + " behind the tracker's clock, more than deadline_ms" +
           beyond;
  }
  return std::nullopt;
}

bool CentroidCollector::complete(std::uint64_t epoch) const {
  return std::all_of(edges_.begin(), edges_.end(), [&](const std::string& edge) {
    const auto it = newest_.find(edge);
    return it != newest_.end() && it->second >= epoch;
  });
}

void CentroidCollector::emit(std::map<std::uint64_t, std::vector<tracking::CentroidFrame>>::iterator it,
                             std::vector<tracking::CloudFrame>& out) {
  if (!complete(it->first)) ++counters_.epochs_partial;
  ++counters_.epochs_emitted;
  out.push_back(merged(it->second));
  emitted_any_ = true;
  last_emitted_ = it->first;
  open_.erase(it);
}

std::vector<tracking::CloudFrame> CentroidCollector::expire(std::int64_t now_ns) {
  std::vector<tracking::CloudFrame> out;
  // In epoch order: an epoch is never emitted after a later one.
  while (!open_.empty()) {
    const auto oldest = open_.begin();
    if (now_ns < schedule_.deadlineNs(oldest->first, 1) && !complete(oldest->first)) break;
    emit(oldest, out);
  }
  return out;
}

CentroidCollector::Added CentroidCollector::add(tracking::CentroidFrame frame, std::int64_t now_ns) {
  Added added;
  added.ready = expire(now_ns);
  if (edges_.count(frame.edge) == 0) {
    added.verdict = CentroidVerdict::kUnknownEdge;
    added.detail = "not an edge that sends centroids to this tracker";
    return added;
  }
  const std::uint64_t epoch = frame.epoch;
  if (auto skew = clockSkew(epoch, frame.time_ns, now_ns)) {
    added.verdict = CentroidVerdict::kClockSkew;
    added.detail = std::move(*skew);
    return added;
  }
  if (emitted_any_ && epoch <= last_emitted_) {
    added.verdict = CentroidVerdict::kLate;
    added.detail = "epoch " + std::to_string(last_emitted_) + " was fused already";
    return added;
  }
  const auto newest = newest_.find(frame.edge);
  if (newest != newest_.end() && epoch <= newest->second) {
    // The same epoch twice, or an older one after a newer (the stream keeps order): either way
    // the edge has spoken for this epoch.
    added.verdict = CentroidVerdict::kDuplicate;
    added.detail = "the edge sent epoch " + std::to_string(newest->second) + " already";
    return added;
  }
  newest_[frame.edge] = epoch;
  ++counters_.frames_accepted;
  open_[epoch].push_back(std::move(frame));
  while (open_.size() > config_.max_open_epochs) emit(open_.begin(), added.ready);
  // This frame may complete its epoch and, as the edge's newest, earlier ones it skipped.
  const auto more = expire(now_ns);
  added.ready.insert(added.ready.end(), more.begin(), more.end());
  return added;
}

}  // namespace fogmap
