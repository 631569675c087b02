#pragma once
// The views of one sensor's clusters (docs/design.md "Oriented boxes"): for each cluster, its
// oriented box fitted by L-shape with the face or corner nearest the sensor, and, with a
// classifier, its LiDAR class. What an edge attaches to its local map's ellipsoids, what
// `fogctl cluster --objects` writes, and what training sees.
#include <cstddef>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "common/base/status.hpp"
#include "common/classify/object_classifier.hpp"
#include "common/geometry/cloud.hpp"
#include "common/geometry/map.hpp"
#include "common/perception/clustering.hpp"

namespace fogmap {

struct ClusterView {
  std::size_t points = 0;
  OrientedBox box;
  std::optional<ObjectLabel> label{};  // with a classifier
};

// The points of each cluster of `clustering` (labels over `points`), in point order.
std::vector<Cloud> pointsByCluster(std::span<const Point> points, const Clustering& clustering);

// The view of every cluster with at least min_points points (nothing for the smaller ones: too few
// points for a shape). Errors when a box cannot be fitted.
Expected<std::vector<std::optional<ClusterView>>> clusterViews(std::span<const Point> points, const Clustering& clustering,
                                                               const Eigen::Vector3d& sensor,
                                                               const ObjectClassifier* classifier,
                                                               std::size_t min_points = 1);

// Vehicle parts (docs/design.md "Oriented boxes"): a sensor sees a car in pieces where a band of
// it returns nothing (dark paint, glass, a sloped rear between two rings). Two clusters whose views
// are both vehicles' (vehiclePriorFor: the class, or a box of at least kVehicleMinLengthM) are one
// vehicle when one lies above the other as the sensor sees it (their boxes' heights overlap by at
// most 5 cm, their azimuths from the sensor overlap by at least half the narrower's, and their
// near faces are at most 1 m apart in range: a band between them returned nothing; parts side by
// side are two objects, or a vehicle and a wall, and what is seen over a car's roof is behind it),
// their boxes, each grown to its prior from the face or corner `sensor` saw (grownToPrior),
// overlap, and the box fitted on their points together is still one vehicle's: no
// longer than kVehiclePartsMaxLength times the larger prior's length and no wider than its
// max_width_m (two cars side by side, or nose to tail, are not). Pairs are taken in label order, each
// tested on the points of the clusters joined so far. Returns the clustering with the parts joined
// (canonical labels) and its views, or nothing when no two clusters join. A joined cluster's view:
// its box spans all its points at the yaw of its part of most points (the parts are cuts through
// one vehicle at different heights, and a sloped rear moves a cut back without turning it: fitted
// together, the cuts read as a side that is not there), with that part's class. Errors when a box
// cannot be fitted.
inline constexpr double kVehiclePartsMaxLength = 1.5;
struct JoinedParts {
  Clustering clustering;
  std::vector<std::optional<ClusterView>> views;  // per cluster of `clustering`
};
Expected<std::optional<JoinedParts>> joinedVehicleParts(std::span<const Point> points, const Clustering& clustering,
                                                       std::span<const std::optional<ClusterView>> views,
                                                       const Eigen::Vector3d& sensor);

// One sensor's objects, as an edge with boxes ships them, `fogctl cluster --objects` writes them and
// the KITTI scoring scores them: the view of every cluster of at least min_points points
// (clusterViews), then a vehicle seen in pieces joined into one cluster (joinedVehicleParts).
struct SensorObjects {
  Clustering clustering;                          // with the parts joined
  std::vector<std::optional<ClusterView>> views;  // per cluster of `clustering`
  std::size_t parts_joined = 0;                   // clusters joined into others
};
Expected<SensorObjects> sensorObjects(std::span<const Point> points, Clustering clustering, const Eigen::Vector3d& sensor,
                                      const ObjectClassifier* classifier, std::size_t min_points = 1);

// Puts each cluster's view on its ellipsoid of a local map (ellipsoid index = cluster label).
void attachViews(std::span<const std::optional<ClusterView>> views, Map& local);

}  // namespace fogmap
