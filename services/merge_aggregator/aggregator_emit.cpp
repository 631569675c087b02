// MergeAggregator's emitting half (aggregator_core.cpp collects and merges): which epochs are due,
// the maps and global maps they become, the root's silent epochs, and what is kept afterwards.
#include "services/merge_aggregator/aggregator_core.hpp"

#include <algorithm>
#include <iterator>
#include <map>
#include <set>
#include <utility>
#include <vector>

namespace fogmap {
namespace {

// The sensor's scan in its original order (the chunks tile it, checked on arrival).
Cloud assemblePoints(const std::map<std::uint32_t, PointChunk>& chunks) {
  Cloud cloud;
  for (const auto& [index, chunk] : chunks) cloud.insert(cloud.end(), chunk.points.begin(), chunk.points.end());
  return cloud;
}

std::vector<std::int32_t> assembleLabels(const std::map<std::uint32_t, PointChunk>& chunks) {
  std::vector<std::int32_t> labels;
  for (const auto& [index, chunk] : chunks) labels.insert(labels.end(), chunk.labels.begin(), chunk.labels.end());
  return labels;
}

}  // namespace

bool MergeAggregator::isComplete(const Epoch& epoch, std::int64_t now_ns) const {
  const bool needs_maps = config_.mode != Mode::kBaseline;
  const bool needs_points = config_.is_root && config_.mode != Mode::kMadc;
  for (const auto& [id, child] : children_) {
    // A dead child is never waited for (DESIGN.md 2.2): neither its map nor its sensors' points.
    if (!isLive(child, now_ns)) continue;
    if (needs_maps && !epoch.reported_children.contains(id)) return false;
    if (needs_points) {
      for (const auto sensor : child.sensors) {
        const auto it = epoch.points.find(sensor);
        if (it == epoch.points.end() || !it->second.complete()) return false;
      }
    }
  }
  return true;
}

void MergeAggregator::forgetOldEpochs(std::int64_t now_ns) {
  // Epochs whose deadline left the admission window can take no more maps (admit refuses them).
  const std::int64_t window = windowNs();
  const auto expired = [&](std::uint64_t epoch) {
    const std::int64_t deadline = schedule_.deadlineNs(epoch, config_.levels);
    return deadline < now_ns && now_ns - deadline > window;
  };
  // One with late data not yet emitted stays until poll has emitted its revision.
  for (auto it = emitted_.begin(); it != emitted_.end() && expired(it->first);) {
    it = it->second.dirty ? std::next(it) : emitted_.erase(it);
  }
}

void MergeAggregator::openSilentEpochs(std::int64_t now_ns) {
  // The root publishes every epoch, with every sensor missing when nothing came: a silent map is
  // news (every child dead or cut off), silence from the root is not. It opens every epoch as it
  // begins (empty until maps arrive), so poll, which emits in order, never emits an epoch before
  // an older one, reported or not. Epochs from the first poll on (those already due then are not
  // invented); after a stall of the root itself (SIGSTOP, a starved process) every epoch it missed
  // is published late and flagged, never left out. Only beyond max_pending_epochs (a stall of
  // many seconds) are the oldest of them dropped, counted in dropped_epochs as openEpoch does.
  if (now_ns < 0) return;
  const std::uint64_t current = schedule_.epochAt(now_ns);  // the latest epoch that has begun
  if (!silent_from_) {
    const std::int64_t due_ns = now_ns - static_cast<std::int64_t>(config_.levels) * schedule_.deadlineNs();
    silent_from_ = due_ns <= 0 ? 0 : schedule_.epochAt(due_ns) + 1;
  }
  std::uint64_t from = *silent_from_;
  if (current >= from && current - from + 1 > config_.max_pending_epochs) {
    const std::uint64_t skipped = current - from + 1 - config_.max_pending_epochs;
    for (std::uint64_t e = from; e < from + skipped; ++e) {
      if (!pending_.contains(e) && !emitted_.contains(e)) ++counters_.dropped_epochs;
    }
    from += skipped;
  }
  for (std::uint64_t e = from; e <= current; ++e) {
    if (pending_.contains(e) || emitted_.contains(e)) continue;
    openEpoch(e);
    if (now_ns > schedule_.deadlineNs(e, config_.levels) + schedule_.periodNs()) ++counters_.caught_up;
  }
  silent_from_ = std::max(*silent_from_, current + 1);
}

std::vector<EpochOutput> MergeAggregator::poll(std::int64_t now_ns) {
  std::vector<EpochOutput> outputs;
  if (last_poll_ns_) counters_.longest_poll_gap_ns = std::max(counters_.longest_poll_gap_ns, now_ns - *last_poll_ns_);
  last_poll_ns_ = std::max(last_poll_ns_.value_or(now_ns), now_ns);
  if (config_.is_root) openSilentEpochs(now_ns);
  // Oldest first, and in order: an epoch complete before an older one is due waits for it, so
  // every epoch's first emission comes after the previous epoch's.
  for (auto it = pending_.begin(); it != pending_.end();) {
    // Never before the epoch has begun: an early upload cannot make an epoch look complete.
    const bool begun = now_ns >= schedule_.startNs(it->first);
    const bool complete = begun && isComplete(it->second, now_ns);
    // An epoch nobody reported (the root opens every epoch as it begins) waits for its deadline
    // even when no child is live: a child that connects in time still makes it.
    const bool heard = !it->second.reported_children.empty() || !it->second.points.empty();
    if (!(complete && heard) && now_ns < schedule_.deadlineNs(it->first, config_.levels)) break;
    outputs.push_back(emit(it->first, it->second, complete, now_ns));
    emitted_.insert_or_assign(it->first, std::move(it->second));
    it = pending_.erase(it);
  }
  for (auto& [epoch_id, epoch] : emitted_) {
    if (epoch.dirty) outputs.push_back(emit(epoch_id, epoch, isComplete(epoch, now_ns), now_ns));
  }
  forgetOldEpochs(now_ns);
  std::stable_sort(outputs.begin(), outputs.end(),
                   [](const EpochOutput& a, const EpochOutput& b) { return a.epoch < b.epoch; });
  return outputs;
}

std::vector<EpochOutput> MergeAggregator::drain(std::int64_t now_ns) {
  std::vector<EpochOutput> outputs = poll(now_ns);
  for (auto& [epoch_id, epoch] : pending_) {
    outputs.push_back(emit(epoch_id, epoch, isComplete(epoch, now_ns), now_ns));
    emitted_.insert_or_assign(epoch_id, std::move(epoch));
  }
  pending_.clear();
  return outputs;
}

MapHeader MergeAggregator::headerFor(std::uint64_t epoch_id, const Epoch& epoch,
                                     const std::set<std::uint32_t>& contributing) const {
  MapHeader header;
  header.node = config_.node;
  header.epoch = epoch_id;
  header.sensor_time_ns = epoch.sensor_time_ns.value_or(0);
  header.contributing_nodes.assign(contributing.begin(), contributing.end());
  std::set_difference(sensors_.begin(), sensors_.end(), contributing.begin(), contributing.end(),
                      std::back_inserter(header.missing_nodes));
  header.failed_nodes.assign(epoch.failed.begin(), epoch.failed.end());
  header.dropped_uploads = link_drops_ + counters_.dropped_epochs;
  for (const auto& [id, child] : children_) header.dropped_uploads += child.dropped;
  return header;
}

EpochOutput MergeAggregator::emit(std::uint64_t epoch_id, Epoch& epoch, bool complete, std::int64_t now_ns) {
  EpochOutput out;
  out.epoch = epoch_id;
  out.complete = complete;
  out.revision = epoch.revision++;
  out.late = out.revision > 0 || now_ns > schedule_.deadlineNs(epoch_id, config_.levels) + schedule_.periodNs();
  out.stats = epoch.stats;
  out.merge_seconds = epoch.merge_seconds;
  epoch.dirty = false;
  ++counters_.emitted;
  if (out.revision > 0) ++counters_.revisions;
  if (out.late) ++counters_.late_emits;

  if (!config_.is_root) {
    // The whole epoch again for a revision: MERGE is idempotent, the parent keeps what it has.
    out.message = MapMessage{headerFor(epoch_id, epoch, epoch.contributing), epoch.working};
    return out;
  }

  GlobalMapMessage global;
  global.mode = config_.mode;
  global.revision = out.revision;
  global.late = out.late;
  if (config_.mode == Mode::kBaseline) {
    BaselineJob job;
    job.node = config_.node;
    job.madc = config_.madc;
    job.preprocess = config_.preprocess;
    std::set<std::uint32_t> contributing;
    for (const auto& [sensor, points] : epoch.points) {
      // A partial scan would be clustered wrongly near the gaps; a failed one has no data.
      if (!points.complete() || epoch.failed.contains(sensor)) continue;
      contributing.insert(sensor);
      job.scans.emplace_back(sensor, assemblePoints(points.chunks));
    }
    global.header = headerFor(epoch_id, epoch, contributing);
    job.message = std::move(global);
    out.stats = {};
    out.message = std::move(job);
    return out;
  }

  // Edges ship their fragments too; what is published are the objects with min_points points
  // over all their sensors (withoutFragments, common/geometry/map.hpp).
  global.map = withoutFragments(epoch.working, config_.madc.clustering.min_points);
  counters_.fragments_unpublished += epoch.working.objects.size() - global.map.objects.size();
  global.header = headerFor(epoch_id, epoch, epoch.contributing);
  if (config_.mode == Mode::kExt) {
    std::map<EllipsoidId, std::int32_t> object_of;
    for (std::size_t i = 0; i < global.map.objects.size(); ++i) {
      for (const auto& e : global.map.objects[i].ellipsoids) object_of.emplace(e.id, static_cast<std::int32_t>(i));
    }
    for (const auto& [sensor, points] : epoch.points) {
      if (!points.complete()) continue;
      NodeLabels labels{sensor, assembleLabels(points.chunks)};
      for (auto& label : labels.labels) {
        if (label < 0) continue;
        const auto it = object_of.find({sensor, epoch_id, static_cast<std::uint32_t>(label)});
        // A local cluster missing from the global map (its map was lost) has no object.
        label = it == object_of.end() ? -1 : it->second;
      }
      global.point_labels.push_back(std::move(labels));
    }
  }
  global.merge_seconds = out.merge_seconds;
  global.pairs_all = out.stats.pairs_all;
  global.pairs_tested = out.stats.pairs_tested;
  published(global);
  out.message = std::move(global);
  return out;
}

void MergeAggregator::published(const GlobalMapMessage& message) {
  // Geofences answer on the live picture: never a late revision, never an older epoch.
  if (message.late) return;
  if (!latest_ || latest_->header.epoch <= message.header.epoch) latest_ = message;
}

}  // namespace fogmap
