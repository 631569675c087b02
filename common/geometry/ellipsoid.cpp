#include "common/geometry/ellipsoid.hpp"
#include "common/geometry/symmetric_eigen.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Cholesky>

namespace fogmap {

std::string toString(const EllipsoidId& id) {
  return std::to_string(id.node) + "/" + std::to_string(id.frame) + "/" + std::to_string(id.index);
}

void ClusterSummary::add(const Eigen::Vector3d& p) {
  if (count_ == 0) reference_ = p;
  const Eigen::Vector3d r = p - reference_;
  ++count_;
  sum_ += r;
  sum_outer_.noalias() += r * r.transpose();
}

void ClusterSummary::absorb(const ClusterSummary& other) {
  if (other.count_ == 0) return;
  if (count_ == 0) {
    *this = other;
    return;
  }
  // Re-express the other's sums relative to our reference: sum (r + o), sum (r + o)(r + o)^T.
  const Eigen::Vector3d o = other.reference_ - reference_;
  const auto n = static_cast<double>(other.count_);
  sum_outer_ += other.sum_outer_ + other.sum_ * o.transpose() + o * other.sum_.transpose() + n * o * o.transpose();
  sum_ += other.sum_ + n * o;
  count_ += other.count_;
}

Eigen::Vector3d ClusterSummary::mean() const {
  if (count_ == 0) return Eigen::Vector3d::Zero();
  return reference_ + sum_ / static_cast<double>(count_);
}

Eigen::Matrix3d ClusterSummary::covariance() const {
  if (count_ == 0) return Eigen::Matrix3d::Zero();
  const auto n = static_cast<double>(count_);
  const Eigen::Vector3d m = sum_ / n;  // relative mean: small, so no cancellation
  Eigen::Matrix3d c = sum_outer_ / n - m * m.transpose();
  c = 0.5 * (c + c.transpose());
  return c;
}

Eigen::Matrix3d withAura(const Eigen::Matrix3d& shape, double delta_m) {
  const SymmetricEigen<3> eigen = symmetricEigen(Eigen::Matrix3d(0.5 * (shape + shape.transpose())));
  const Eigen::Vector3d semi_axes = eigen.values.cwiseMax(0.0).cwiseSqrt().array() + delta_m;
  const Eigen::Matrix3d& v = eigen.vectors;
  Eigen::Matrix3d grown = v * semi_axes.cwiseAbs2().asDiagonal() * v.transpose();
  return 0.5 * (grown + grown.transpose());
}

Ellipsoid ellipsoidFromSummary(const ClusterSummary& summary, const EllipsoidId& id,
                               const EllipsoidParams& params) {
  Ellipsoid e;
  e.id = id;
  e.center = summary.mean();
  e.shape = withAura(params.alpha * params.alpha * summary.covariance(), params.aura_m);
  e.point_count = summary.count();
  return e;
}

ClusterReach::ClusterReach(const ClusterSummary& summary) : count_(summary.count()), mean_(summary.mean()) {
  const SymmetricEigen<3> eigen = symmetricEigen(summary.covariance());
  axes_ = eigen.vectors;
  sigma_ = eigen.values.cwiseMax(0.0).cwiseSqrt();
}

Ellipsoid ClusterReach::ellipsoid(const EllipsoidId& id, const EllipsoidParams& params) const {
  Ellipsoid e;
  e.id = id;
  e.point_count = count_;
  const bool reaches = params.reaches();
  Eigen::Vector3d semi_axes;
  for (int k = 0; k < 3; ++k) {
    const double half_extent = reaches ? 0.5 * (high_[k] - low_[k]) : 0.0;
    semi_axes[k] = std::clamp(half_extent, params.alpha * sigma_[k], std::max(params.alpha, params.alpha_max) * sigma_[k]) +
                   params.aura_m;
  }
  e.center = reaches ? Eigen::Vector3d(mean_ + axes_ * (0.5 * (low_ + high_))) : mean_;
  const Eigen::Matrix3d shape = axes_ * semi_axes.cwiseAbs2().asDiagonal() * axes_.transpose();
  e.shape = 0.5 * (shape + shape.transpose());
  return e;
}

Box delimitingBox(const Ellipsoid& e) {
  const Eigen::Vector3d half = e.shape.diagonal().cwiseMax(0.0).cwiseSqrt();
  return Box{e.center - half, e.center + half};
}

bool contains(const Ellipsoid& e, const Eigen::Vector3d& p) {
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(e.shape);
  const Eigen::Vector3d d = p - e.center;
  return d.dot(ldlt.solve(d)) <= 1.0 + 1e-12;
}

namespace {

// Relative tolerance on "touching": the separating function's maximum may exceed 1 by this much.
constexpr double kTouchTolerance = 1e-9;

// With A = I and B = diag(lambda) after a congruence transform, and v the transformed centre
// offset, the ellipsoids are disjoint iff max over s in [0,1] of
//   f(s) = s (1 - s) sum_i v_i^2 / (s + (1 - s) lambda_i)
// exceeds 1 (Gilitschenski and Hanebeck's convex separating function, K(s) = 1 - f(s)).
// f is concave, so bisection on the sign of f' finds the maximum; we stop as soon as some f(s)
// proves separation or the concavity bound proves overlap.
bool separatingMaximumExceedsOne(const Eigen::Vector3d& v2, const Eigen::Vector3d& lambda) {
  auto value = [&](double s) {
    double f = 0.0;
    for (int i = 0; i < 3; ++i) f += v2[i] / (s + (1.0 - s) * lambda[i]);
    return s * (1.0 - s) * f;
  };
  auto slope = [&](double s) {
    double g = 0.0;
    for (int i = 0; i < 3; ++i) {
      const double den = lambda[i] + s * (1.0 - lambda[i]);
      g += v2[i] * (lambda[i] * (1.0 - 2.0 * s) - (1.0 - lambda[i]) * s * s) / (den * den);
    }
    return g;
  };
  const double limit = 1.0 + kTouchTolerance;
  double lo = 0.0;
  double hi = 1.0;
  for (int iter = 0; iter < 200; ++iter) {
    const double s = 0.5 * (lo + hi);
    const double f = value(s);
    if (f > limit) return true;
    const double g = slope(s);
    // Concavity: f(t) <= f(s) + g (t - s) for every t; the maximiser lies in [lo, hi].
    const double bound = f + std::max(g * (lo - s), g * (hi - s));
    if (bound <= limit) return false;
    if (g > 0.0) {
      lo = s;
    } else if (g < 0.0) {
      hi = s;
    } else {
      return false;  // s is the maximiser and f(s) <= limit
    }
    if (hi - lo < 1e-15) return false;
  }
  return false;
}

}  // namespace

bool ellipsoidsIntersect(const Eigen::Vector3d& center_a, const Eigen::Matrix3d& shape_a,
                         const Eigen::Vector3d& center_b, const Eigen::Matrix3d& shape_b) {
  const Eigen::Vector3d d = center_b - center_a;
  // Cheap exits first: bounding spheres apart, a separating plane across the centre line, or
  // the two ellipsoids meeting on the centre line; the exact test decides the rest.
  const double ra2 = shape_a.trace();  // trace >= largest eigenvalue = largest semi-axis^2
  const double rb2 = shape_b.trace();
  const double dist2 = d.squaredNorm();
  const double rsum = std::sqrt(ra2) + std::sqrt(rb2);
  if (dist2 > rsum * rsum * (1.0 + 1e-12)) return false;
  // Separating plane normal to the centre line: with u = d / |d| the half-widths are
  // sqrt(u^T M u), so the projections are apart when |d|^2 > sqrt(d^T A d) + sqrt(d^T B d).
  const double ha = std::sqrt(std::max(0.0, d.dot(shape_a * d)));
  const double hb = std::sqrt(std::max(0.0, d.dot(shape_b * d)));
  if (dist2 > (ha + hb) * (1.0 + 2.0 * kTouchTolerance)) return false;

  // Congruence transform making one shape the unit sphere. Use the better-conditioned shape:
  // transforming by a nearly flat one amplifies rounding. LLT fails on singular (flat) shapes; at
  // least one of the two must be positive definite.
  auto conditioning = [](const Eigen::LLT<Eigen::Matrix3d>& f) {
    if (f.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
    const Eigen::Vector3d diag = f.matrixLLT().diagonal();
    if (!(diag.minCoeff() > 0.0)) return std::numeric_limits<double>::infinity();
    return diag.maxCoeff() / diag.minCoeff();
  };
  Eigen::LLT<Eigen::Matrix3d> llt_a(shape_a);
  Eigen::LLT<Eigen::Matrix3d> llt_b(shape_b);
  const double cond_a = conditioning(llt_a);
  const double cond_b = conditioning(llt_b);
  if (std::isinf(cond_a) && std::isinf(cond_b)) {
    // Both flat: regularise both by a negligible relative amount.
    const double eps = 1e-12 * std::max(ra2, rb2);
    return ellipsoidsIntersect(center_a, shape_a + eps * Eigen::Matrix3d::Identity(), center_b,
                               shape_b + eps * Eigen::Matrix3d::Identity());
  }
  // On the centre line c_a + t d, A covers t <= 1 / sqrt(d^T A^-1 d) and B covers
  // t >= 1 - 1 / sqrt(d^T B^-1 d): if those intervals meet, so do the ellipsoids.
  const double reach_a = std::isinf(cond_a) ? 0.0 : 1.0 / std::sqrt(d.dot(llt_a.solve(d)));
  const double reach_b = std::isinf(cond_b) ? 0.0 : 1.0 / std::sqrt(d.dot(llt_b.solve(d)));
  if (reach_a + reach_b >= 1.0) return true;

  const bool a_is_base = cond_a <= cond_b;
  const Eigen::LLT<Eigen::Matrix3d>& llt = a_is_base ? llt_a : llt_b;
  const Eigen::Matrix3d* b = a_is_base ? &shape_b : &shape_a;
  const auto l = llt.matrixL();
  // C = L^-1 B L^-T, w = L^-1 d.
  Eigen::Matrix3d c = l.solve(*b);
  c = l.solve(c.transpose()).eval();
  c = 0.5 * (c + c.transpose());
  const Eigen::Vector3d w = l.solve(d);  // the sign of d does not matter: only w_i^2 enters
  // The iterative solver: the closed-form 3x3 one loses small eigenvalues of thin shapes.
  const SymmetricEigen<3> eigen = symmetricEigen(c);
  const Eigen::Vector3d lambda = eigen.values.cwiseMax(0.0);
  const Eigen::Vector3d v = eigen.vectors.transpose() * w;
  return !separatingMaximumExceedsOne(v.cwiseAbs2(), lambda);
}

}  // namespace fogmap
