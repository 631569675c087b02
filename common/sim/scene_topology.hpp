#pragma once
// A topology from a scene (fogctl topology --scene): one edge per LiDAR of the scene, each a
// simulated sensor (`sensor: {source: sim, scene, lidar}`) at the LiDAR's mounting pose, under one
// sink (star) or a balanced tree of aggregators, as makeStarTopology and makeTreeTopology lay them out.
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>

#include "common/config/camera_node.hpp"
#include "common/config/topology.hpp"
#include "common/config/tracker_node.hpp"
#include "common/sim/scene.hpp"
#include "common/tracking/displacement_config.hpp"
#include "common/tracking/tracker_config.hpp"

namespace fogmap::sim {

// How a scene's edges make their maps: their clustering (kSensor gives each edge its scene LiDAR's
// model for the ring links) and madc.fragment_min_points. A scene's LiDARs are sparse and of known
// models: by default each edge clusters sensor-aware and ships every cluster, down to one point, so
// that objects only the pooled points of several LiDARs hold are kept (docs/evaluation.md measures
// both against the exact mode without fragments).
struct SceneMapping {
  ClusteringMode clustering = ClusteringMode::kSensor;
  std::optional<std::size_t> fragment_min_points = 1;
  // madc.alpha_max: each ellipsoid reaches its cluster's extent along its axes, to at most 2.5
  // standard deviations (ClusterReach), so that the faces of an object that several LiDARs see
  // meet where the baseline's pooled points join them (docs/evaluation.md; 0: off)
  double alpha_max = 2.5;
  ObjectsConfig objects{};  // boxes and classes at the edges (off: ellipsoids only)
};

// The MAD-C paper's edges: exact clustering, no fragments, alpha for every ellipsoid. The default
// for recorded scans, whose LiDAR models fogmap does not know.
inline SceneMapping paperMapping() { return SceneMapping{ClusteringMode::kExact, std::nullopt, 0.0, ObjectsConfig{}}; }

struct SceneTopologyOptions {
  bool tree = false;       // a balanced tree of aggregators instead of a star
  int fanout = 2;          // a tree's aggregators have at most this many children
  int base_port = 50000;   // ports as makeStarTopology / makeTreeTopology number them
  double rate_hz = 10.0;   // every simulated LiDAR's scan rate
  SceneMapping mapping;
  // A tracker (named "tracker") and one detection node per camera of the scene (named
  // cameraNodeFor(camera)), each replaying the scene's objects as its detections with `truth`;
  // the tracker reads the root's global maps, or with tracker_input centroids every edge streams it
  // the displacement centroids of its scans, found with `displacement`.
  bool tracker = false;
  // The topology's (not sim::TruthReplayConfig, which a file that includes camera_truth.hpp first
  // would find here: two layouts of one struct).
  fogmap::TruthReplayConfig truth;
  tracking::TrackerConfig tracking;
  TrackerInput tracker_input = TrackerInput::kGlobalMap;
  tracking::DisplacementParams displacement;
};

// The detection node of scene camera `camera_name`: "cam-" + the name as edgeNameFor cleans it.
std::string cameraNodeFor(const std::string& camera_name);

// The edge that simulates LiDAR `lidar_name`: "edge-" + the name with every character outside
// [A-Za-z0-9._-] replaced by '_', cut to a node name's 64 characters.
std::string edgeNameFor(const std::string& lidar_name);

// One edge per LiDAR of `scene` (ids 1..K in the scene's order, named edgeNameFor(LiDAR), with
// "-<id>" appended when two would be equal), each with a sim sensor on `scene_file` as given
// (and with options.tracker, the tracker and a detection node per camera, calibrated as the scene
// says, on the same scene file)
// (written into the topology as is: relative paths resolve against the topology file's directory)
// and the LiDAR's pose. The common frame is the scene's: the crop box spans the scene's extent and
// its objects' heights, and ground removal is hinted at the scene's ground height when it is level.
TopologyConfig sceneTopology(const Scene& scene, const std::filesystem::path& scene_file,
                             const SceneTopologyOptions& options = {});

}  // namespace fogmap::sim
