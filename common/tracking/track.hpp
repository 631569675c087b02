#pragma once
// What the tracker takes and gives, as plain types: LiDAR observations, camera detection frames and
// tracks (common/tracking/tracker.hpp fuses them; services/common/proto_convert carries them).
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/camera/detection.hpp"
#include "common/geometry/object_class.hpp"
#include "common/geometry/oriented_box.hpp"

namespace fogmap::tracking {

// A LiDAR observation: a displacement centroid or a global-map object, in the common frame.
struct CloudObservation {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity() * 0.01;  // m^2
  // The points behind it (0: not known). When a step must shed measurements, the ones near no
  // track go by this, most points first (common/tracking/tracker.hpp).
  std::size_t point_count = 0;
  // The LiDAR class of a global-map object whose edges classify (topology objects:), and its
  // oriented box as its views give it (a vehicle's position is its box grown to its class's size).
  std::optional<ObjectLabel> lidar_class{};
  std::optional<OrientedBox> box{};
};

// One moving (or newly seen) object's points, summarised (displacement centroids, DESIGN.md 2.4).
struct DisplacementCentroid {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();    // mean of the cluster's points, in their frame, m
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // sample covariance (n - 1) of those points, m^2
  std::size_t point_count = 0;
};

// One edge's displacement centroids of one scan, in the common frame: what an edge streams to the
// tracker whose input is centroids. The tracker merges the frames of one epoch from all its edges
// into one CloudFrame (services/tracker/centroid_collector.hpp).
struct CentroidFrame {
  std::string edge;          // the edge node's name
  std::uint64_t epoch = 0;   // the cluster epoch the scan was shipped in (common/base/epochs.hpp)
  std::int64_t time_ns = 0;  // the scan's sensor time (unix epoch)
  Eigen::Vector3d sensor_position = Eigen::Vector3d::Zero();  // the LiDAR, common frame
  std::vector<DisplacementCentroid> centroids;
};

// Every observation of one LiDAR frame (or one global map), with the sensor's timestamp and where
// the sensor is (the overlay keeps the overlaid observation nearest to it).
struct CloudFrame {
  std::int64_t time_ns = 0;
  Eigen::Vector3d sensor_position = Eigen::Vector3d::Zero();
  std::vector<CloudObservation> observations;
};

// Every detection of one camera image, with the image's capture time.
struct DetectionFrame {
  std::string camera;
  std::int64_t capture_time_ns = 0;
  std::vector<camera::Detection> detections;
};

enum class TrackState { kTentative, kConfirmed, kLost };
const char* trackStateName(TrackState state);

inline constexpr const char* kUnknownLabel = "unknown";

struct Track {
  std::uint64_t id = 0;
  std::string label = kUnknownLabel;
  TrackState state = TrackState::kTentative;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // ground plane, m
  Eigen::Vector2d velocity = Eigen::Vector2d::Zero();  // m/s (0 under the paper's association)
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();  // of the position, m^2
  std::int64_t created_ns = 0;
  std::int64_t last_update_ns = 0;
  bool camera_confirmed = false;  // a camera detection was fused into it at least once
  int consecutive_hits = 0;
  // A vehicle's heading (rad, in [-pi, pi], where its front points), from the boxes of the
  // observations that updated it (Tracker, "vehicleHeading"); none for people and other objects,
  // and for a vehicle not yet seen with a box.
  std::optional<double> heading_rad{};
};

}  // namespace fogmap::tracking
