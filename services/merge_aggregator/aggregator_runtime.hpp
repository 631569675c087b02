#pragma once
// What the gRPC adapters share: the core behind one mutex, the clock, and the emitter (the poll
// thread that turns emitted epochs into uploads to the parent or global maps for subscribers).
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "common/base/clock.hpp"
#include "services/common/metrics.hpp"
#include "services/common/periodic.hpp"
#include "services/common/proto_convert.hpp"
#include "services/merge_aggregator/aggregator_core.hpp"

namespace fogmap {

// The core is not thread-safe; every RPC handler and the emitter go through here.
class SharedAggregator {
 public:
  explicit SharedAggregator(MergeAggregator core) : core_(std::move(core)) {}
  // Runs f(core) under the lock and returns its result.
  template <class F>
  decltype(auto) with(F&& f) {
    std::lock_guard lock(mutex_);
    return std::forward<F>(f)(core_);
  }

 private:
  std::mutex mutex_;
  MergeAggregator core_;
};

// Where emitted epochs go; either may be empty.
struct EmitterSinks {
  std::function<void(v1::Upload)> to_parent;      // intermediate: ParentLink::send
  std::function<void(GlobalMapMessage)> publish;  // root: GlobalMapService::publish
  std::function<std::uint64_t()> link_drops;      // intermediate: ParentLink::dropped
};

class Emitter {
 public:
  // `metrics` may be null (tests). `pacer`: how the poll thread waits (empty: the steady clock).
  Emitter(SharedAggregator& aggregator, EmitterSinks sinks, Metrics* metrics, NowNs now_ns = systemNowNs,
          std::chrono::milliseconds period = std::chrono::milliseconds(2), std::shared_ptr<Pacer> pacer = nullptr);
  ~Emitter();  // stops the thread
  Emitter(const Emitter&) = delete;
  Emitter& operator=(const Emitter&) = delete;

  // Polls every `period` on a thread until stop().
  void start();
  void stop();
  // Polls now (from any thread): called when an upload arrives that may complete an epoch.
  void wake();
  // One poll: emits every due epoch to the sinks, updates metrics; returns how many it emitted.
  std::size_t pollOnce();
  // Emits every open epoch, due or not (shutdown, after the ingest stopped); returns how many.
  std::size_t drain();
  // Root: the names of the sensor nodes, for the per-sensor metrics of published maps (call
  // before start()). An id without a name is reported by its number.
  void sensorNames(std::map<std::uint32_t, std::string> names) { sensor_names_ = std::move(names); }

 private:
  std::size_t dispatch(std::vector<EpochOutput> outputs);
  // Exports what the core counted since the last call (the core's counters are the one set).
  void exportCounters(const AggregatorCounters& now);
  // Root: objects and missing sensors of a live global map.
  void exportPublished(const GlobalMapMessage& global);

  SharedAggregator& aggregator_;
  EmitterSinks sinks_;
  Metrics* metrics_;
  NowNs now_ns_;
  std::map<std::uint32_t, std::string> sensor_names_;
  AggregatorCounters exported_;  // what exportCounters has reported so far (emitter thread only)
  Periodic poller_;              // last: its thread stops before the members it polls with go
};

}  // namespace fogmap
