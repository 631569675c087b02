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

// Puts each cluster's view on its ellipsoid of a local map (ellipsoid index = cluster label).
void attachViews(std::span<const std::optional<ClusterView>> views, Map& local);

}  // namespace fogmap
