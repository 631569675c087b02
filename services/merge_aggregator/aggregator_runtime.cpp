#include "services/merge_aggregator/aggregator_runtime.hpp"

#include <variant>

namespace fogmap {

Emitter::Emitter(SharedAggregator& aggregator, EmitterSinks sinks, Metrics* metrics, NowNs now_ns,
                 std::chrono::milliseconds period, std::shared_ptr<Pacer> pacer)
    : aggregator_(aggregator),
      sinks_(std::move(sinks)),
      metrics_(metrics),
      now_ns_(std::move(now_ns)),
      poller_([this] { pollOnce(); }, period, std::move(pacer)) {}

Emitter::~Emitter() { stop(); }

void Emitter::start() { poller_.start(); }

void Emitter::stop() { poller_.stop(); }

void Emitter::wake() { poller_.wake(); }

void Emitter::exportCounters(const AggregatorCounters& now) {
  if (metrics_ != nullptr) {
    metrics_->mapsIn(now.accepted - exported_.accepted);
    metrics_->lateMaps(now.late - exported_.late);
    metrics_->droppedEpochs(now.dropped_epochs - exported_.dropped_epochs);
    metrics_->fragmentsUnpublished(now.fragments_unpublished - exported_.fragments_unpublished);
    metrics_->caughtUpEpochs(now.caught_up - exported_.caught_up);
    metrics_->longestPollGapSeconds(static_cast<double>(now.longest_poll_gap_ns) * 1e-9);
    metrics_->lateEmits(now.late_emits - exported_.late_emits);
    metrics_->duplicateUploads(now.duplicates - exported_.duplicates);
    for (const auto& [reason, count] : now.refused) {
      const auto before = exported_.refused.find(reason);
      const std::uint64_t delta = count - (before == exported_.refused.end() ? 0 : before->second);
      if (delta > 0) metrics_->refused(refusalName(reason), delta);
    }
  }
  exported_ = now;
}

void Emitter::exportPublished(const GlobalMapMessage& global) {
  // Revisions and late maps are not the live picture.
  if (metrics_ == nullptr || global.late || global.revision != 0) return;
  metrics_->globalObjects(static_cast<double>(global.map.objects.size()));
  const auto name = [this](std::uint32_t id) {
    const auto it = sensor_names_.find(id);
    return it == sensor_names_.end() ? std::to_string(id) : it->second;
  };
  for (const std::uint32_t id : global.header.contributing_nodes) metrics_->sensorMissing(name(id), false);
  for (const std::uint32_t id : global.header.missing_nodes) metrics_->sensorMissing(name(id), true);
}

std::size_t Emitter::pollOnce() {
  std::vector<EpochOutput> outputs;
  std::size_t live = 0;
  std::size_t stale = 0;
  AggregatorCounters counters;
  const std::uint64_t drops = sinks_.link_drops ? sinks_.link_drops() : 0;
  aggregator_.with([&](MergeAggregator& core) {
    const std::int64_t now = now_ns_();
    core.setLinkDrops(drops);
    outputs = core.poll(now);
    live = core.liveChildren(now);
    stale = core.staleChildren(now);
    counters = core.counters();
  });
  if (metrics_ != nullptr) {
    metrics_->childrenLive(static_cast<double>(live));
    metrics_->childrenStale(static_cast<double>(stale));
  }
  exportCounters(counters);
  return dispatch(std::move(outputs));
}

std::size_t Emitter::drain() {
  std::vector<EpochOutput> outputs;
  AggregatorCounters counters;
  aggregator_.with([&](MergeAggregator& core) {
    outputs = core.drain(now_ns_());
    counters = core.counters();
  });
  exportCounters(counters);
  return dispatch(std::move(outputs));
}

std::size_t Emitter::dispatch(std::vector<EpochOutput> outputs) {
  for (auto& output : outputs) {
    // A baseline root clusters the epoch's points here, outside the core's lock, so the streams
    // keep flowing meanwhile.
    if (auto* job = std::get_if<BaselineJob>(&output.message)) {
      GlobalMapMessage global = clusterCentrally(std::move(*job));
      output.merge_seconds = global.merge_seconds;
      aggregator_.with([&](MergeAggregator& core) { core.published(global); });
      output.message = std::move(global);
    }
    if (metrics_ != nullptr) {
      metrics_->mergeSeconds(output.merge_seconds);
      metrics_->pairs(output.stats.pairs_tested, output.stats.pairs_pruned);
      metrics_->mapsOut();
    }
    if (auto* map = std::get_if<MapMessage>(&output.message)) {
      if (!sinks_.to_parent) continue;
      v1::Upload upload;
      *upload.mutable_map() = toProto(*map);
      sinks_.to_parent(std::move(upload));
    } else if (auto* global = std::get_if<GlobalMapMessage>(&output.message)) {
      global->published_time_ns = now_ns_();
      if (metrics_ != nullptr) {
        if (global->mode == Mode::kBaseline) metrics_->clusteringSeconds(output.merge_seconds);
        // Zero: no contribution carried a sensor timestamp, so there is no latency to report.
        // Late maps are not the live picture; their delay is not the pipeline's latency.
        if (global->header.sensor_time_ns > 0 && !global->late) {
          metrics_->endToEndSeconds(static_cast<double>(global->published_time_ns - global->header.sensor_time_ns) *
                                    1e-9);
        }
      }
      exportPublished(*global);
      if (sinks_.publish) sinks_.publish(std::move(*global));
    }
  }
  return outputs.size();
}

}  // namespace fogmap
