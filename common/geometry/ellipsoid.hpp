#pragma once
// MAD-C summaries (DESIGN.md 2.1): constant-space cluster summaries, bounding ellipsoids with
// confidence step alpha and aura delta, delimiting boxes, and the exact intersection test (2.2).
#include <compare>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>

#include <Eigen/Core>

#include "common/geometry/cloud.hpp"
#include "common/geometry/object_class.hpp"
#include "common/geometry/oriented_box.hpp"

namespace fogmap {

// Globally unique ellipsoid id: (node, frame sequence, local index).
struct EllipsoidId {
  std::uint32_t node = 0;
  std::uint64_t frame = 0;
  std::uint32_t index = 0;
  auto operator<=>(const EllipsoidId&) const = default;
};
std::string toString(const EllipsoidId& id);

// Axis-aligned box, closed intervals.
struct Box {
  Eigen::Vector3d min{Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity())};
  Eigen::Vector3d max{Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity())};

  bool empty() const { return (min.array() > max.array()).any(); }
  bool overlaps(const Box& other) const {
    return (min.array() <= other.max.array()).all() && (other.min.array() <= max.array()).all();
  }
  void extend(const Box& other) {
    min = min.cwiseMin(other.min);
    max = max.cwiseMax(other.max);
  }
  bool operator==(const Box&) const = default;
};

// N, S = sum p, Q = sum p p^T in double, relative to a reference point (the first point added),
// so that the covariance keeps its precision far from the origin.
class ClusterSummary {
 public:
  void add(const Eigen::Vector3d& p);
  void add(const Point& p) { add(Eigen::Vector3d(p.x, p.y, p.z)); }
  // Combines two summaries of disjoint point sets.
  void absorb(const ClusterSummary& other);

  std::uint64_t count() const { return count_; }
  Eigen::Vector3d mean() const;
  // Maximum-likelihood covariance Q/N - mu mu^T (zero for a single point).
  Eigen::Matrix3d covariance() const;

 private:
  std::uint64_t count_ = 0;
  Eigen::Vector3d reference_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d sum_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_outer_ = Eigen::Matrix3d::Zero();
};

struct EllipsoidParams {
  double alpha = 1.5;     // confidence step; the paper's useful range is [0.8, 2.4]
  double aura_m = 0.175;  // delta = eps / 2
  // Reach (docs/design.md "Reaching ellipsoids"): above alpha, each semi-axis grows from
  // alpha sigma towards the cluster's farthest point along its axis, to at most alpha_max sigma.
  // At most alpha (the default): the paper's alpha^2 Sigma.
  double alpha_max = 0.0;
  bool reaches() const { return alpha_max > alpha; }
};

// The set {x : (x - center)^T shape^-1 (x - center) <= 1}; shape is symmetric positive definite
// once the aura is applied.
struct Ellipsoid {
  EllipsoidId id;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Matrix3d shape = Eigen::Matrix3d::Identity();
  std::uint64_t point_count = 0;
  // What its sensor saw of the cluster beyond the ellipsoid, where the topology's `objects:` asks
  // for it (docs/design.md "Oriented boxes"): the oriented box fitted on the cluster's points, with
  // the face or corner nearest the sensor, and the LiDAR classifier's class. MERGE carries both
  // through untouched; a global object's box and class are functions of its views' (object_shape.hpp).
  std::optional<OrientedBox> box{};
  std::optional<ObjectLabel> label{};

  std::uint32_t node() const { return id.node; }
  bool operator==(const Ellipsoid&) const = default;
};

// Grows every semi-axis of `shape` by delta: V (L^1/2 + delta I)^2 V^T.
Eigen::Matrix3d withAura(const Eigen::Matrix3d& shape, double delta_m);

// Bounding ellipsoid of a cluster: shape alpha^2 Sigma grown by the aura.
Ellipsoid ellipsoidFromSummary(const ClusterSummary& summary, const EllipsoidId& id,
                               const EllipsoidParams& params);

// A cluster's principal axes (its covariance's eigenvectors) and how far its points reach from
// its mean along each, on both sides: made from the cluster's summary, then given every point of
// the cluster.
class ClusterReach {
 public:
  explicit ClusterReach(const ClusterSummary& summary);
  void add(const Eigen::Vector3d& p) {
    const Eigen::Vector3d q = axes_.transpose() * (p - mean_);
    low_ = low_.cwiseMin(q);
    high_ = high_.cwiseMax(q);
  }
  void add(const Point& p) { add(Eigen::Vector3d(p.x, p.y, p.z)); }
  // With params.reaches(): centred on the middle of the points' extent along each axis, with
  // semi-axis k half that extent clamped to [alpha sigma_k, alpha_max sigma_k], grown by the aura.
  // It reaches the cluster's ends along its axes where alpha sigma falls short of them (a flat
  // face's ends lie at sqrt(3) sigma), without the bulge a larger alpha gives every cluster, nor
  // the one a mean-centred ellipsoid needs on the near side to reach an uneven cluster's far end.
  // Without: the paper's ellipsoid (ellipsoidFromSummary's, up to rounding).
  Ellipsoid ellipsoid(const EllipsoidId& id, const EllipsoidParams& params) const;

 private:
  std::uint64_t count_ = 0;
  Eigen::Vector3d mean_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d axes_ = Eigen::Matrix3d::Identity();  // column k: axis k
  Eigen::Vector3d sigma_ = Eigen::Vector3d::Zero();     // standard deviation along axis k
  Eigen::Vector3d low_ = Eigen::Vector3d::Zero();       // smallest projection on axis k (<= 0)
  Eigen::Vector3d high_ = Eigen::Vector3d::Zero();      // largest projection on axis k (>= 0)
};

// Axis-aligned box of the ellipsoid: half extent sqrt(M_dd) along axis d.
Box delimitingBox(const Ellipsoid& e);

// True when the closed ellipsoids share a point (touching counts). Exact up to a relative
// tolerance of 1e-9 on the separating function; shapes must be positive semi-definite and at
// least one of them positive definite.
bool ellipsoidsIntersect(const Eigen::Vector3d& center_a, const Eigen::Matrix3d& shape_a,
                         const Eigen::Vector3d& center_b, const Eigen::Matrix3d& shape_b);
inline bool intersects(const Ellipsoid& a, const Ellipsoid& b) {
  return ellipsoidsIntersect(a.center, a.shape, b.center, b.shape);
}

// True when p lies in the closed ellipsoid.
bool contains(const Ellipsoid& e, const Eigen::Vector3d& p);

}  // namespace fogmap
