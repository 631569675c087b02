// MergeAggregator's collecting half: children and their streams, admission, MERGE into the
// epochs (and the baseline root's central clustering), the root's geofences. aggregator_emit.cpp
// emits the epochs.
#include "services/merge_aggregator/aggregator_core.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

#include "common/perception/clustering.hpp"
#include "common/perception/madc.hpp"

namespace fogmap {
namespace {

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string nodeText(std::uint32_t node) { return "node " + std::to_string(node); }

std::string msText(std::int64_t ns) { return std::to_string(ns / 1'000'000) + " ms"; }

void addStats(MergeStats& total, const MergeStats& step) {
  total.pairs_all += step.pairs_all;
  total.pairs_tested += step.pairs_tested;
  total.pairs_pruned += step.pairs_pruned;
}

bool sameGeometry(const Ellipsoid& a, const Ellipsoid& b) {
  return a.center == b.center && a.shape == b.shape && a.point_count == b.point_count;
}

}  // namespace

std::uint64_t AggregatorCounters::refusedTotal() const {
  std::uint64_t total = 0;
  for (const auto& [reason, count] : refused) total += count;
  return total;
}

Expected<AggregatorConfig> aggregatorConfigFor(const TopologyConfig& topology, const std::string& name) {
  const NodeConfig* self = topology.find(name);
  if (self == nullptr || self->role != Role::kAggregator) {
    return invalidArgument("the topology '" + topology.name + "' has no aggregator named '" + name + "'");
  }
  AggregatorConfig config;
  config.node = self->id;
  config.mode = topology.mode;
  config.is_root = self->parent.empty();
  config.levels = topology.aggregatorLevels(self->name);
  config.period_ms = topology.period_ms;
  config.deadline_ms = topology.deadline_ms;
  config.admission = topology.admission;
  config.madc = topology.madc;
  if (topology.mode == Mode::kBaseline && topology.baseline_ships_raw && config.is_root) {
    config.preprocess = topology.preprocess;
    config.preprocess->sensor_to_common = Eigen::Isometry3d::Identity();
  }
  for (const NodeConfig* child : topology.children(self->name)) {
    config.children.push_back({child->id, topology.sensorsBelow(child->name), child->name});
  }
  return config;
}

GlobalMapMessage clusterCentrally(BaselineJob job) {
  GlobalMapMessage global = std::move(job.message);
  const auto start = std::chrono::steady_clock::now();
  if (job.preprocess) {
    for (auto& [sensor, cloud] : job.scans) {
      // A scan that cannot be pre-processed (a degenerate ground fit) contributes no points, as
      // its edge would have failed the frame.
      Expected<Cloud> prepared = preprocessScan(cloud, *job.preprocess);
      cloud = prepared ? std::move(*prepared) : Cloud{};
    }
  }
  Cloud all;
  for (const auto& [sensor, cloud] : job.scans) all.insert(all.end(), cloud.begin(), cloud.end());
  const Clustering clustering = euclideanClusters(all, job.madc.clustering);
  // Ids (node, epoch, k) sort by k, so object k of the canonical map is central cluster k.
  global.map = localMap(clusterEllipsoids(all, clustering, job.node, global.header.epoch, job.madc.ellipsoidParams()));
  global.merge_seconds = secondsSince(start);
  global.pairs_all = 0;
  global.pairs_tested = 0;
  std::size_t offset = 0;
  for (const auto& [sensor, cloud] : job.scans) {
    NodeLabels labels{sensor, {}};
    labels.labels.assign(clustering.labels.begin() + static_cast<std::ptrdiff_t>(offset),
                         clustering.labels.begin() + static_cast<std::ptrdiff_t>(offset + cloud.size()));
    global.point_labels.push_back(std::move(labels));
    offset += cloud.size();
  }
  return global;
}

MergeAggregator::MergeAggregator(AggregatorConfig config, EpochSchedule schedule)
    : config_(std::move(config)), schedule_(schedule) {
  for (const auto& child : config_.children) {
    sensors_.insert(sensors_.end(), child.sensors.begin(), child.sensors.end());
    Child state;
    state.name = child.name;
    state.sensors = child.sensors;
    std::sort(state.sensors.begin(), state.sensors.end());
    children_.emplace(child.id, std::move(state));
  }
  std::sort(sensors_.begin(), sensors_.end());
}

Expected<MergeAggregator> MergeAggregator::create(AggregatorConfig config) {
  auto schedule = EpochSchedule::create(config.period_ms, config.deadline_ms);
  if (!schedule) return invalidArgument("aggregator " + nodeText(config.node) + ": " + schedule.error().message);
  if (const Status limits = validateAdmissionLimits(config.admission); !limits.ok()) return limits.error();
  if (config.max_pending_epochs == 0) {
    return invalidArgument("aggregator max_pending_epochs must be at least 1");
  }
  if (config.levels < 1) return invalidArgument("aggregator levels must be at least 1");
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
  return MergeAggregator(std::move(config), *schedule);
}

std::optional<std::uint32_t> MergeAggregator::childOf(std::uint32_t node) const {
  if (children_.contains(node)) return node;
  for (const auto& [id, child] : children_) {
    if (std::binary_search(child.sensors.begin(), child.sensors.end(), node)) return id;
  }
  return std::nullopt;
}

Expected<std::uint32_t> MergeAggregator::childConnected(std::uint32_t sender) {
  const auto child = childOf(sender);
  if (!child) {
    ++counters_.refused[Refusal::kUnknownNode];
    return invalidArgument(nodeText(sender) + " is neither a child of aggregator " + nodeText(config_.node) +
                           " nor a sensor below one; check the topology");
  }
  Child& state = children_.at(*child);
  ++state.open_streams;
  state.disconnected_ns.reset();
  return *child;
}

std::optional<std::uint32_t> MergeAggregator::peerConnected(const std::string& certificate_name) {
  if (certificate_name.empty()) return std::nullopt;
  for (auto& [id, child] : children_) {
    if (child.name != certificate_name) continue;
    ++child.open_streams;
    child.disconnected_ns.reset();
    return id;
  }
  return std::nullopt;
}

void MergeAggregator::childDisconnected(std::uint32_t child, std::int64_t now_ns) {
  const auto it = children_.find(child);
  if (it == children_.end() || it->second.open_streams == 0) return;
  if (--it->second.open_streams == 0) it->second.disconnected_ns = now_ns;
}

bool MergeAggregator::isLive(const Child& child, std::int64_t now_ns) const {
  if (child.open_streams > 0) return true;
  // A child that never connected is not waited for; one that just lost its stream is, for a
  // grace of one period and one deadline (it reconnects and re-sends what was not answered).
  return child.disconnected_ns && now_ns - *child.disconnected_ns < schedule_.periodNs() + schedule_.deadlineNs();
}

std::size_t MergeAggregator::liveChildren(std::int64_t now_ns) const {
  return static_cast<std::size_t>(std::count_if(children_.begin(), children_.end(),
                                                [&](const auto& entry) { return isLive(entry.second, now_ns); }));
}

std::int64_t MergeAggregator::windowNs() const {
  return static_cast<std::int64_t>(std::llround(config_.admission.window_periods *
                                                static_cast<double>(schedule_.periodNs())));
}

std::size_t MergeAggregator::windowEpochs() const {
  const std::int64_t span = 2 * windowNs() + config_.levels * schedule_.deadlineNs();
  return static_cast<std::size_t>(span / schedule_.periodNs()) + 1;
}

std::size_t MergeAggregator::rememberedUploads() const {
  std::size_t total = 0;
  for (const auto& [id, child] : children_) total += child.uploads.size();
  return total;
}

Outcome MergeAggregator::refusedOutcome(Refused refused) {
  ++counters_.refused[refused.reason];
  Outcome outcome;
  outcome.refused = std::move(refused);
  return outcome;
}

Refused MergeAggregator::refuse(Refusal reason, std::string message) {
  ++counters_.refused[reason];
  return Refused{reason, std::move(message)};
}

bool MergeAggregator::speaksFor(const Child& child, std::uint32_t sensor) const {
  return std::binary_search(child.sensors.begin(), child.sensors.end(), sensor);
}

std::optional<Refused> MergeAggregator::admit(std::uint32_t child_id, const UploadKey& key, const MapHeader& header,
                                              std::size_t wire_bytes, std::int64_t now_ns, const std::string& what,
                                              bool& duplicate) {
  duplicate = false;
  // Emitted epochs that left the window are dropped here too, not only in poll: what the core
  // holds stays bounded by the window even between polls.
  forgetOldEpochs(now_ns);
  const auto child = children_.find(child_id);
  if (child == children_.end()) {
    return Refused{Refusal::kUnknownNode, what + ": " + nodeText(child_id) + " is not a child of aggregator " +
                                              nodeText(config_.node)};
  }
  if (wire_bytes > config_.admission.max_map_bytes) {
    return Refused{Refusal::kTooLarge, what + " has " + std::to_string(wire_bytes) + " bytes, more than the bound of " +
                                           std::to_string(config_.admission.max_map_bytes) +
                                           " (admission max_map_bytes)"};
  }
  // The window bounds how far an epoch may be from this aggregator's clock: no map can open an
  // epoch ahead of time, and the epochs remembered (open, emitted, closed) stay few.
  const std::int64_t window = windowNs();
  const std::int64_t start = schedule_.startNs(header.epoch);
  if (start > now_ns && start - now_ns > window) {
    return Refused{Refusal::kClockSkew, what + ": the epoch starts " + msText(start - now_ns) +
                                            " ahead of aggregator " + nodeText(config_.node) +
                                            "'s clock, beyond the admission window of " + msText(window) +
                                            " (check the sender's clock)"};
  }
  const std::int64_t deadline = schedule_.deadlineNs(header.epoch, config_.levels);
  if (deadline < now_ns && now_ns - deadline > window) {
    return Refused{Refusal::kClockSkew, what + ": the epoch's deadline passed " + msText(now_ns - deadline) +
                                            " ago, beyond the admission window of " + msText(window) +
                                            " (a stale re-send, or the sender's clock is behind)"};
  }
  const auto seen = child->second.uploads.find(key.sequence);
  if (seen != child->second.uploads.end()) {
    if (seen->second != key.fingerprint) {
      return Refused{Refusal::kSequenceConflict, what + ": sequence " + std::to_string(key.sequence) +
                                                     " was already applied with other content"};
    }
    duplicate = true;
  }
  return std::nullopt;
}

void MergeAggregator::rememberUpload(std::uint32_t child_id, const UploadKey& key) {
  auto& uploads = children_.at(child_id).uploads;
  uploads.emplace(key.sequence, key.fingerprint);
  while (uploads.size() > kUploadHistory) uploads.erase(uploads.begin());
}

MergeAggregator::Epoch& MergeAggregator::openEpoch(std::uint64_t epoch) {
  auto it = pending_.find(epoch);
  if (it != pending_.end()) return it->second;
  // The admission window already bounds the open epochs; this is the last line of defence.
  while (pending_.size() >= config_.max_pending_epochs) {
    ++counters_.dropped_epochs;
    pending_.erase(pending_.begin());
  }
  return pending_.emplace(epoch, Epoch{}).first->second;
}

std::optional<Refused> MergeAggregator::checkEllipsoids(std::uint32_t child_id, const MapMessage& message,
                                                        const Epoch* epoch, const std::string& what) const {
  const Child& child = children_.at(child_id);
  std::map<std::uint32_t, std::size_t> added;  // ellipsoids new to the epoch, per sensor
  for (const auto& object : message.map.objects) {
    for (const auto& e : object.ellipsoids) {
      if (!speaksFor(child, e.id.node)) {
        return Refused{Refusal::kForgedNode, what + ": ellipsoid " + toString(e.id) + " names " +
                                                 nodeText(e.id.node) + ", which is not a sensor below " +
                                                 nodeText(child_id)};
      }
      const Ellipsoid* known = nullptr;
      if (epoch != nullptr) {
        const auto it = epoch->ellipsoids.find(e.id);
        if (it != epoch->ellipsoids.end()) known = &it->second;
      }
      if (known == nullptr) {
        ++added[e.id.node];
      } else if (!sameGeometry(*known, e)) {
        return Refused{Refusal::kEllipsoidConflict,
                       what + ": ellipsoid " + toString(e.id) + " was already merged with other geometry"};
      }
    }
  }
  // One sensor's map of an epoch is bounded like one upload: more distinct ids for it, sent as
  // many maps under other sequences, would grow the epoch (and every MERGE into it) without end.
  for (const auto& [sensor, count] : added) {
    std::size_t held = 0;
    if (epoch != nullptr) {
      const auto it = epoch->ellipsoids_of.find(sensor);
      if (it != epoch->ellipsoids_of.end()) held = it->second;
    }
    if (held + count > config_.admission.max_ellipsoids_per_map) {
      return Refused{Refusal::kTooLarge, what + " would bring the ellipsoids of " + nodeText(sensor) +
                                             " in the epoch to " + std::to_string(held + count) +
                                             ", more than the bound of " +
                                             std::to_string(config_.admission.max_ellipsoids_per_map) +
                                             " (admission max_ellipsoids_per_map)"};
    }
  }
  return std::nullopt;
}

void MergeAggregator::mergeInto(Epoch& epoch, const MapMessage& message) {
  const MapHeader& header = message.header;
  const auto start = std::chrono::steady_clock::now();
  MergeResult merged = merge(epoch.working, message.map);
  epoch.merge_seconds += secondsSince(start);
  epoch.working = std::move(merged.map);
  addStats(epoch.stats, merged.stats);
  for (const auto& object : message.map.objects) {
    for (const auto& e : object.ellipsoids) {
      if (epoch.ellipsoids.emplace(e.id, e).second) ++epoch.ellipsoids_of[e.id.node];
    }
  }
  epoch.reported_children.insert(header.node);
  epoch.contributing.insert(header.contributing_nodes.begin(), header.contributing_nodes.end());
  epoch.failed.insert(header.failed_nodes.begin(), header.failed_nodes.end());
  // An edge that leaves contributing_nodes empty still contributes its own scan (possibly empty),
  // unless it reported the frame as failed.
  if (header.contributing_nodes.empty() && header.failed_nodes.empty() &&
      std::binary_search(sensors_.begin(), sensors_.end(), header.node)) {
    epoch.contributing.insert(header.node);
  }
  // Zero means "unknown" on the wire; it must not become the epoch's earliest timestamp.
  if (header.sensor_time_ns > 0) {
    epoch.sensor_time_ns = std::min(epoch.sensor_time_ns.value_or(header.sensor_time_ns), header.sensor_time_ns);
  }
}

Outcome MergeAggregator::onMap(std::uint32_t child_id, const UploadKey& key, const MapMessage& message,
                               std::size_t wire_bytes, std::int64_t now_ns) {
  const MapHeader& header = message.header;
  const std::string what = "map of " + nodeText(header.node) + " for epoch " + std::to_string(header.epoch);
  if (config_.mode == Mode::kBaseline) {
    return refusedOutcome({Refusal::kWrongMode, what + ", but the cluster runs in baseline mode (points only)"});
  }
  bool duplicate = false;
  if (auto refused = admit(child_id, key, header, wire_bytes, now_ns, what, duplicate)) {
    return refusedOutcome(std::move(*refused));
  }
  const Child& child = children_.at(child_id);
  if (header.node != child_id) {
    return refusedOutcome({Refusal::kForgedNode, what + " arrived on the stream of " + nodeText(child_id) +
                                                     "; a stream speaks for one node only"});
  }
  for (const auto* nodes : {&header.contributing_nodes, &header.failed_nodes}) {
    for (const auto sensor : *nodes) {
      if (!speaksFor(child, sensor)) {
        return refusedOutcome({Refusal::kForgedNode, what + " speaks for " + nodeText(sensor) +
                                                         ", which is not a sensor below " + nodeText(child_id)});
      }
    }
  }
  auto open = pending_.find(header.epoch);
  auto retained = emitted_.find(header.epoch);
  if (duplicate) {
    ++counters_.duplicates;
    return Outcome{retained != emitted_.end() ? Arrival::kLate : Arrival::kAccepted, std::nullopt, std::nullopt};
  }
  if (auto refused = checkMapBounds(message.map, config_.admission, what)) return refusedOutcome(std::move(*refused));
  Epoch* known = open != pending_.end() ? &open->second : retained != emitted_.end() ? &retained->second : nullptr;
  if (auto refused = checkEllipsoids(child_id, message, known, what)) return refusedOutcome(std::move(*refused));

  children_.at(child_id).dropped = header.dropped_uploads;
  rememberUpload(child_id, key);
  if (retained != emitted_.end()) {
    mergeInto(retained->second, message);
    retained->second.dirty = true;
    ++counters_.late;
    return Outcome{Arrival::kLate, std::nullopt, std::nullopt};
  }
  mergeInto(openEpoch(header.epoch), message);
  ++counters_.accepted;
  return Outcome{};
}

Outcome MergeAggregator::onPoints(std::uint32_t child_id, const UploadKey& key, PointChunk chunk,
                                  std::size_t wire_bytes, std::int64_t now_ns) {
  // Copies: the chunk is moved into storage below.
  const std::uint32_t node = chunk.header.node;
  const std::uint64_t epoch_id = chunk.header.epoch;
  const std::string what = "point chunk " + std::to_string(chunk.chunk) + " of " + nodeText(node) + " for epoch " +
                           std::to_string(epoch_id);
  if (config_.mode == Mode::kMadc) {
    return refusedOutcome({Refusal::kWrongMode, what + " arrived, but the cluster runs in madc mode (maps only)"});
  }
  bool duplicate = false;
  if (auto refused = admit(child_id, key, chunk.header, wire_bytes, now_ns, what, duplicate)) {
    return refusedOutcome(std::move(*refused));
  }
  const Child& child = children_.at(child_id);
  if (!speaksFor(child, node)) {
    return refusedOutcome({Refusal::kForgedNode, what + " arrived on the stream of " + nodeText(child_id) +
                                                     ", but that node is not a sensor below it"});
  }
  if (chunk.chunk_count == 0 || chunk.chunk >= chunk.chunk_count) {
    return refusedOutcome({Refusal::kMalformed, what + ": chunk index must be below chunk_count " +
                                                    std::to_string(chunk.chunk_count)});
  }
  // The edge cuts a scan into chunks of at least one point each (one empty chunk for an empty
  // scan): more chunks, or empty ones, would only cost memory.
  if (chunk.chunk_count > std::max<std::uint32_t>(1, chunk.total_points) ||
      (chunk.total_points > 0 && chunk.points.empty())) {
    return refusedOutcome({Refusal::kMalformed, what + ": " + std::to_string(chunk.chunk_count) + " chunks of " +
                                                    std::to_string(chunk.total_points) +
                                                    " points; a chunk of a non-empty scan carries at least one point"});
  }
  if (std::uint64_t{chunk.first_point} + chunk.points.size() > chunk.total_points) {
    return refusedOutcome({Refusal::kMalformed, what + ": points " + std::to_string(chunk.first_point) + " + " +
                                                    std::to_string(chunk.points.size()) + " exceed total_points " +
                                                    std::to_string(chunk.total_points)});
  }
  if (config_.mode == Mode::kExt && chunk.labels.size() != chunk.points.size()) {
    return refusedOutcome({Refusal::kMalformed, what + ": ext mode needs one local label per point, got " +
                                                    std::to_string(chunk.labels.size()) + " labels for " +
                                                    std::to_string(chunk.points.size()) + " points"});
  }
  for (const auto& p : chunk.points) {
    if (!(std::abs(p.x) <= config_.admission.world_extent_m && std::abs(p.y) <= config_.admission.world_extent_m &&
          std::abs(p.z) <= config_.admission.world_extent_m)) {
      return refusedOutcome({Refusal::kOutOfWorld, what + ": a point lies outside the world extent of " +
                                                       std::to_string(config_.admission.world_extent_m) + " m"});
    }
  }

  if (!config_.is_root) {
    // Relayed again even when re-sent: the child is answered once the next hop answers.
    rememberUpload(child_id, key);
    ++counters_.relayed;
    return Outcome{Arrival::kRelay, std::nullopt, std::move(chunk)};
  }
  auto open = pending_.find(epoch_id);
  auto retained = emitted_.find(epoch_id);
  if (duplicate) {
    ++counters_.duplicates;
    return Outcome{retained != emitted_.end() ? Arrival::kLate : Arrival::kAccepted, std::nullopt, std::nullopt};
  }
  Epoch* known = open != pending_.end() ? &open->second : retained != emitted_.end() ? &retained->second : nullptr;
  if (known != nullptr) {
    const auto sensor = known->points.find(node);
    if (sensor != known->points.end() &&
        (sensor->second.chunk_count != chunk.chunk_count || sensor->second.total_points != chunk.total_points)) {
      return refusedOutcome({Refusal::kInconsistentChunks,
                             what + ": chunk_count/total_points " + std::to_string(chunk.chunk_count) + "/" +
                                 std::to_string(chunk.total_points) + " disagree with earlier chunks (" +
                                 std::to_string(sensor->second.chunk_count) + "/" +
                                 std::to_string(sensor->second.total_points) + ")"});
    }
    if (sensor != known->points.end()) {
      const auto same = sensor->second.chunks.find(chunk.chunk);
      if (same != sensor->second.chunks.end() && !(same->second == chunk)) {
        return refusedOutcome({Refusal::kInconsistentChunks, what + " was already stored with other content"});
      }
      // Chunks that tile the scan hold total_points points together; more can never tile it.
      if (same == sensor->second.chunks.end() &&
          sensor->second.stored_points + chunk.points.size() > sensor->second.total_points) {
        return refusedOutcome({Refusal::kInconsistentChunks,
                               what + ": its points and those stored before exceed the scan's " +
                                   std::to_string(sensor->second.total_points) + " points"});
      }
    }
  }

  const bool late = retained != emitted_.end();
  Epoch& epoch = late ? retained->second : openEpoch(epoch_id);
  SensorPoints& sensor = epoch.points[node];
  sensor.chunk_count = chunk.chunk_count;
  sensor.total_points = chunk.total_points;
  if (chunk.header.sensor_time_ns > 0) {
    epoch.sensor_time_ns =
        std::min(epoch.sensor_time_ns.value_or(chunk.header.sensor_time_ns), chunk.header.sensor_time_ns);
  }
  epoch.failed.insert(chunk.header.failed_nodes.begin(), chunk.header.failed_nodes.end());
  const std::size_t chunk_points = chunk.points.size();
  if (sensor.chunks.emplace(chunk.chunk, std::move(chunk)).second) sensor.stored_points += chunk_points;

  if (sensor.complete()) {
    // The chunks must tile the scan exactly, in index order, or per-point labels would be shifted.
    std::uint64_t next = 0;
    bool tiled = true;
    for (const auto& [index, part] : sensor.chunks) {
      tiled = tiled && part.first_point == next;
      next += part.points.size();
    }
    if (!tiled || next != sensor.total_points) {
      const std::string message = "point chunks of " + nodeText(node) + " for epoch " + std::to_string(epoch_id) +
                                  " do not tile its " + std::to_string(sensor.total_points) +
                                  " points; the scan is discarded";
      epoch.points.erase(node);
      // An epoch opened only by the discarded scan would otherwise emit an empty map later.
      if (!late && epoch.points.empty() && epoch.reported_children.empty()) pending_.erase(epoch_id);
      return refusedOutcome({Refusal::kInconsistentChunks, message});
    }
  }
  rememberUpload(child_id, key);
  if (late) {
    epoch.dirty = true;
    ++counters_.late;
    return Outcome{Arrival::kLate, std::nullopt, std::nullopt};
  }
  ++counters_.accepted;
  return Outcome{};
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
  } else if (geofences_.size() >= kMaxGeofences) {
    return resourceExhausted("the root keeps at most " + std::to_string(kMaxGeofences) +
                             " geofences; replace one (same name) instead of adding '" + fence.name + "'");
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
