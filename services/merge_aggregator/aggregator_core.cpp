#include "services/merge_aggregator/aggregator_core.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <utility>

#include "common/clustering.hpp"

namespace fogmap {
namespace {

// Closed epochs remembered exactly; older ones are covered by a floor. Far more than any sane
// number of epochs in flight, small enough to cost nothing.
constexpr std::size_t kClosedHistory = 4096;

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string nodeText(std::uint32_t node) { return "node " + std::to_string(node); }

void addStats(MergeStats& total, const MergeStats& step) {
  total.pairs_all += step.pairs_all;
  total.pairs_tested += step.pairs_tested;
  total.pairs_pruned += step.pairs_pruned;
}

}  // namespace

MergeAggregator::MergeAggregator(AggregatorConfig config) : config_(std::move(config)) {
  for (const auto& child : config_.children) {
    sensors_.insert(sensors_.end(), child.sensors.begin(), child.sensors.end());
    open_streams_[child.id] = 0;
  }
  std::sort(sensors_.begin(), sensors_.end());
}

Expected<MergeAggregator> MergeAggregator::create(AggregatorConfig config) {
  if (!std::isfinite(config.deadline_ms) || config.deadline_ms <= 0.0) {
    return invalidArgument("aggregator deadline_ms must be a positive number of milliseconds, got " +
                           std::to_string(config.deadline_ms));
  }
  if (config.max_pending_epochs == 0) {
    return invalidArgument("aggregator max_pending_epochs must be at least 1");
  }
  std::set<std::uint32_t> children;
  std::set<std::uint32_t> sensors;
  for (const auto& child : config.children) {
    if (child.id == config.node) {
      return invalidArgument("aggregator " + nodeText(config.node) + " lists itself as a child");
    }
    if (!children.insert(child.id).second) {
      return invalidArgument("aggregator " + nodeText(config.node) + " lists child " + nodeText(child.id) + " twice");
    }
    // A sensor under two children would make a relayed chunk's stream ambiguous.
    for (const auto sensor : child.sensors) {
      if (!sensors.insert(sensor).second) {
        return invalidArgument("sensor " + nodeText(sensor) + " is listed under two children of aggregator " +
                               nodeText(config.node));
      }
    }
  }
  return MergeAggregator(std::move(config));
}

std::optional<std::uint32_t> MergeAggregator::childOf(std::uint32_t node) const {
  for (const auto& child : config_.children) {
    if (child.id == node) return child.id;
  }
  for (const auto& child : config_.children) {
    if (std::find(child.sensors.begin(), child.sensors.end(), node) != child.sensors.end()) return child.id;
  }
  return std::nullopt;
}

Expected<std::uint32_t> MergeAggregator::childConnected(std::uint32_t sender) {
  const auto child = childOf(sender);
  if (!child) {
    return invalidArgument(nodeText(sender) + " is neither a child of aggregator " + nodeText(config_.node) +
                           " nor a sensor below one; check the topology");
  }
  ++open_streams_[*child];
  return *child;
}

void MergeAggregator::childDisconnected(std::uint32_t child) {
  const auto it = open_streams_.find(child);
  if (it != open_streams_.end() && it->second > 0) --it->second;
}

std::size_t MergeAggregator::liveChildren() const {
  return static_cast<std::size_t>(
      std::count_if(open_streams_.begin(), open_streams_.end(), [](const auto& entry) { return entry.second > 0; }));
}

bool MergeAggregator::isClosed(std::uint64_t epoch) const {
  return closed_.contains(epoch) || (closed_floor_ && epoch <= *closed_floor_);
}

void MergeAggregator::close(std::uint64_t epoch) {
  closed_.insert(epoch);
  while (closed_.size() > kClosedHistory) {
    closed_floor_ = std::max(closed_floor_.value_or(0), *closed_.begin());
    closed_.erase(closed_.begin());
  }
}

MergeAggregator::Epoch& MergeAggregator::openEpoch(std::uint64_t epoch, std::int64_t now_ns) {
  auto it = pending_.find(epoch);
  if (it != pending_.end()) return it->second;
  // A child stuck far behind (or a flood of bogus epochs) must not grow memory without bound.
  while (pending_.size() >= config_.max_pending_epochs) {
    ++counters_.dropped_epochs;
    close(pending_.begin()->first);
    pending_.erase(pending_.begin());
  }
  Epoch fresh;
  fresh.first_arrival_ns = now_ns;
  return pending_.emplace(epoch, std::move(fresh)).first->second;
}

Expected<Arrival> MergeAggregator::onMap(const MapMessage& message, std::int64_t now_ns) {
  const MapHeader& header = message.header;
  if (config_.mode == Mode::kBaseline) {
    return invalidArgument(nodeText(header.node) + " sent a map for epoch " + std::to_string(header.epoch) +
                           ", but the cluster runs in baseline mode (points only)");
  }
  const bool direct_child = std::any_of(config_.children.begin(), config_.children.end(),
                                        [&](const ChildConfig& c) { return c.id == header.node; });
  if (!direct_child) {
    return invalidArgument("map from " + nodeText(header.node) + ", which is not a direct child of aggregator " +
                           nodeText(config_.node));
  }
  if (isClosed(header.epoch)) {
    ++counters_.late;
    return Arrival::kLate;
  }
  Epoch& epoch = openEpoch(header.epoch, now_ns);
  const auto start = std::chrono::steady_clock::now();
  MergeResult merged = merge(epoch.working, message.map);
  epoch.merge_seconds += secondsSince(start);
  epoch.working = std::move(merged.map);
  addStats(epoch.stats, merged.stats);

  epoch.reported_children.insert(header.node);
  epoch.contributing.insert(header.contributing_nodes.begin(), header.contributing_nodes.end());
  // An edge that leaves contributing_nodes empty still contributes its own scan (possibly empty).
  if (header.contributing_nodes.empty() && std::binary_search(sensors_.begin(), sensors_.end(), header.node)) {
    epoch.contributing.insert(header.node);
  }
  // Zero means "unknown" on the wire; it must not become the epoch's earliest timestamp.
  if (header.sensor_time_ns > 0) {
    epoch.sensor_time_ns = std::min(epoch.sensor_time_ns.value_or(header.sensor_time_ns), header.sensor_time_ns);
  }
  ++counters_.accepted;
  return Arrival::kAccepted;
}

Expected<PointsArrival> MergeAggregator::onPoints(PointChunk chunk, std::int64_t now_ns) {
  // Copies: the chunk is moved into storage below.
  const std::uint32_t node = chunk.header.node;
  const std::uint64_t epoch_id = chunk.header.epoch;
  const std::int64_t sensor_time_ns = chunk.header.sensor_time_ns;
  const std::string what = "point chunk " + std::to_string(chunk.chunk) + " of " + nodeText(node) +
                           " for epoch " + std::to_string(epoch_id);
  if (config_.mode == Mode::kMadc) {
    return invalidArgument(what + " arrived, but the cluster runs in madc mode (maps only)");
  }
  if (!std::binary_search(sensors_.begin(), sensors_.end(), node)) {
    return invalidArgument(what + ": the node is not a sensor below aggregator " + nodeText(config_.node));
  }
  if (chunk.chunk_count == 0 || chunk.chunk >= chunk.chunk_count) {
    return invalidArgument(what + ": chunk index must be below chunk_count " + std::to_string(chunk.chunk_count));
  }
  if (std::uint64_t{chunk.first_point} + chunk.points.size() > chunk.total_points) {
    return invalidArgument(what + ": points " + std::to_string(chunk.first_point) + " + " +
                           std::to_string(chunk.points.size()) + " exceed total_points " +
                           std::to_string(chunk.total_points));
  }
  if (config_.mode == Mode::kExt && chunk.labels.size() != chunk.points.size()) {
    return invalidArgument(what + ": ext mode needs one local label per point, got " +
                           std::to_string(chunk.labels.size()) + " labels for " +
                           std::to_string(chunk.points.size()) + " points");
  }

  if (!config_.is_root) {
    ++counters_.relayed;
    return PointsArrival{Arrival::kRelay, std::move(chunk)};
  }
  if (isClosed(epoch_id)) {
    ++counters_.late;
    return PointsArrival{Arrival::kLate, std::nullopt};
  }

  const auto existing = pending_.find(epoch_id);
  if (existing != pending_.end()) {
    const auto sensor = existing->second.points.find(node);
    if (sensor != existing->second.points.end() &&
        (sensor->second.chunk_count != chunk.chunk_count || sensor->second.total_points != chunk.total_points)) {
      return invalidArgument(what + ": chunk_count/total_points " + std::to_string(chunk.chunk_count) + "/" +
                             std::to_string(chunk.total_points) + " disagree with earlier chunks (" +
                             std::to_string(sensor->second.chunk_count) + "/" +
                             std::to_string(sensor->second.total_points) + ")");
    }
  }

  Epoch& epoch = openEpoch(epoch_id, now_ns);
  SensorPoints& sensor = epoch.points[node];
  sensor.chunk_count = chunk.chunk_count;
  sensor.total_points = chunk.total_points;
  if (sensor_time_ns > 0) {
    epoch.sensor_time_ns = std::min(epoch.sensor_time_ns.value_or(sensor_time_ns), sensor_time_ns);
  }
  // A re-sent chunk (after a reconnect) is the same chunk: keep the first copy.
  sensor.chunks.emplace(chunk.chunk, std::move(chunk));

  if (sensor.complete()) {
    // The chunks must tile the scan exactly, in index order, or per-point labels would be shifted.
    std::uint64_t next = 0;
    bool tiled = true;
    for (const auto& [index, part] : sensor.chunks) {
      tiled = tiled && part.first_point == next;
      next += part.points.size();
    }
    if (!tiled || next != sensor.total_points) {
      const std::string message = "point chunks of " + nodeText(node) + " for epoch " +
                                  std::to_string(epoch_id) + " do not tile its " +
                                  std::to_string(sensor.total_points) + " points; the scan is discarded";
      epoch.points.erase(node);
      // An epoch opened only by the discarded scan would otherwise emit an empty map later.
      if (epoch.points.empty() && epoch.reported_children.empty()) pending_.erase(epoch_id);
      return invalidArgument(message);
    }
  }
  ++counters_.accepted;
  return PointsArrival{Arrival::kAccepted, std::nullopt};
}

bool MergeAggregator::isComplete(const Epoch& epoch) const {
  const bool needs_maps = config_.mode != Mode::kBaseline;
  const bool needs_points = config_.is_root && config_.mode != Mode::kMadc;
  for (const auto& child : config_.children) {
    // A dead child is never waited for (DESIGN.md 2.2): neither its map nor its sensors' points.
    if (open_streams_.at(child.id) == 0) continue;
    if (needs_maps && !epoch.reported_children.contains(child.id)) return false;
    if (needs_points) {
      for (const auto sensor : child.sensors) {
        const auto it = epoch.points.find(sensor);
        if (it == epoch.points.end() || !it->second.complete()) return false;
      }
    }
  }
  return true;
}

std::vector<EpochOutput> MergeAggregator::poll(std::int64_t now_ns) {
  const auto deadline_ns = static_cast<std::int64_t>(std::llround(config_.deadline_ms * 1e6));
  std::vector<EpochOutput> outputs;
  for (auto it = pending_.begin(); it != pending_.end();) {
    const bool complete = isComplete(it->second);
    if (complete || now_ns >= it->second.first_arrival_ns + deadline_ns) {
      outputs.push_back(emit(it->first, it->second, complete));
      close(it->first);
      it = pending_.erase(it);
    } else {
      ++it;
    }
  }
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
  return header;
}

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

EpochOutput MergeAggregator::emit(std::uint64_t epoch_id, Epoch& epoch, bool complete) {
  ++counters_.emitted;
  EpochOutput out;
  out.epoch = epoch_id;
  out.complete = complete;
  out.stats = epoch.stats;
  out.merge_seconds = epoch.merge_seconds;

  if (!config_.is_root) {
    out.message = MapMessage{headerFor(epoch_id, epoch, epoch.contributing), std::move(epoch.working)};
    return out;
  }

  GlobalMapMessage global;
  global.mode = config_.mode;
  if (config_.mode == Mode::kBaseline) {
    // Central clustering of the union, exactly the clustering the edges would run.
    std::set<std::uint32_t> contributing;
    Cloud all;
    std::vector<std::pair<std::uint32_t, std::size_t>> extents;  // (sensor, point count), sensor order
    for (const auto& [sensor, points] : epoch.points) {
      if (!points.complete()) continue;  // a partial scan would be clustered wrongly near the gaps
      Cloud cloud = assemblePoints(points.chunks);
      contributing.insert(sensor);
      extents.emplace_back(sensor, cloud.size());
      all.insert(all.end(), cloud.begin(), cloud.end());
    }
    const auto start = std::chrono::steady_clock::now();
    const Clustering clustering = euclideanClusters(all, config_.madc.clustering);
    const auto summaries = summarizeClusters(all, clustering);
    std::vector<Ellipsoid> ellipsoids;
    ellipsoids.reserve(summaries.size());
    for (std::size_t k = 0; k < summaries.size(); ++k) {
      ellipsoids.push_back(ellipsoidFromSummary(summaries[k], {config_.node, epoch_id, static_cast<std::uint32_t>(k)},
                                                config_.madc.ellipsoidParams()));
    }
    // Ids (node, epoch, k) sort by k, so object k of the canonical map is central cluster k.
    global.map = localMap(std::move(ellipsoids));
    out.merge_seconds = secondsSince(start);
    out.stats = {};
    std::size_t offset = 0;
    for (const auto& [sensor, count] : extents) {
      NodeLabels labels{sensor, {}};
      labels.labels.assign(clustering.labels.begin() + static_cast<std::ptrdiff_t>(offset),
                           clustering.labels.begin() + static_cast<std::ptrdiff_t>(offset + count));
      global.point_labels.push_back(std::move(labels));
      offset += count;
    }
    global.header = headerFor(epoch_id, epoch, contributing);
  } else {
    global.map = std::move(epoch.working);
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
  }
  global.merge_seconds = out.merge_seconds;
  global.pairs_all = out.stats.pairs_all;
  global.pairs_tested = out.stats.pairs_tested;
  if (!latest_ || latest_->header.epoch <= epoch_id) latest_ = global;
  out.message = std::move(global);
  return out;
}

Expected<std::size_t> MergeAggregator::setGeofence(Geofence fence) {
  if (!config_.is_root) {
    return invalidArgument("geofences are kept by the root aggregator; " + nodeText(config_.node) + " is not the root");
  }
  if (const Status valid = validateGeofence(fence); !valid.ok()) return valid.error();
  const auto it = std::find_if(geofences_.begin(), geofences_.end(),
                               [&](const Geofence& g) { return g.name == fence.name; });
  if (it != geofences_.end()) {
    *it = std::move(fence);
  } else {
    geofences_.push_back(std::move(fence));
  }
  return geofences_.size();
}

Expected<GeofenceReport> MergeAggregator::queryGeofences(const std::string& name) const {
  if (!config_.is_root) {
    return invalidArgument("geofences are kept by the root aggregator; " + nodeText(config_.node) + " is not the root");
  }
  if (!name.empty() && std::none_of(geofences_.begin(), geofences_.end(),
                                    [&](const Geofence& g) { return g.name == name; })) {
    return notFound("no geofence named '" + name + "'");
  }
  GeofenceReport report;
  if (!latest_) return report;
  report.epoch = latest_->header.epoch;
  for (const auto& fence : geofences_) {
    if (!name.empty() && fence.name != name) continue;
    for (const auto& hit : intrusions(latest_->map, fence)) {
      const MapObject& object = latest_->map.objects[hit.object_index];
      GeofenceIntrusion intrusion{fence.name, hit.object_index, hit.containment, object.box, {}};
      for (const auto& e : object.ellipsoids) intrusion.ellipsoids.push_back(e.id);
      report.intrusions.push_back(std::move(intrusion));
    }
  }
  return report;
}

}  // namespace fogmap
