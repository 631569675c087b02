#pragma once
// The topology file (YAML): nodes, roles, parents, sensors, ports and the cluster mode. One file
// starts the local processes (fogctl up) and names each service's own settings.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "common/admission.hpp"
#include "common/camera/detector_config.hpp"
#include "common/camera/image_limits.hpp"
#include "common/camera/pinhole.hpp"
#include "common/madc.hpp"
#include "common/messages.hpp"
#include "common/preprocess.hpp"
#include "common/cloud_io.hpp"
#include "common/status.hpp"
#include "common/tracking/centroid_merge.hpp"
#include "common/tracking/displacement_config.hpp"
#include "common/tracking/tracker_config.hpp"

namespace fogmap {

// Edges and aggregators make the map; a detection node (one per camera) sends its camera's 2D
// detections to a tracker, which fuses them with the root's global map (or with the displacement
// centroids its edges send) into tracks.
enum class Role { kEdge, kAggregator, kDetection, kTracker };
// The service (and binary) that runs a node of this role: "edge-cluster", "merge-aggregator",
// "detection", "tracker".
const char* serviceName(Role role);
// The role as the topology file writes it: "edge", "aggregator", "detection", "tracker".
const char* roleName(Role role);

// A virtual LiDAR cut from a real scan: azimuth sector `index` of `views`, widened by overlap.
struct SectorSplit {
  int views = 1;
  int index = 0;
  double overlap_deg = 10.0;
};

// The `source` of a simulated LiDAR (a directory named so is written ./sim).
inline constexpr const char* kSimSource = "sim";

struct SensorConfig {
  std::filesystem::path source;         // a directory of scans (replayed in name order), one file, or "sim"
  // source sim: LiDAR `lidar` of the scene file `scene` (common/sim), cast at the scene time of
  // each scan number (sim::sceneTime); no split, and `pose` must be the LiDAR's pose in the scene.
  std::filesystem::path scene;
  std::string lidar;
  double rate_hz = 10.0;                // replay rate
  bool loop = true;                     // start again after the last scan (sim: after the scene's duration)
  std::optional<std::uint64_t> frames;  // stop after this many frames (default: endless when looping)
  std::optional<SectorSplit> split;     // virtual LiDAR; its pose is the sector's rotation
  // The scan's frame -> common frame. With a split, the points of a view are in the sector's frame
  // and the edge applies pose * sectorPose(split).
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();

  // True for a simulated LiDAR (source: sim).
  bool simulated() const { return source == kSimSource; }
};

// What a detection node replays as its detector's output instead of running one (`detector: {kind:
// truth}`): the simulated scene's objects projected into the camera (source sim), with seeded
// misses, box jitter and latency, for repeatable tests and evaluations.
struct TruthReplayConfig {
  double miss_rate = 0.0;     // probability that a visible object is not reported
  double box_jitter_px = 0.0;  // Gaussian sigma added to each box edge
  double latency_ms = 0.0;     // how long after the capture the detections are sent
};

// A detection node's camera (`camera:`): where its frames come from, its calibration and its
// detector.
struct CameraNodeConfig {
  // A directory of images (replayed in name order), a video file, a V4L2 device (/dev/videoN), or
  // sim: camera `camera` of the scene `scene`, whose objects are projected (detector truth).
  std::filesystem::path source;
  std::filesystem::path scene;
  std::string camera;
  double rate_hz = 10.0;                // replay rate of a directory (and sim); devices and videos keep theirs
  bool loop = true;
  std::optional<std::uint64_t> frames;  // stop after this many frames
  std::size_t queue_frames = 2;         // frames waiting for a slower detector; beyond, the oldest is dropped
  // Frames with more pixels are refused from their header, before decoding (common/camera/image_limits.hpp).
  std::uint64_t max_image_pixels = camera::kDefaultMaxImagePixels;
  bool truth = false;                   // detector kind truth: replay the scene's objects (source sim only)
  camera::DetectorConfig detector;      // kind hog, cascade or dnn (paths resolved against the topology)
  TruthReplayConfig truth_replay;
  // The camera's calibration in the common frame (`calibration:` {fx, fy, cx, cy, width, height,
  // distortion: [k1, k2, p1, p2, k3], pose: camera -> common frame, x right, y down, z forward}).
  camera::PinholeCamera calibration;

  bool simulated() const { return source == kSimSource; }
};

// Which LiDAR observations a tracker fuses with its cameras' detections (`tracker: {input: ...}`).
// One input, not both: the global map and the centroids see the same objects at the same instants,
// so together they would give each object two measurements a frame.
enum class TrackerInput {
  // The root's global map (every obstacle a measurement: the centroid of its ellipsoids, their
  // spread as covariance). Sees parked and moving objects alike; works with moving sensors.
  kGlobalMap,
  // The displacement centroids its edges stream (the edges whose displacement.tracker names it),
  // merged per epoch across edges. Moving objects only, from static sensors; needs no root.
  kCentroids,
};
// "global_map" or "centroids", as the topology writes it.
const char* trackerInputName(TrackerInput input);
Expected<TrackerInput> parseTrackerInput(const std::string& name);

// A tracker node's settings (`tracker:`): the fusion (common/tracking/tracker_config.hpp) and its
// LiDAR input.
struct TrackerNodeConfig {
  tracking::TrackerConfig tracking;
  TrackerInput input = TrackerInput::kGlobalMap;
  // Input centroids: centroids of one epoch (from any edges) closer than this on the ground are one
  // observation (common/tracking/centroid_merge.hpp); 0 keeps every centroid. Only with centroids.
  double centroid_merge_m = 1.0;
  // Input centroids: each edge's centroids narrower than this radius are placed on the object's
  // axis instead of the side its LiDAR sees (tracking::visibleSideCorrected: people and poles; the
  // merge still groups them as seen); 0 leaves them as Algorithm 1 gives them. Only with centroids.
  double visible_side_max_radius_m = tracking::kVisibleSideMaxRadiusM;
};

// An edge's displacement centroids (`displacement:`, DESIGN.md 2.4): the edge runs the displacement
// detector on each scan it cleaned (in the common frame) and streams the centroids to `tracker`,
// whose input must be centroids. The sensor must stand still.
struct DisplacementNodeConfig {
  std::string tracker;  // the tracker node that fuses them
  // `preset: indoor` (the default; 0.1 m voxels) or `outdoor` (1.0 m voxels, KITTI's HDL-64E),
  // then every key given: voxel_m, neighbour_m, min_neighbours, min_points, min_z_variance_m2.
  tracking::DisplacementParams params;
};

// A node's own certificate and private key (PEM files), when they are not <cert_dir>/<name>.crt
// and .key.
struct TlsFiles {
  std::filesystem::path cert;
  std::filesystem::path key;
};

// Mutual TLS on every gRPC link (topology `tls:`; plaintext when absent). Every endpoint presents a
// certificate issued by the CA, and a certificate's common name is its holder's identity: a node's
// name, or a client's (fogctl). Paths are resolved against the topology file's directory.
struct TlsConfig {
  std::filesystem::path ca;        // CA bundle (PEM) every peer's certificate must chain to
  std::filesystem::path cert_dir;  // <name>.crt and <name>.key of nodes and clients (default: the CA's directory)
  std::vector<std::string> geofence_clients;  // certificate names the root lets call SetGeofence
};

// What one TLS endpoint presents (cert, key) and trusts (ca), as file paths.
struct TlsIdentity {
  std::filesystem::path ca;
  std::filesystem::path cert;
  std::filesystem::path key;
};

struct NodeConfig {
  std::uint32_t id = 0;
  std::string name;
  Role role = Role::kEdge;
  std::string parent;                  // empty for the root
  // An IPv4 address (checked at parse time): the services listen on and connect to it as written.
  std::string host = "127.0.0.1";      // where the node listens / is reached
  std::uint16_t port = 0;              // gRPC port (aggregators)
  std::uint16_t metrics_port = 0;      // Prometheus /metrics
  std::optional<SensorConfig> sensor;  // edges only
  std::optional<CameraNodeConfig> camera;  // detection nodes only; their parent is a tracker
  std::optional<TrackerNodeConfig> tracker;  // tracker nodes only (no parent; they read the root or edges)
  std::optional<DisplacementNodeConfig> displacement;  // edges only: displacement centroids to a tracker
  std::optional<TlsFiles> tls;         // overrides <cert_dir>/<name>.crt and .key (TLS on only)
};

struct TopologyConfig {
  std::string name;
  Mode mode = Mode::kMadc;
  // Baseline mode: the edges ship their scans whole (only moved into the common frame) and the
  // root crops, downsamples and removes the ground of each before clustering them together (the
  // MAD-C paper's baseline; YAML `baseline_ships: raw`); else they ship pre-processed points.
  bool baseline_ships_raw = false;
  MadcParams madc;                     // eps, min points, alpha
  PreprocessConfig preprocess;         // crop and ground (the pose comes from each sensor)
  // An aggregator with L levels of aggregators below it emits epoch k at k period_ms + L deadline_ms
  // (common/epochs.hpp).
  double deadline_ms = 80.0;
  double period_ms = 100.0;            // the cluster period: epoch k is [k, k + 1) x period_ms of unix time
  std::size_t max_message_bytes = 64U << 20;  // gRPC transport limit
  std::uintmax_t max_scan_bytes = kDefaultMaxScanBytes;  // scan files above this are refused unread
  AdmissionLimits admission;           // what every aggregator accepts (common/admission.hpp)
  std::optional<TlsConfig> tls;        // mutual TLS on every link; plaintext when absent
  std::vector<NodeConfig> nodes;

  const NodeConfig* find(const std::string& name) const;
  const NodeConfig* find(std::uint32_t id) const;
  // The root aggregator: the aggregator without a parent.
  const NodeConfig* root() const;
  // Detection nodes whose detections go to tracker `name`.
  std::vector<const NodeConfig*> camerasOf(const std::string& name) const;
  // Edges whose displacement centroids go to tracker `name`.
  std::vector<const NodeConfig*> centroidEdgesOf(const std::string& name) const;
  std::vector<const NodeConfig*> children(const std::string& name) const;
  // Levels of aggregators in the subtree of `name`: 1 when its children are edges, 0 for an edge.
  int aggregatorLevels(const std::string& name) const;
  // Sensor (edge) node ids in the subtree of `name` (itself if it is an edge), sorted.
  std::vector<std::uint32_t> sensorsBelow(const std::string& name) const;
  // The files TLS endpoint `name` uses: a node's own override, else <cert_dir>/<name>.crt and .key
  // (nodes and clients alike). std::nullopt when TLS is off.
  std::optional<TlsIdentity> tlsIdentity(const std::string& name) const;
};

// A topology's or node's name: 1 to 64 letters, digits, '.', '_' and '-', not starting with '.'
// (names become file names, command-line words and metric labels).
bool isName(const std::string& name);
// With TLS a name is also a file name (<cert_dir>/<name>.crt): letters, digits, '.', '_' and '-',
// not starting with '.', and not "ca" (the CA's own files).
bool isCertificateName(const std::string& name);

// Parses and validates (names of letters, digits, '.', '_', '-'; unique names, ids and ports;
// exactly one root; parents exist and are aggregators; no cycles; edges have sensors). Relative
// sensor paths (source, scene) resolve against `base_dir`. A sensor is recorded scans
// (`source: DIR|FILE`, optionally `split`) or a simulated LiDAR (`source: sim, scene: FILE, lidar:
// NAME`): `scene` and `lidar` are required with source sim and refused otherwise, `split` is refused
// with it.
// Hosts must be IPv4 addresses; madc and admission values are checked by common/admission.hpp.
// The optional tls section: `ca` is required, `cert_dir` and `geofence_clients` optional; a node's
// `tls: {cert, key}` needs both keys and the top-level section. TLS files are read when a service
// starts, not here. An edge's `displacement:` names a tracker whose input is centroids, and such a
// tracker has at least one edge sending to it.
Expected<TopologyConfig> parseTopology(const std::string& yaml_text, const std::filesystem::path& base_dir);
Expected<TopologyConfig> loadTopology(const std::filesystem::path& path);

// Ready-made topologies (the repository's topologies/ files are generated from these).
// Star: one sink, `edges` edges. Tree: a balanced tree of aggregators over the edges, each over at
// most `fanout` subtrees (binary by default; tree-7 with fanout 4 is a sink over two aggregators of
// four and three edges).
TopologyConfig makeStarTopology(int edges, const std::filesystem::path& source, int base_port);
TopologyConfig makeTreeTopology(int edges, const std::filesystem::path& source, int base_port, int fanout = 2);
// The tracker of a ready-made topology: named kTrackerNodeName, id 300, gRPC port base_port + 300,
// metrics base_port + 301 (after the aggregators' ports and the edges' and aggregators' metrics).
inline constexpr const char* kTrackerNodeName = "tracker";
NodeConfig trackerNode(int base_port, const tracking::TrackerConfig& tracking);
// Camera `number` (1, 2, ...) of a ready-made topology: a detection node named `name` sending to
// the tracker `tracker`, id 400 + number, metrics base_port + 400 + number; its calibration takes
// the node's name.
NodeConfig detectionNode(int number, const std::string& name, const std::string& tracker, int base_port,
                         CameraNodeConfig camera);
std::string toYaml(const TopologyConfig& topology);

}  // namespace fogmap
