#include "services/edge_cluster/edge_node.hpp"

#include <algorithm>
#include <chrono>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <utility>

#include "common/classify/cluster_views.hpp"
#include "common/config/displacement_node.hpp"
#include "common/perception/lidar_models.hpp"
#include "common/perception/virtual_lidar.hpp"

namespace fogmap {
namespace {

using SteadyClock = std::chrono::steady_clock;

double secondsSince(SteadyClock::time_point start) {
  return std::chrono::duration<double>(SteadyClock::now() - start).count();
}

// Packed xyz plus an ext label: the most a point costs on the wire.
constexpr std::size_t kMaxBytesPerPoint = 3 * sizeof(float) + sizeof(std::int32_t);

// Slices the points (and labels, when given) into chunks that tile [0, total) in order. An empty
// scan still gives one empty chunk, so the parent learns that this node reported the epoch.
std::vector<PointChunk> chunkPoints(const Cloud& points, std::span<const std::int32_t> labels, const MapHeader& header,
                                    std::size_t max_points_per_chunk) {
  const std::size_t total = points.size();
  const std::size_t count = std::max<std::size_t>(1, (total + max_points_per_chunk - 1) / max_points_per_chunk);
  std::vector<PointChunk> chunks(count);
  for (std::size_t c = 0; c < count; ++c) {
    const std::size_t first = c * max_points_per_chunk;
    const std::size_t last = std::min(total, first + max_points_per_chunk);
    PointChunk& chunk = chunks[c];
    chunk.header = header;
    chunk.chunk = static_cast<std::uint32_t>(c);
    chunk.chunk_count = static_cast<std::uint32_t>(count);
    chunk.first_point = static_cast<std::uint32_t>(first);
    chunk.total_points = static_cast<std::uint32_t>(total);
    chunk.points.reserve(last - first);
    for (std::size_t i = first; i < last; ++i) {
      const Point& p = points[i];
      chunk.points.push_back({p.x, p.y, p.z, 0.0F});  // intensity does not travel
    }
    if (!labels.empty()) chunk.labels.assign(labels.begin() + first, labels.begin() + last);
  }
  return chunks;
}

}  // namespace

Eigen::Isometry3d sensorToCommon(const SensorConfig& sensor) {
  if (!sensor.split) return sensor.pose;
  return sensor.pose * sectorPose(*sensor.split);
}

EdgeConfig edgeConfigFor(const TopologyConfig& topology, const NodeConfig& node) {
  EdgeConfig config;
  config.node = node.id;
  config.mode = topology.mode;
  config.madc = topology.madc;
  // The edge keeps its fragments (clusters below min_points): the root applies min_points to each
  // global object's points over all its sensors.
  config.madc.clustering.min_points = topology.madc.edgeMinPoints();
  config.preprocess = topology.preprocess;
  if (node.sensor) config.preprocess.sensor_to_common = sensorToCommon(*node.sensor);
  if (node.sensor && node.sensor->clustering == ClusteringMode::kSensor) {
    // The model was checked with the topology; were it unknown, the mode's checks refuse the empty
    // beam table on the first frame, naming it.
    const auto model = lidarModel(node.sensor->model);
    SensorLinks links;
    if (model) links.beams = beamTableOf(*model);
    links.sensor_pose = sensorToCommon(*node.sensor);
    config.madc.sensor_links = links;
  }
  config.ship_raw = topology.baseline_ships_raw;
  // Half the limit leaves room for the header and protobuf framing whatever the limit is.
  const std::size_t by_limit = topology.max_message_bytes / 2 / kMaxBytesPerPoint;
  config.max_points_per_chunk = std::clamp<std::size_t>(by_limit, 1, kDefaultMaxPointsPerChunk);
  config.name = node.name;
  if (node.displacement) config.displacement = node.displacement->params;
  config.boxes = topology.objects.boxes;
  config.box_min_points = topology.madc.clustering.min_points;
  return config;
}

Expected<std::shared_ptr<const ObjectClassifier>> loadClassifierOf(const TopologyConfig& topology) {
  if (!topology.objects.classifier) return std::shared_ptr<const ObjectClassifier>();
  auto loaded = ObjectClassifier::load(*topology.objects.classifier);
  if (!loaded) return invalidArgument("objects.classifier: " + loaded.error().message);
  return std::shared_ptr<const ObjectClassifier>(std::make_shared<ObjectClassifier>(std::move(*loaded)));
}

EdgeNode::EdgeNode(EdgeConfig config) : config_(std::move(config)), mapper_(config_.madc) {
  // Zero would mean "no chunk can hold a point"; one point a chunk is the least that works.
  config_.max_points_per_chunk = std::max<std::size_t>(config_.max_points_per_chunk, 1);
  if (config_.displacement) detector_.emplace(tracking::DisplacementDetector::create(*config_.displacement));
}

Expected<std::optional<tracking::CentroidFrame>> EdgeNode::displacementOf(const Cloud& cleaned, std::uint64_t frame,
                                                                          std::int64_t sensor_time_ns) {
  Expected<tracking::DisplacementDetector>& detector = *detector_;
  if (!detector) return detector.error();
  tracking::DisplacementResult found = detector->push(cleaned);
  const bool first = !has_previous_scan_;
  has_previous_scan_ = true;
  if (first) return std::optional<tracking::CentroidFrame>{};
  tracking::CentroidFrame centroids;
  centroids.edge = config_.name;
  centroids.epoch = frame;
  centroids.time_ns = sensor_time_ns;
  centroids.sensor_position = config_.preprocess.sensor_to_common.translation();
  centroids.centroids = std::move(found.centroids);
  return std::optional<tracking::CentroidFrame>(std::move(centroids));
}

Expected<Cloud> EdgeNode::preprocessScan(const Cloud& scan) const { return fogmap::preprocessScan(scan, config_.preprocess); }

Expected<EdgeOutput> EdgeNode::processFrame(const Cloud& scan_in_sensor_frame, std::uint64_t frame,
                                            std::int64_t sensor_time_ns) {
  EdgeOutput output;
  output.points_in = scan_in_sensor_frame.size();

  const SteadyClock::time_point preprocess_start = SteadyClock::now();
  // A baseline that ships its scans whole only moves them into the common frame.
  PreprocessConfig move_only;
  move_only.sensor_to_common = config_.preprocess.sensor_to_common;
  const bool whole = config_.mode == Mode::kBaseline && config_.ship_raw;
  Expected<Cloud> preprocessed = whole ? preprocess(scan_in_sensor_frame, move_only) : preprocessScan(scan_in_sensor_frame);
  if (!preprocessed) return preprocessed.error();
  const Cloud& points = *preprocessed;
  output.preprocess_seconds = secondsSince(preprocess_start);
  output.points_out = points.size();
  // The wire counts points in uint32 (first_point, total_points).
  if (points.size() > std::numeric_limits<std::uint32_t>::max()) {
    return invalidArgument("frame " + std::to_string(frame) + " has " + std::to_string(points.size()) +
                           " points after pre-processing, more than a point chunk can index (2^32 - 1)");
  }

  if (detector_) {
    const SteadyClock::time_point displacement_start = SteadyClock::now();
    // A baseline that ships raw scans cleans a copy for the detector: ground flicker and what lies
    // outside the crop would be displacement.
    std::optional<Cloud> cleaned_copy;
    if (whole) {
      Expected<Cloud> cleaned = preprocessScan(scan_in_sensor_frame);
      if (!cleaned) return cleaned.error();
      cleaned_copy = std::move(*cleaned);
    }
    auto centroids = displacementOf(cleaned_copy ? *cleaned_copy : points, frame, sensor_time_ns);
    if (!centroids) return centroids.error();
    output.centroids = std::move(*centroids);
    output.displacement_seconds = secondsSince(displacement_start);
  }

  MapHeader header;
  header.node = config_.node;
  header.epoch = frame;
  header.sensor_time_ns = sensor_time_ns;
  header.contributing_nodes = {config_.node};

  if (config_.mode == Mode::kBaseline) {
    output.chunks = chunkPoints(points, {}, header, config_.max_points_per_chunk);
    return output;
  }

  const SteadyClock::time_point clustering_start = SteadyClock::now();
  auto clustered = mapper_.cluster(points);
  if (!clustered) return clustered.error();
  Clustering clustering = std::move(*clustered);
  std::vector<std::optional<ClusterView>> views;  // with boxes: per cluster
  if (config_.boxes) {
    // A vehicle seen in pieces is one cluster before it is summarised (joinedVehicleParts).
    auto found = sensorObjects(points, std::move(clustering), config_.preprocess.sensor_to_common.translation(),
                               config_.classifier.get(), config_.box_min_points);
    if (!found) return found.error();
    output.vehicle_parts_joined = found->parts_joined;
    clustering = std::move(found->clustering);
    views = std::move(found->views);
  }
  Map map = mapper_.summarise(points, clustering, config_.node, frame);
  if (config_.boxes) attachViews(views, map);
  output.clustering_seconds = secondsSince(clustering_start);
  output.clusters = static_cast<std::size_t>(clustering.cluster_count);
  output.map = MapMessage{header, std::move(map)};
  if (config_.mode == Mode::kExt) {
    output.chunks = chunkPoints(points, clustering.labels, header, config_.max_points_per_chunk);
  }
  return output;
}

EdgeOutput EdgeNode::failedFrame(std::uint64_t frame) const {
  MapHeader header;
  header.node = config_.node;
  header.epoch = frame;
  header.failed_nodes = {config_.node};
  EdgeOutput output;
  if (config_.mode == Mode::kBaseline) {
    output.chunks = chunkPoints(Cloud{}, {}, header, config_.max_points_per_chunk);
  } else {
    // Ext ships no chunk either: points of a failed frame do not exist, and the map alone tells
    // the parent that this node reported the epoch.
    output.map = MapMessage{std::move(header), Map{}};
  }
  return output;
}

}  // namespace fogmap
