#pragma once
// The topology file (YAML): nodes, roles, parents, sensors, ports and the cluster mode. One file
// starts the local processes (fogctl up) and names each service's own settings. This is its model,
// plain structs; topology_parse.hpp reads and validates a file, topology_yaml.hpp writes one, and
// topology_presets.hpp makes the ready-made ones.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "common/config/admission.hpp"
#include "common/config/optional_section.hpp"
#include "common/io/cloud_io.hpp"
#include "common/io/messages.hpp"
#include "common/perception/madc.hpp"
#include "common/perception/preprocess.hpp"
#include "common/perception/virtual_lidar.hpp"

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

// The `source` of a simulated LiDAR (a directory named so is written ./sim).
inline constexpr const char* kSimSource = "sim";

// How an edge clusters its scans: kExact, PCL's Euclidean partition (euclideanClusters, the default);
// kSensor, the exact links plus ring links from its LiDAR model's beam table (sensorAwareClusters),
// which keeps an object a sparse LiDAR sees as one cluster.
enum class ClusteringMode { kExact, kSensor };
// "exact" or "sensor", as the topology file writes it.
const char* clusteringModeName(ClusteringMode mode);
Expected<ClusteringMode> parseClusteringMode(const std::string& name);

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
  ClusteringMode clustering = ClusteringMode::kExact;
  std::string model;  // the LiDAR model (lidarModel): its beam table; required with clustering sensor

  // True for a simulated LiDAR (source: sim).
  bool simulated() const { return source == kSimSource; }
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

// The sections of one role, each in its own header (included by the code that reads them).
struct CameraNodeConfig;        // common/config/camera_node.hpp
struct TrackerNodeConfig;       // common/config/tracker_node.hpp
struct DisplacementNodeConfig;  // common/config/displacement_node.hpp

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
  OptionalSection<CameraNodeConfig> camera;  // detection nodes only; their parent is a tracker
  OptionalSection<TrackerNodeConfig> tracker;  // tracker nodes only (no parent; they read the root or edges)
  OptionalSection<DisplacementNodeConfig> displacement;  // edges only: displacement centroids to a tracker
  std::optional<TlsFiles> tls;         // overrides <cert_dir>/<name>.crt and .key (TLS on only)
};

// What the edges say of each local cluster beyond its ellipsoid (YAML `objects:`): its oriented box
// (docs/design.md "Oriented boxes") and, with a classifier model file, its LiDAR class. The file is
// loaded by each edge at start-up; a missing or corrupt one stops the edge, naming it.
struct ObjectsConfig {
  bool boxes = false;
  std::optional<std::filesystem::path> classifier{};  // resolved against the topology's folder
  bool operator==(const ObjectsConfig&) const = default;
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
  ObjectsConfig objects{};             // boxes and classes at the edges (off: ellipsoids only)
  // An aggregator with L levels of aggregators below it emits epoch k at k period_ms + L deadline_ms
  // (common/base/epochs.hpp).
  double deadline_ms = 80.0;
  double period_ms = 100.0;            // the cluster period: epoch k is [k, k + 1) x period_ms of unix time
  std::size_t max_message_bytes = 64U << 20;  // gRPC transport limit
  std::uintmax_t max_scan_bytes = kDefaultMaxScanBytes;  // scan files above this are refused unread
  AdmissionLimits admission;           // what every aggregator accepts (common/config/admission.hpp)
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

// The longest topology or node name.
inline constexpr std::size_t kMaxNameChars = 64;
// A topology's or node's name: 1 to kMaxNameChars letters, digits, '.', '_' and '-', not starting
// with '.' (names become file names, command-line words and metric labels).
bool isName(const std::string& name);
// With TLS a name is also a file name (<cert_dir>/<name>.crt): letters, digits, '.', '_' and '-',
// not starting with '.', and not "ca" (the CA's own files).
bool isCertificateName(const std::string& name);

}  // namespace fogmap
