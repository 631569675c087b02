#pragma once
// MAD-C Algorithm 1 (GENLOCALMAP): cluster one pre-processed scan and distil every cluster into
// a bounding ellipsoid with a globally unique id.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "common/geometry/cloud.hpp"
#include "common/geometry/ellipsoid.hpp"
#include "common/geometry/map.hpp"
#include "common/base/status.hpp"
#include "common/perception/clustering.hpp"
#include "common/perception/sensor_clustering.hpp"

namespace fogmap {

struct MadcParams {
  ClusteringParams clustering;  // eps 0.35 m, 10 points
  // Unset: the exact mode (euclideanClusters, PCL's partition). Set: the sensor-aware mode
  // (sensorAwareClusters: the exact links plus ring links from the sensor's beam table), which keeps
  // an object a sparse LiDAR sees as one cluster where its rings lie further apart than eps.
  std::optional<SensorLinks> sensor_links;
  double alpha = 1.5;           // confidence step
  // Above alpha: each ellipsoid reaches its cluster's extent along its axes, up to alpha_max
  // (EllipsoidParams, ClusterReach). At most alpha: off, the paper's ellipsoids.
  double alpha_max = 0.0;
  // An edge ships every local cluster of at least this many points: those below
  // clustering.min_points are fragments, and min_points applies to a global object's points over
  // all its sensors, at the root (withoutFragments, common/geometry/map.hpp). Unset: min_points,
  // no fragments (the edges drop their small clusters, as the MAD-C paper does). Fragments cost
  // bytes: the default stays off until the compact wire carries them (docs/design.md).
  std::optional<std::size_t> fragment_min_points;
  std::size_t edgeMinPoints() const { return fragment_min_points.value_or(clustering.min_points); }
  // The aura is eps / 2 so that "two clusters closer than eps" becomes "two ellipsoids meet".
  EllipsoidParams ellipsoidParams() const { return {alpha, clustering.eps_m / 2.0, alpha_max}; }
};

struct LocalMapResult {
  Map map;                // one object per local cluster, ellipsoid index = cluster label
  Clustering clustering;  // per-point labels, for MAD-C-ext and accuracy checks
};

// One bounding ellipsoid per cluster of `clustering`, in label order, with ids (node, frame, label):
// from the clusters' summaries, or with params.reaches() from a second pass over their points.
std::vector<Ellipsoid> clusterEllipsoids(std::span<const Point> points, const Clustering& clustering, std::uint32_t node,
                                         std::uint64_t frame, const EllipsoidParams& params);

// GENLOCALMAP with its parameters prepared once: in the sensor-aware mode, the sensor's beam
// geometry (SensorClusterer). An edge holds one for all its frames.
class LocalMapper {
 public:
  explicit LocalMapper(MadcParams params);
  // Errors only in the sensor-aware mode: on every frame when validateSensorClusteringParams refused
  // its parameters (naming the field), or for more than 2^32 - 1 points.
  Expected<LocalMapResult> map(std::span<const Point> points, std::uint32_t node, std::uint64_t frame) const;
  // map's two steps, for an edge that changes the clustering between them (vehicle parts joined):
  // the clusters of `points` (same errors), and the local map of a clustering of them.
  Expected<Clustering> cluster(std::span<const Point> points) const;
  Map summarise(std::span<const Point> points, const Clustering& clustering, std::uint32_t node, std::uint64_t frame) const;
  const MadcParams& params() const { return params_; }

 private:
  MadcParams params_;
  std::optional<Expected<SensorClusterer>> clusterer_;  // with sensor_links
};

// LocalMapper(params).map(points, node, frame): for one cloud.
Expected<LocalMapResult> genLocalMap(std::span<const Point> points, std::uint32_t node, std::uint64_t frame,
                                     const MadcParams& params);

}  // namespace fogmap
