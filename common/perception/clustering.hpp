#pragma once
// Euclidean clustering with exactly the semantics of PCL's EuclideanClusterExtraction (points
// closer than eps, strictly, are connected; connected components with fewer than min_points or
// more than max_points points are noise), computed fast on a sorted voxel grid; PCL itself as the
// reference; DBSCAN.
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "common/geometry/cloud.hpp"
#include "common/geometry/ellipsoid.hpp"

namespace fogmap {

struct ClusteringParams {
  double eps_m = 0.35;
  std::size_t min_points = 10;
  std::size_t max_points = std::numeric_limits<std::int32_t>::max();
  // Threads for the neighbour search of euclideanClusters (the result does not depend on it).
  std::size_t threads = 1;
};

// Labels in canonical form: -1 for noise, clusters numbered 0, 1, ... in the order of their
// first point, so that two equal partitions have equal label vectors.
struct Clustering {
  std::vector<std::int32_t> labels;
  std::int32_t cluster_count = 0;
};

enum class ClusteringMethod { kFogmap, kPcl, kPclUnsorted };

// Fast exact Euclidean clustering: grid of cell edge eps/sqrt(3) (a cell is one component),
// union-find over neighbouring cells with an early-exit closest-pair check.
Clustering euclideanClusters(std::span<const Point> points, const ClusteringParams& params);
// PCL's EuclideanClusterExtraction on a KdTree (sorted or unsorted radius search), relabelled canonically.
Clustering pclEuclideanClusters(std::span<const Point> points, const ClusteringParams& params,
                                bool sorted_search = true);
Clustering clusterPoints(std::span<const Point> points, const ClusteringParams& params,
                         ClusteringMethod method);

struct DbscanParams {
  double eps_m = 0.35;            // neighbourhood radius (a point is its own neighbour)
  std::size_t min_neighbours = 5;  // a core point has at least this many neighbours, itself included
  std::size_t min_cluster_points = 1;  // smaller clusters become noise
};
// DBSCAN (Ester et al. 1996) with neighbours closer than eps (strictly): clusters grow from core
// points taken in index order; a border point joins the first cluster whose expansion reaches it.
Clustering dbscan(std::span<const Point> points, const DbscanParams& params);

// Rewrites arbitrary labels (negative = noise) into canonical form.
Clustering canonicalize(std::span<const std::int32_t> labels);

// One summary per cluster, in label order.
std::vector<ClusterSummary> summarizeClusters(std::span<const Point> points, const Clustering& clustering);

}  // namespace fogmap
