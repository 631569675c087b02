#include "services/merge_aggregator/aggregator_core.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <utility>

#include "common/clustering.hpp"

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
  const auto summaries = summarizeClusters(all, clustering);
  std::vector<Ellipsoid> ellipsoids;
  ellipsoids.reserve(summaries.size());
  for (std::size_t k = 0; k < summaries.size(); ++k) {
    ellipsoids.push_back(ellipsoidFromSummary(summaries[k],
                                              {job.node, global.header.epoch, static_cast<std::uint32_t>(k)},
                                              job.madc.ellipsoidParams()));
  }
  // Ids (node, epoch, k) sort by k, so object k of the canonical map is central cluster k.
  global.map = localMap(std::move(ellipsoids));
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

  global.map = epoch.working;
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
