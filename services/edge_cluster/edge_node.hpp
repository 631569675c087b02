#pragma once
// The edge-cluster core (DESIGN.md 2.1): one scan in the sensor frame in, what the edge ships to
// its parent out: a local map of ellipsoids (MAD-C), the pre-processed points in chunks
// (baseline), or both with local cluster labels (MAD-C-ext); and, when the topology gives the edge
// a displacement section, the displacement centroids of the cleaned scan for its tracker
// (DESIGN.md 2.4). Domain types only; no gRPC.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "common/classify/object_classifier.hpp"
#include "common/geometry/cloud.hpp"
#include "common/perception/madc.hpp"
#include "common/io/messages.hpp"
#include "common/perception/preprocess.hpp"
#include "common/base/status.hpp"
#include "common/config/topology.hpp"
#include "common/tracking/displacement.hpp"

namespace fogmap {

// 65,536 points are 786 KB of packed xyz (1 MiB with ext labels): far below gRPC's limits.
inline constexpr std::size_t kDefaultMaxPointsPerChunk = 65536;

struct EdgeConfig {
  std::uint32_t node = 0;
  Mode mode = Mode::kMadc;
  MadcParams madc;
  PreprocessConfig preprocess;  // sensor_to_common = sensorToCommon(sensor)
  std::size_t max_points_per_chunk = kDefaultMaxPointsPerChunk;
  bool ship_raw = false;        // baseline: ship the scan moved to the common frame, nothing cut
  std::string name;             // the node's name: centroid frames carry it
  // Run the displacement detector on every cleaned scan (common frame) and put its centroids in
  // the output; none when empty.
  std::optional<tracking::DisplacementParams> displacement;
  // The topology's `objects:`: each local cluster of at least box_min_points points gets its
  // oriented box (fitted with the sensor's position) and, with a classifier, its LiDAR class, on its
  // ellipsoid. Fragments (smaller clusters) get neither.
  bool boxes = false;
  std::size_t box_min_points = 10;
  std::shared_ptr<const ObjectClassifier> classifier{};  // loadClassifierOf
};

// What one frame produced, and what it cost.
struct EdgeOutput {
  std::optional<MapMessage> map;  // madc and ext modes
  std::vector<PointChunk> chunks;  // baseline and ext modes; at least one chunk (maybe empty)
  std::size_t points_in = 0;       // points of the scan
  std::size_t points_out = 0;      // points left after pre-processing (clustered or shipped)
  std::size_t clusters = 0;        // local clusters = ellipsoids (0 in baseline mode)
  // With boxes: clusters joined into others as parts of one vehicle (joinedVehicleParts).
  std::size_t vehicle_parts_joined = 0;
  double preprocess_seconds = 0.0;
  double clustering_seconds = 0.0;  // clustering and ellipsoids (0 in baseline mode)
  // With displacement: the scan's centroids for the tracker, from the second scan on (the first
  // has no previous scan to be compared with: all of it would be displacement).
  std::optional<tracking::CentroidFrame> centroids;
  std::optional<double> displacement_seconds;  // with displacement: the detector's time on this scan
};

// The sensor's pose in the common frame: its pose composed with the sector's rotation when the
// sensor is a virtual LiDAR (the scan source returns sector points in the sector's frame).
Eigen::Isometry3d sensorToCommon(const SensorConfig& sensor);

// The edge configuration of `node` (an edge with a sensor) in `topology`: the topology's mode,
// MAD-C and pre-processing settings with the node's pose, chunks of at most
// kDefaultMaxPointsPerChunk points that also stay below half the message limit, the node's name
// and its displacement settings.
EdgeConfig edgeConfigFor(const TopologyConfig& topology, const NodeConfig& node);

// The classifier the topology's `objects.classifier` names, loaded; none without one. Errors naming
// the file when it is missing or not a model trained on today's features.
Expected<std::shared_ptr<const ObjectClassifier>> loadClassifierOf(const TopologyConfig& topology);

class EdgeNode {
 public:
  explicit EdgeNode(EdgeConfig config);

  // Pre-processes the scan (transform to the common frame, crop, voxel, ground) and produces the
  // mode's output for epoch `frame`. A scan with nothing left (fewer than 3 points to fit the
  // ground on) gives an empty map and one empty chunk. With displacement, the cleaned scan (in a
  // baseline that ships raw scans, cleaned for this alone) also goes through the detector, which
  // keeps it as the previous scan: feed the scans in order, each once. Errors on invalid
  // pre-processing or displacement settings, when no ground plane is found, or on more than
  // 2^32 - 1 points.
  Expected<EdgeOutput> processFrame(const Cloud& scan_in_sensor_frame, std::uint64_t frame, std::int64_t sensor_time_ns);

  // What the edge ships for epoch `frame` when its scan could not be read or processed, so that
  // the parent need not wait out its deadline: an empty map (madc, ext) or one empty chunk
  // (baseline) whose header lists this node in failed_nodes and in no contributing_nodes, with
  // sensor time 0 (no data: unknown).
  EdgeOutput failedFrame(std::uint64_t frame) const;

  const EdgeConfig& config() const { return config_; }

 private:
  Expected<Cloud> preprocessScan(const Cloud& scan) const;
  // The displacement centroids of the cleaned scan (empty for the first scan), and the time taken.
  Expected<std::optional<tracking::CentroidFrame>> displacementOf(const Cloud& cleaned, std::uint64_t frame,
                                                                 std::int64_t sensor_time_ns);

  EdgeConfig config_;
  LocalMapper mapper_;  // config_.madc, prepared once
  std::optional<Expected<tracking::DisplacementDetector>> detector_;  // with displacement
  bool has_previous_scan_ = false;
};

}  // namespace fogmap
