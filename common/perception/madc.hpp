#pragma once
// MAD-C Algorithm 1 (GENLOCALMAP): cluster one pre-processed scan and distil every cluster into
// a bounding ellipsoid with a globally unique id.
#include <cstdint>
#include <span>

#include "common/geometry/cloud.hpp"
#include "common/geometry/ellipsoid.hpp"
#include "common/geometry/map.hpp"
#include "common/perception/clustering.hpp"

namespace fogmap {

struct MadcParams {
  ClusteringParams clustering;  // eps 0.35 m, 10 points
  double alpha = 1.5;           // confidence step
  // The aura is eps / 2 so that "two clusters closer than eps" becomes "two ellipsoids meet".
  EllipsoidParams ellipsoidParams() const { return {alpha, clustering.eps_m / 2.0}; }
};

struct LocalMapResult {
  Map map;                // one object per local cluster, ellipsoid index = cluster label
  Clustering clustering;  // per-point labels, for MAD-C-ext and accuracy checks
};

LocalMapResult genLocalMap(std::span<const Point> points, std::uint32_t node, std::uint64_t frame,
                           const MadcParams& params);

}  // namespace fogmap
