#include "services/merge_aggregator/aggregator_runtime.hpp"

#include <variant>

namespace fogmap {

std::int64_t systemNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

Emitter::Emitter(SharedAggregator& aggregator, EmitterSinks sinks, Metrics* metrics, NowNs now_ns,
                 std::chrono::milliseconds period)
    : aggregator_(aggregator), sinks_(std::move(sinks)), metrics_(metrics), now_ns_(std::move(now_ns)), period_(period) {}

Emitter::~Emitter() { stop(); }

void Emitter::start() {
  std::lock_guard lock(mutex_);
  if (thread_.joinable()) return;
  stopping_ = false;
  thread_ = std::thread([this] { run(); });
}

void Emitter::stop() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void Emitter::run() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    lock.unlock();
    pollOnce();
    lock.lock();
    wake_.wait_for(lock, period_, [this] { return stopping_ || woken_; });
    woken_ = false;
  }
}

void Emitter::wake() {
  {
    std::lock_guard lock(mutex_);
    woken_ = true;
  }
  wake_.notify_one();
}

std::size_t Emitter::pollOnce() {
  std::vector<EpochOutput> outputs;
  std::size_t live = 0;
  std::size_t stale = 0;
  aggregator_.with([&](MergeAggregator& core) {
    outputs = core.poll(now_ns_());
    live = core.liveChildren();
    stale = core.staleChildren();
  });

  if (metrics_ != nullptr) {
    metrics_->childrenLive(static_cast<double>(live));
    metrics_->childrenStale(static_cast<double>(stale));
  }

  for (auto& output : outputs) {
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
        if (global->header.sensor_time_ns > 0) {
          metrics_->endToEndSeconds(static_cast<double>(global->published_time_ns - global->header.sensor_time_ns) * 1e-9);
        }
      }
      if (sinks_.publish) sinks_.publish(std::move(*global));
    }
  }
  return outputs.size();
}

}  // namespace fogmap
