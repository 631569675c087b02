#include "common/geometry/ellipsoid.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "tests/support/geometry_builders.hpp"

namespace fogmap {
namespace {

// ---------------------------------------------------------------------------------------------
// Helpers.

using test_support::quadraticForm;
using test_support::randomRotation;
using test_support::randomShape;
using test_support::randomUnitVector;
using test_support::shapeOf;
using test_support::sphere;

Ellipsoid ellipsoidAt(const Eigen::Vector3d& center, const Eigen::Matrix3d& shape) {
  Ellipsoid e;
  e.center = center;
  e.shape = shape;
  return e;
}

Ellipsoid axisAligned(const Eigen::Vector3d& center, const Eigen::Vector3d& semi_axes) {
  return ellipsoidAt(center, Eigen::Matrix3d(semi_axes.cwiseAbs2().asDiagonal()));
}

// A matrix root of a positive semi-definite shape (M = R R^T), valid for flat shapes too.
Eigen::Matrix3d rootOf(const Eigen::Matrix3d& shape) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(shape);
  return solver.eigenvectors() * solver.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
}

// Symmetric check, with a message naming the inputs so that a failure can be reproduced.
std::string describe(const Ellipsoid& a, const Ellipsoid& b) {
  std::ostringstream out;
  out.precision(17);
  out << "A centre [" << a.center.transpose() << "] shape [" << a.shape.row(0) << "; "
      << a.shape.row(1) << "; " << a.shape.row(2) << "]\nB centre [" << b.center.transpose()
      << "] shape [" << b.shape.row(0) << "; " << b.shape.row(1) << "; " << b.shape.row(2) << "]";
  return out.str();
}

void expectIntersect(const Ellipsoid& a, const Ellipsoid& b, bool expected) {
  EXPECT_EQ(intersects(a, b), expected) << describe(a, b);
  EXPECT_EQ(intersects(b, a), expected) << "(arguments swapped)\n" << describe(a, b);
}

double relativeError(const Eigen::Matrix3d& actual, const Eigen::Matrix3d& expected) {
  return (actual - expected).norm() / std::max(expected.norm(), 1e-300);
}

// ---------------------------------------------------------------------------------------------
// (1) ClusterSummary.

struct TwoPass {
  Eigen::Vector3d mean;
  Eigen::Matrix3d covariance;
};

// The textbook two-pass computation in long double: mean first, then centred outer products.
TwoPass twoPass(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Matrix<long double, 3, 1> sum = Eigen::Matrix<long double, 3, 1>::Zero();
  for (const auto& p : points) sum += p.cast<long double>();
  const auto n = static_cast<long double>(points.size());
  const Eigen::Matrix<long double, 3, 1> mean = sum / n;
  Eigen::Matrix<long double, 3, 3> c = Eigen::Matrix<long double, 3, 3>::Zero();
  for (const auto& p : points) {
    const Eigen::Matrix<long double, 3, 1> r = p.cast<long double>() - mean;
    c += r * r.transpose();
  }
  return {mean.cast<double>(), (c / n).cast<double>()};
}

std::vector<Eigen::Vector3d> randomCluster(std::mt19937_64& rng, const Eigen::Vector3d& offset,
                                           double spread, std::size_t n) {
  std::normal_distribution<double> normal;
  const Eigen::Matrix3d root = rootOf(randomShape(rng, 0.1 * spread, spread));
  std::vector<Eigen::Vector3d> points(n);
  for (auto& p : points) p = offset + root * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  return points;
}

TEST(EllipsoidClusterSummary, EmptyAndSinglePoint) {
  ClusterSummary empty;
  EXPECT_EQ(empty.count(), 0U);
  ClusterSummary one;
  one.add(Eigen::Vector3d(1e5, -2e5, 3.25));
  EXPECT_EQ(one.count(), 1U);
  EXPECT_EQ(one.mean(), Eigen::Vector3d(1e5, -2e5, 3.25));
  EXPECT_EQ(one.covariance(), Eigen::Matrix3d::Zero());
}

TEST(EllipsoidClusterSummary, MatchesTwoPassFarFromTheOrigin) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (double offset : {0.0, 1e3, 1e5, 1e6}) {
    for (double spread : {0.05, 1.0, 10.0}) {
      const Eigen::Vector3d origin = offset * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
      const std::vector<Eigen::Vector3d> points = randomCluster(rng, origin, spread, 2000);
      ClusterSummary summary;
      for (const auto& p : points) summary.add(p);
      const TwoPass truth = twoPass(points);
      EXPECT_EQ(summary.count(), points.size());
      // The mean to a millionth of the cluster's size; the covariance to 1e-6 relative.
      EXPECT_LT((summary.mean() - truth.mean).norm(), 1e-6 * spread)
          << "offset " << offset << " spread " << spread;
      EXPECT_LT(relativeError(summary.covariance(), truth.covariance), 1e-6)
          << "offset " << offset << " spread " << spread << "\n"
          << summary.covariance() << "\nvs\n" << truth.covariance;
    }
  }
}

TEST(EllipsoidClusterSummary, AddingFloatPointsUsesTheirCoordinates) {
  ClusterSummary from_points;
  ClusterSummary from_vectors;
  const std::vector<Point> points = {{1.5F, 2.0F, -3.0F, 0.1F}, {2.5F, 2.0F, -1.0F, 0.9F}};
  for (const Point& p : points) {
    from_points.add(p);
    from_vectors.add(Eigen::Vector3d(p.x, p.y, p.z));
  }
  EXPECT_EQ(from_points.mean(), from_vectors.mean());
  EXPECT_EQ(from_points.covariance(), from_vectors.covariance());
  EXPECT_EQ(from_points.mean(), Eigen::Vector3d(2.0, 2.0, -2.0));
}

TEST(EllipsoidClusterSummary, AbsorbEqualsAddingAllPoints) {
  std::mt19937_64 rng(2);
  std::uniform_int_distribution<std::size_t> cut(0, 600);
  for (int trial = 0; trial < 50; ++trial) {
    // Parts far apart and far from the origin, so the references differ a lot.
    std::vector<Eigen::Vector3d> all;
    std::vector<ClusterSummary> parts;
    for (int part = 0; part < 3; ++part) {
      const std::size_t n = cut(rng);  // may be empty
      const Eigen::Vector3d offset(1e5 + 3.0 * part, -1e5, 50.0 * part);
      const std::vector<Eigen::Vector3d> points = randomCluster(rng, offset, 2.0, n);
      ClusterSummary s;
      for (const auto& p : points) s.add(p);
      parts.push_back(s);
      all.insert(all.end(), points.begin(), points.end());
    }
    ClusterSummary merged;
    for (const auto& part : parts) merged.absorb(part);
    ClusterSummary direct;
    for (const auto& p : all) direct.add(p);
    ASSERT_EQ(merged.count(), all.size());
    if (all.empty()) continue;
    const TwoPass truth = twoPass(all);
    EXPECT_LT((merged.mean() - direct.mean()).norm(), 1e-9) << trial;
    EXPECT_LT(relativeError(merged.covariance(), direct.covariance()), 1e-9) << trial;
    EXPECT_LT(relativeError(merged.covariance(), truth.covariance), 1e-6) << trial;
  }
}

TEST(EllipsoidClusterSummary, AbsorbingEmptyChangesNothing) {
  ClusterSummary s;
  s.add(Eigen::Vector3d(1, 2, 3));
  s.add(Eigen::Vector3d(2, 2, 5));
  const Eigen::Vector3d mean = s.mean();
  const Eigen::Matrix3d cov = s.covariance();
  s.absorb(ClusterSummary{});
  EXPECT_EQ(s.count(), 2U);
  EXPECT_EQ(s.mean(), mean);
  EXPECT_EQ(s.covariance(), cov);
  ClusterSummary empty;
  empty.absorb(s);
  EXPECT_EQ(empty.count(), 2U);
  EXPECT_EQ(empty.mean(), mean);
  EXPECT_EQ(empty.covariance(), cov);
}

// ---------------------------------------------------------------------------------------------
// (2) withAura, (3) ellipsoidFromSummary.

// The expected grown shape built from the eigen-decomposition in the test.
Eigen::Matrix3d grownShape(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& semi_axes,
                           double delta) {
  return shapeOf(rotation, semi_axes.array() + delta);
}

TEST(EllipsoidWithAura, GrowsEverySemiAxisByDelta) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> axis(0.01, 5.0);
  std::uniform_real_distribution<double> delta(0.0, 1.0);
  for (int trial = 0; trial < 500; ++trial) {
    const Eigen::Matrix3d rotation = randomRotation(rng);
    Eigen::Vector3d semi_axes(axis(rng), axis(rng), axis(rng));
    if (trial % 5 == 0) semi_axes[1] = semi_axes[0];  // repeated eigenvalue
    const double d = delta(rng);
    const Eigen::Matrix3d grown = withAura(shapeOf(rotation, semi_axes), d);
    EXPECT_LT(relativeError(grown, grownShape(rotation, semi_axes, d)), 1e-9) << trial;
    // The semi-axes of the result are sqrt(eigenvalues).
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(grown);
    Eigen::Vector3d expected = semi_axes.array() + d;
    std::sort(expected.begin(), expected.end());
    EXPECT_LT((solver.eigenvalues().cwiseSqrt() - expected).norm(), 1e-9 * expected.norm()) << trial;
  }
}

TEST(EllipsoidWithAura, RepairsFlatAndDegenerateShapes) {
  std::mt19937_64 rng(4);
  const double d = 0.175;
  for (int trial = 0; trial < 100; ++trial) {
    const Eigen::Matrix3d rotation = randomRotation(rng);
    // A disc (one zero eigenvalue) and a segment (two zero eigenvalues).
    for (const Eigen::Vector3d& semi_axes : {Eigen::Vector3d(2.0, 0.5, 0.0), Eigen::Vector3d(3.0, 0.0, 0.0)}) {
      // A rotated flat shape carries rounding noise of order eps |M| in its zero eigenvalue, which
      // the square root turns into a semi-axis of order sqrt(eps |M|) ~ 1e-8: hence 1e-7 here.
      const Eigen::Matrix3d grown = withAura(shapeOf(rotation, semi_axes), d);
      EXPECT_LT(relativeError(grown, grownShape(rotation, semi_axes, d)), 1e-7) << trial;
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(grown);
      EXPECT_NEAR(std::sqrt(solver.eigenvalues()[0]), d, 1e-7) << trial;
    }
  }
  // Without rotation the zero eigenvalue is exact, and so is the result.
  EXPECT_LT(relativeError(withAura(Eigen::Vector3d(4.0, 0.25, 0.0).asDiagonal().toDenseMatrix(), d),
                          Eigen::Vector3d(2 + d, 0.5 + d, d).cwiseAbs2().asDiagonal().toDenseMatrix()),
            1e-12);
  // A point cluster becomes a ball of radius delta.
  EXPECT_LT(relativeError(withAura(Eigen::Matrix3d::Zero(), d), d * d * Eigen::Matrix3d::Identity()),
            1e-12);
  // Rounding may leave an eigenvalue slightly negative; it still counts as zero.
  Eigen::Matrix3d nearly_flat = Eigen::Vector3d(1.0, 1.0, -1e-17).asDiagonal();
  EXPECT_LT(relativeError(withAura(nearly_flat, d),
                          Eigen::Vector3d(1 + d, 1 + d, d).cwiseAbs2().asDiagonal().toDenseMatrix()),
            1e-12);
}

TEST(EllipsoidWithAura, ZeroDeltaKeepsTheShape) {
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Matrix3d shape = randomShape(rng, 0.1, 3.0);
    EXPECT_LT(relativeError(withAura(shape, 0.0), shape), 1e-12) << trial;
  }
}

TEST(EllipsoidFromSummary, CentreIsMeanAndShapeIsGrownScaledCovariance) {
  std::mt19937_64 rng(6);
  const EllipsoidId id{7, 123456789012ULL, 42};
  for (const EllipsoidParams params : {EllipsoidParams{}, EllipsoidParams{0.8, 0.0},
                                       EllipsoidParams{2.4, 0.5}}) {
    const std::vector<Eigen::Vector3d> points = randomCluster(rng, {300.0, -20.0, 1.0}, 1.5, 500);
    ClusterSummary summary;
    for (const auto& p : points) summary.add(p);
    const Ellipsoid e = ellipsoidFromSummary(summary, id, params);
    EXPECT_EQ(e.id, id);
    EXPECT_EQ(e.node(), 7U);
    EXPECT_EQ(e.point_count, 500U);
    EXPECT_LT((e.center - summary.mean()).norm(), 1e-12 * summary.mean().norm());
    const TwoPass truth = twoPass(points);
    // Expected shape: V (sqrt(alpha^2 L) + delta)^2 V^T from the test's own decomposition.
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(truth.covariance);
    const Eigen::Matrix3d expected = grownShape(
        solver.eigenvectors(), params.alpha * solver.eigenvalues().cwiseMax(0.0).cwiseSqrt(),
        params.aura_m);
    EXPECT_LT(relativeError(e.shape, expected), 1e-6) << params.alpha << " " << params.aura_m;
    EXPECT_LT(relativeError(e.shape, withAura(params.alpha * params.alpha * summary.covariance(),
                                              params.aura_m)),
              1e-12);
  }
}

TEST(EllipsoidFromSummary, SinglePointGivesABallOfTheAura) {
  ClusterSummary summary;
  summary.add(Eigen::Vector3d(4, 5, 6));
  const Ellipsoid e = ellipsoidFromSummary(summary, {}, EllipsoidParams{1.5, 0.2});
  EXPECT_EQ(e.center, Eigen::Vector3d(4, 5, 6));
  EXPECT_LT(relativeError(e.shape, 0.04 * Eigen::Matrix3d::Identity()), 1e-12);
}

// ---------------------------------------------------------------------------------------------
// (3b) ClusterReach: ellipsoids that reach their clusters' ends along their axes.

template <typename Points>
ClusterReach reachOf(const Points& points) {
  ClusterSummary summary;
  for (const auto& p : points) summary.add(p);
  ClusterReach reach(summary);
  for (const auto& p : points) reach.add(p);
  return reach;
}

TEST(ClusterReach, AFlatFaceReachesItsEndsWhereTheMeanCentredEllipsoidStopsShort) {
  // A face 4 m long and 1.5 m high (a car's side), turned by 30 degrees, far from the origin, on a
  // grid: its ends lie at sqrt(3 (n - 1) / (n + 1)) sigma, between alpha 1.5 and alpha_max 2.5.
  const Eigen::Vector3d along(std::cos(std::numbers::pi / 6.0), std::sin(std::numbers::pi / 6.0), 0.0);
  const Eigen::Vector3d up(0.0, 0.0, 1.0);
  const Eigen::Vector3d middle(300.0, -20.0, 1.0);
  std::vector<Eigen::Vector3d> face;
  for (int i = 0; i <= 80; ++i) {
    for (int j = 0; j <= 15; ++j) face.push_back(middle + (-2.0 + 0.05 * i) * along + (-0.75 + 0.1 * j) * up);
  }
  const EllipsoidParams params{1.5, 0.175, 2.5};
  const Ellipsoid e = reachOf(face).ellipsoid({1, 2, 3}, params);
  EXPECT_EQ(e.id, (EllipsoidId{1, 2, 3}));
  EXPECT_EQ(e.point_count, face.size());
  EXPECT_LT((e.center - middle).norm(), 1e-9);
  // The semi-axes are the half extents plus the aura; across the face only the aura is left.
  for (const double sign : {-1.0, 1.0}) {
    EXPECT_NEAR(quadraticForm(e, middle + sign * (2.0 + params.aura_m) * along), 1.0, 1e-9);
    EXPECT_NEAR(quadraticForm(e, middle + sign * (0.75 + params.aura_m) * up), 1.0, 1e-9);
    EXPECT_NEAR(quadraticForm(e, middle + sign * params.aura_m * along.cross(up)), 1.0, 1e-9);
  }
  // The paper's ellipsoid at the same alpha does not hold the face's ends, even with its aura.
  ClusterSummary summary;
  for (const auto& p : face) summary.add(p);
  const Ellipsoid paper = ellipsoidFromSummary(summary, {}, params);
  EXPECT_GT(quadraticForm(paper, middle + 2.0 * along), 1.0);
  EXPECT_GT(quadraticForm(paper, middle - 2.0 * along), 1.0);
}

TEST(ClusterReach, AnUnevenClusterIsCentredOnItsExtentNotOnItsMean) {
  // 90 points on [0, 1] and 10 on [1, 4] along x: the mean lies at 0.7, the extent's middle at 2.
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 90; ++i) line.emplace_back(i / 89.0, 0.0, 0.0);
  for (int i = 1; i <= 10; ++i) line.emplace_back(1.0 + 0.3 * i, 0.0, 0.0);
  const ClusterReach reach = reachOf(line);
  ClusterSummary summary;
  for (const auto& p : line) summary.add(p);
  const double sigma = std::sqrt(summary.covariance()(0, 0));
  ASSERT_GT(3.0 * sigma, 2.0);  // the half extent lies within [1.5 sigma, 3 sigma]
  ASSERT_LT(1.5 * sigma, 2.0);
  const EllipsoidParams wide{1.5, 0.175, 3.0};
  const Ellipsoid e = reach.ellipsoid({}, wide);
  EXPECT_LT((e.center - Eigen::Vector3d(2.0, 0.0, 0.0)).norm(), 1e-9);
  EXPECT_NEAR(quadraticForm(e, {-0.175, 0.0, 0.0}), 1.0, 1e-9);
  EXPECT_NEAR(quadraticForm(e, {4.175, 0.0, 0.0}), 1.0, 1e-9);
  // A mean-centred ellipsoid that reaches x = 4 bulges a metre and more past x = 0.
  const Ellipsoid paper = ellipsoidFromSummary(summary, {}, EllipsoidParams{3.0, 0.175});
  EXPECT_LT(quadraticForm(paper, {-1.0, 0.0, 0.0}), 1.0);
  // With alpha_max 2.5 the half extent is cut to 2.5 sigma, still about the extent's middle.
  const Ellipsoid capped = reach.ellipsoid({}, EllipsoidParams{1.5, 0.175, 2.5});
  EXPECT_LT((capped.center - Eigen::Vector3d(2.0, 0.0, 0.0)).norm(), 1e-9);
  EXPECT_NEAR(quadraticForm(capped, {2.0 + 2.5 * sigma + 0.175, 0.0, 0.0}), 1.0, 1e-9);
}

TEST(ClusterReach, AlphaBoundsTheSemiAxesFromBelowAndWithoutReachItIsThePapersEllipsoid) {
  // Two points at +-1: sigma 1, half extent 1, below alpha sigma.
  const std::vector<Eigen::Vector3d> pair{{-1.0, 0.0, 0.0}, {1.0, 0.0, 0.0}};
  const Ellipsoid e = reachOf(pair).ellipsoid({}, EllipsoidParams{1.5, 0.2, 2.5});
  EXPECT_NEAR(quadraticForm(e, {1.7, 0.0, 0.0}), 1.0, 1e-9);
  EXPECT_NEAR(quadraticForm(e, {0.0, 0.2, 0.0}), 1.0, 1e-9);
  // alpha_max at most alpha: the paper's ellipsoid, centred on the mean.
  std::mt19937_64 rng(11);
  for (const EllipsoidParams params : {EllipsoidParams{1.5, 0.175}, EllipsoidParams{2.4, 0.0, 1.0}}) {
    const std::vector<Eigen::Vector3d> points = randomCluster(rng, {-50.0, 80.0, 2.0}, 1.0, 400);
    ClusterSummary summary;
    for (const auto& p : points) summary.add(p);
    const Ellipsoid paper = ellipsoidFromSummary(summary, {}, params);
    const Ellipsoid same = reachOf(points).ellipsoid({}, params);
    EXPECT_FALSE(params.reaches());
    EXPECT_LT((same.center - paper.center).norm(), 1e-12 * paper.center.norm());
    EXPECT_LT(relativeError(same.shape, paper.shape), 1e-9);
  }
}

TEST(ClusterReach, TwoFacesOfACornerSeenByTwoSensorsMeetAndFacesAnEpsApartDoNot) {
  // A 4 x 4 m footprint's two faces at its corner (4, 0): one sensor sees y = 0, x in [0, 4], the
  // other x = 4, y in [0, 4]; both 1.5 m high. The points of the two faces meet at the corner.
  std::vector<Eigen::Vector3d> south;
  std::vector<Eigen::Vector3d> east;
  for (int i = 0; i <= 40; ++i) {
    for (int j = 0; j <= 15; ++j) {
      south.emplace_back(0.1 * i, 0.0, 0.1 * j);
      east.emplace_back(4.0, 0.1 * i, 0.1 * j);
    }
  }
  const EllipsoidParams reach{1.5, 0.175, 2.5};
  const EllipsoidParams paper{1.5, 0.175};
  EXPECT_TRUE(intersects(reachOf(south).ellipsoid({1, 0, 0}, reach), reachOf(east).ellipsoid({2, 0, 0}, reach)));
  EXPECT_FALSE(intersects(reachOf(south).ellipsoid({1, 0, 0}, paper), reachOf(east).ellipsoid({2, 0, 0}, paper)));
  // The same face continued past a gap along its axis: joined below eps = 2 x aura, apart above.
  for (const double gap : {0.3, 0.4}) {
    std::vector<Eigen::Vector3d> next;
    for (const auto& p : south) next.push_back(p + Eigen::Vector3d(4.0 + gap, 0.0, 0.0));
    EXPECT_EQ(intersects(reachOf(south).ellipsoid({1, 0, 0}, reach), reachOf(next).ellipsoid({2, 0, 0}, reach)), gap < 0.35)
        << gap;
  }
}

// ---------------------------------------------------------------------------------------------
// (4) delimitingBox.

TEST(EllipsoidDelimitingBox, HalfExtentIsSqrtOfDiagonal) {
  const Ellipsoid e = ellipsoidAt({1, 2, 3}, Eigen::Vector3d(4.0, 9.0, 0.25).asDiagonal());
  const Box box = delimitingBox(e);
  EXPECT_EQ(box.min, Eigen::Vector3d(-1.0, -1.0, 2.5));
  EXPECT_EQ(box.max, Eigen::Vector3d(3.0, 5.0, 3.5));
}

TEST(EllipsoidDelimitingBox, ContainsSampledSurfaceAndIsTight) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> position(-100.0, 100.0);
  for (int trial = 0; trial < 20; ++trial) {
    // Every fifth ellipsoid is flat (a disc).
    Eigen::Matrix3d shape = randomShape(rng, 0.1, 3.0);
    if (trial % 5 == 0) {
      shape = shapeOf(randomRotation(rng), Eigen::Vector3d(2.0, 0.7, 0.0));
    }
    const Ellipsoid e = ellipsoidAt({position(rng), position(rng), position(rng)}, shape);
    const Box box = delimitingBox(e);
    for (int d = 0; d < 3; ++d) {
      EXPECT_NEAR(box.max[d] - e.center[d], std::sqrt(shape(d, d)), 1e-12 * (1 + std::abs(e.center[d])));
      EXPECT_NEAR(e.center[d] - box.min[d], std::sqrt(shape(d, d)), 1e-12 * (1 + std::abs(e.center[d])));
    }
    const Eigen::Matrix3d root = rootOf(shape);
    Eigen::Vector3d closest_to_min = Eigen::Vector3d::Constant(1e9);
    Eigen::Vector3d closest_to_max = Eigen::Vector3d::Constant(1e9);
    for (int i = 0; i < 200000; ++i) {
      const Eigen::Vector3d p = e.center + root * randomUnitVector(rng);
      for (int d = 0; d < 3; ++d) {
        ASSERT_GE(p[d], box.min[d] - 1e-9) << trial;
        ASSERT_LE(p[d], box.max[d] + 1e-9) << trial;
        closest_to_min[d] = std::min(closest_to_min[d], p[d] - box.min[d]);
        closest_to_max[d] = std::min(closest_to_max[d], box.max[d] - p[d]);
      }
    }
    EXPECT_LT(closest_to_min.maxCoeff(), 1e-3) << trial << ": box not tight at a min face";
    EXPECT_LT(closest_to_max.maxCoeff(), 1e-3) << trial << ": box not tight at a max face";
  }
}

TEST(EllipsoidBox, OverlapIsClosedAndExtendIsUnion) {
  const Box a{{0, 0, 0}, {1, 1, 1}};
  const Box touching{{1, 0.5, 0.5}, {2, 2, 2}};
  const Box apart{{1.0 + 1e-12, 0, 0}, {2, 1, 1}};
  EXPECT_TRUE(a.overlaps(touching));
  EXPECT_TRUE(touching.overlaps(a));
  EXPECT_FALSE(a.overlaps(apart));
  EXPECT_FALSE(apart.overlaps(a));
  Box u;
  EXPECT_TRUE(u.empty());
  u.extend(a);
  u.extend(apart);
  EXPECT_FALSE(u.empty());
  EXPECT_EQ(u, (Box{{0, 0, 0}, {2, 1, 1}}));
}

// ---------------------------------------------------------------------------------------------
// (5) ellipsoidsIntersect against a sampling oracle.

struct Bounds {
  double upper = 0.0;  // attained at a point of A: the true minimum is at most this
  double lower = 0.0;  // proven: the true minimum is at least this
};

// Points of the unit ball, half of them on its surface; drawn once with a fixed seed and mapped
// into each ellipsoid by x = c + L u.
const std::vector<Eigen::Vector3d>& unitBallSamples() {
  static const std::vector<Eigen::Vector3d> samples = [] {
    std::mt19937_64 rng(424242);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::vector<Eigen::Vector3d> points(20000);
    for (std::size_t i = 0; i < points.size(); ++i) {
      const double r = i % 2 == 0 ? 1.0 : std::cbrt(unit(rng));  // uniform in the ball
      points[i] = r * randomUnitVector(rng);
    }
    return points;
  }();
  return samples;
}

// Bounds on min over x in A of q_B(x) = (x - c_b)^T M_b^-1 (x - c_b); the ellipsoids intersect iff
// that minimum is <= 1. With x = c_a + L_a u, |u| <= 1, q_B = |K u + k|^2 is a convex quadratic on
// the unit ball: dense samples of the ball and its sphere give a start, projected (accelerated)
// gradient descent refines it, and the Frank-Wolfe gap f(u) - min_{|y|<=1} grad f(u).(y - u)
// gives a rigorous lower bound. Both shapes must be positive definite. Without samples the descent
// starts at the centre of A; the problem is convex, so only speed suffers.
Bounds minMahalanobis(const Ellipsoid& a, const Ellipsoid& b, bool sample = true) {
  const Eigen::Matrix3d la = Eigen::LLT<Eigen::Matrix3d>(a.shape).matrixL();
  const Eigen::LLT<Eigen::Matrix3d> llt_b(b.shape);
  const Eigen::Matrix3d k_mat = llt_b.matrixL().solve(la);
  const Eigen::Vector3d k_vec = llt_b.matrixL().solve(a.center - b.center);
  auto f = [&](const Eigen::Vector3d& u) { return (k_mat * u + k_vec).squaredNorm(); };
  auto grad = [&](const Eigen::Vector3d& u) { return Eigen::Vector3d(2.0 * k_mat.transpose() * (k_mat * u + k_vec)); };
  auto project = [](const Eigen::Vector3d& u) {
    const double n = u.norm();
    return n > 1.0 ? Eigen::Vector3d(u / n) : u;
  };

  Eigen::Vector3d best = Eigen::Vector3d::Zero();
  double best_value = f(best);
  static const std::vector<Eigen::Vector3d> kNoSamples;
  for (const Eigen::Vector3d& u : sample ? unitBallSamples() : kNoSamples) {
    const double value = f(u);
    if (value < best_value) {
      best_value = value;
      best = u;
    }
  }

  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> spectrum(k_mat.transpose() * k_mat);
  const double lipschitz = 2.0 * spectrum.eigenvalues().maxCoeff();
  double lower = -1e300;
  Eigen::Vector3d x = best;
  Eigen::Vector3d x_prev = best;
  Eigen::Vector3d y = best;
  double t = 1.0;
  for (int iter = 0; iter < 3000; ++iter) {
    x = project(y - grad(y) / lipschitz);
    const double value = f(x);
    const Eigen::Vector3d g = grad(x);
    lower = std::max(lower, value - g.dot(x) - g.norm());
    if (value < best_value) {
      best_value = value;
      best = x;
    }
    if (value > f(x_prev)) {  // restart the momentum when it overshoots
      t = 1.0;
      y = x;
    } else {
      const double t_next = 0.5 * (1.0 + std::sqrt(1.0 + 4.0 * t * t));
      y = x + ((t - 1.0) / t_next) * (x - x_prev);
      t = t_next;
    }
    x_prev = x;
    if (best_value - lower < 1e-9 * (1.0 + best_value)) break;
  }
  return {best_value, std::max(0.0, lower)};
}

enum class Truth { kIntersect, kSeparate, kUnsure };

Truth oracle(const Ellipsoid& a, const Ellipsoid& b) {
  const Bounds ab = minMahalanobis(a, b);
  const Bounds ba = minMahalanobis(b, a);
  const bool surely_intersect = std::min(ab.upper, ba.upper) < 1.0 - 1e-3;
  const bool surely_separate = std::max(ab.lower, ba.lower) > 1.0 + 1e-3;
  EXPECT_FALSE(surely_intersect && surely_separate) << "oracle inconsistent\n" << describe(a, b);
  if (surely_intersect) return Truth::kIntersect;
  if (surely_separate) return Truth::kSeparate;
  return Truth::kUnsure;
}

// Semi-axes uniform in [min_axis, max_axis], or log-uniform for strongly elongated shapes.
struct AxisRange {
  double min_axis;
  double max_axis;
  bool log_uniform = false;
  double max_distance_factor = 1.6;  // centre distance / sum of extents along the centre line
};

Eigen::Matrix3d randomShape(std::mt19937_64& rng, const AxisRange& range) {
  if (!range.log_uniform) return randomShape(rng, range.min_axis, range.max_axis);
  std::uniform_real_distribution<double> log_axis(std::log(range.min_axis), std::log(range.max_axis));
  return shapeOf(randomRotation(rng), Eigen::Vector3d(std::exp(log_axis(rng)), std::exp(log_axis(rng)),
                                                      std::exp(log_axis(rng))));
}

// Random pair with the centres at a distance comparable to the sum of the extents along the
// centre line, so that about half of the pairs intersect.
std::pair<Ellipsoid, Ellipsoid> randomPair(std::mt19937_64& rng, const AxisRange& range) {
  std::uniform_real_distribution<double> position(-500.0, 500.0);
  std::uniform_real_distribution<double> factor(0.0, range.max_distance_factor);
  const Ellipsoid a = ellipsoidAt({position(rng), position(rng), position(rng)}, randomShape(rng, range));
  const Eigen::Matrix3d shape_b = randomShape(rng, range);
  const Eigen::Vector3d dir = randomUnitVector(rng);
  const double reach = std::sqrt(dir.dot(a.shape * dir)) + std::sqrt(dir.dot(shape_b * dir));
  return {a, ellipsoidAt(a.center + factor(rng) * reach * dir, shape_b)};
}

void checkAgainstOracle(std::uint64_t seed, int pairs, const AxisRange& range) {
  std::mt19937_64 rng(seed);
  int intersecting = 0;
  int separate = 0;
  int unsure = 0;
  int failures = 0;
  for (int trial = 0; trial < pairs; ++trial) {
    const auto [a, b] = randomPair(rng, range);
    const bool ab = intersects(a, b);
    const bool ba = intersects(b, a);
    EXPECT_EQ(ab, ba) << "asymmetric, trial " << trial << "\n" << describe(a, b);
    switch (oracle(a, b)) {
      case Truth::kIntersect:
        ++intersecting;
        if (!ab && ++failures <= 10) {
          ADD_FAILURE() << "trial " << trial << ": oracle found a common point, test says disjoint\n"
                        << describe(a, b);
        }
        break;
      case Truth::kSeparate:
        ++separate;
        if (ab && ++failures <= 10) {
          ADD_FAILURE() << "trial " << trial << ": oracle proved disjoint, test says intersect\n"
                        << describe(a, b);
        }
        break;
      case Truth::kUnsure: ++unsure; break;
    }
  }
  EXPECT_EQ(failures, 0);
  EXPECT_LT(unsure, pairs / 10) << "too many pairs the oracle cannot decide";
  EXPECT_GT(intersecting, pairs / 4);
  EXPECT_GT(separate, pairs / 4);
}

TEST(EllipsoidsIntersect, AgreesWithSamplingOracleOnRandomPairs) {
  checkAgainstOracle(20240611, 2000, {0.1, 3.0});
}

TEST(EllipsoidsIntersect, AgreesWithSamplingOracleOnElongatedPairs) {
  checkAgainstOracle(31337, 2000, {0.02, 5.0, true, 1.3});
}

TEST(EllipsoidsIntersect, AgreesWithSamplingOracleOnNeedlesAndDiscs) {
  checkAgainstOracle(4711, 2000, {0.002, 10.0, true, 1.0});
}

// Pairs moved along the centre line to just before and just after first contact. The contact
// distance is bracketed by bisection on the oracle's proven bounds, with a margin of 1e-4 on the
// Mahalanobis value: far tighter than the random pairs above.
TEST(EllipsoidsIntersect, AgreesWithOracleJustBeforeAndAfterContact) {
  std::mt19937_64 rng(2718);
  constexpr double kMargin = 1e-4;
  int failures = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const AxisRange range = trial % 2 == 0 ? AxisRange{0.1, 3.0} : AxisRange{0.01, 5.0, true};
    const Ellipsoid a = ellipsoidAt({30.0, -20.0, 1.0}, randomShape(rng, range));
    const Eigen::Matrix3d shape_b = randomShape(rng, range);
    const Eigen::Vector3d dir = randomUnitVector(rng);
    const double reach = std::sqrt(dir.dot(a.shape * dir)) + std::sqrt(dir.dot(shape_b * dir));
    auto at = [&](double t) { return ellipsoidAt(a.center + t * reach * dir, shape_b); };
    auto surelyIntersect = [&](double t) {
      const Ellipsoid b = at(t);
      return std::min(minMahalanobis(a, b, false).upper, minMahalanobis(b, a, false).upper) < 1.0 - kMargin;
    };
    auto surelySeparate = [&](double t) {
      const Ellipsoid b = at(t);
      return std::max(minMahalanobis(a, b, false).lower, minMahalanobis(b, a, false).lower) > 1.0 + kMargin;
    };
    // Contact happens at some t in (0, 1]: the centres coincide at 0, the supports touch at 1.
    double in_lo = 0.0;
    double in_hi = 1.0 + 1e-3;
    double out_lo = 0.0;
    double out_hi = 1.0 + 1e-3;
    ASSERT_TRUE(surelySeparate(out_hi)) << trial;
    for (int iter = 0; iter < 40; ++iter) {
      const double in_mid = 0.5 * (in_lo + in_hi);
      (surelyIntersect(in_mid) ? in_lo : in_hi) = in_mid;
      const double out_mid = 0.5 * (out_lo + out_hi);
      (surelySeparate(out_mid) ? out_hi : out_lo) = out_mid;
    }
    ASSERT_LT(in_lo, out_hi) << trial;
    const Ellipsoid before = at(in_lo);
    const Ellipsoid after = at(out_hi);
    if ((!intersects(a, before) || !intersects(before, a)) && ++failures <= 10) {
      ADD_FAILURE() << "trial " << trial << ": just before contact (t = " << in_lo
                    << "), reported disjoint\n" << describe(a, before);
    }
    if ((intersects(a, after) || intersects(after, a)) && ++failures <= 10) {
      ADD_FAILURE() << "trial " << trial << ": just after contact (t = " << out_hi
                    << "), reported intersecting\n" << describe(a, after);
    }
  }
  EXPECT_EQ(failures, 0);
}

// Homothetic pairs (shape_b = k^2 shape_a) have an exact answer: they intersect iff
// d^T shape_a^-1 d <= (1 + k)^2. This reaches conditioning a sampling oracle cannot.
TEST(EllipsoidsIntersect, ExactOnHomotheticPairs) {
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> log_axis(-3.0, 1.0);
  std::uniform_real_distribution<double> log_scale(-2.0, 2.0);
  std::uniform_real_distribution<double> position(-1000.0, 1000.0);
  int failures = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Eigen::Vector3d semi_axes(std::pow(10.0, log_axis(rng)), std::pow(10.0, log_axis(rng)),
                                    std::pow(10.0, log_axis(rng)));
    const Eigen::Matrix3d rotation = randomRotation(rng);
    const double k = std::pow(10.0, log_scale(rng));
    const Ellipsoid a = ellipsoidAt({position(rng), position(rng), position(rng)},
                                    shapeOf(rotation, semi_axes));
    // Offset (1 + k) t R diag(semi_axes) u, |u| = 1, so d^T shape_a^-1 d = ((1 + k) t)^2.
    const Eigen::Vector3d u = randomUnitVector(rng);
    const Eigen::Vector3d step = (1.0 + k) * (rotation * semi_axes.asDiagonal() * u);
    for (double t : {0.5, 1.0 - 1e-6, 1.0 + 1e-6, 2.0}) {
      const Ellipsoid b = ellipsoidAt(a.center + t * step, k * k * a.shape);
      const bool expected = t < 1.0;
      if ((intersects(a, b) != expected || intersects(b, a) != expected) && ++failures <= 10) {
        ADD_FAILURE() << "trial " << trial << " t " << t << " k " << k << " semi-axes "
                      << semi_axes.transpose() << ": expected " << expected << "\n" << describe(a, b);
      }
    }
  }
  EXPECT_EQ(failures, 0);
}

// ---------------------------------------------------------------------------------------------
// (6) Hard cases.

TEST(EllipsoidsIntersect, TouchingSpheresIntersect) {
  expectIntersect(sphere({0, 0, 0}, 1.0), sphere({3, 0, 0}, 2.0), true);
  // Along an oblique direction, and far from the origin.
  const Eigen::Vector3d dir = Eigen::Vector3d(1, -2, 0.5).normalized();
  const Eigen::Vector3d c(1e4, -2e4, 30);
  expectIntersect(sphere(c, 0.3), sphere(c + 0.8 * dir, 0.5), true);
}

TEST(EllipsoidsIntersect, SpheresWithTinyGapDoNotIntersect) {
  expectIntersect(sphere({0, 0, 0}, 1.0), sphere({3.0 * (1 + 1e-6), 0, 0}, 2.0), false);
  const Eigen::Vector3d dir = Eigen::Vector3d(1, -2, 0.5).normalized();
  const Eigen::Vector3d c(1e4, -2e4, 30);
  expectIntersect(sphere(c, 0.3), sphere(c + 0.8 * (1 + 1e-6) * dir, 0.5), false);
}

TEST(EllipsoidsIntersect, TouchingEllipsoidsTipToSide) {
  // Tip of a long x-axis ellipsoid (semi-axis 3) against the side of one with x semi-axis 1.
  const Ellipsoid long_one = axisAligned({0, 0, 0}, {3, 1, 1});
  expectIntersect(long_one, axisAligned({4, 0, 0}, {1, 2, 0.5}), true);
  expectIntersect(long_one, axisAligned({4 + 4e-6, 0, 0}, {1, 2, 0.5}), false);
  // The same along y: the long one's side (1) against the other's tip (2).
  expectIntersect(long_one, axisAligned({0, 3, 0}, {1, 2, 0.5}), true);
  expectIntersect(long_one, axisAligned({0, 3 + 3e-6, 0}, {1, 2, 0.5}), false);
}

TEST(EllipsoidsIntersect, NestedIntersectInBothOrders) {
  expectIntersect(sphere({0, 0, 0}, 10.0), sphere({8, 0, 0}, 0.5), true);
  expectIntersect(sphere({0, 0, 0}, 10.0), sphere({0, 0, 0}, 0.001), true);
  expectIntersect(axisAligned({5, 5, 5}, {10, 3, 2}), axisAligned({12, 5, 5}, {0.5, 0.2, 0.2}), true);
  // A thin needle inside a ball.
  expectIntersect(sphere({0, 0, 0}, 5.0), axisAligned({1, 1, 1}, {2, 1e-3, 1e-3}), true);
}

TEST(EllipsoidsIntersect, IdenticalIntersect) {
  std::mt19937_64 rng(9);
  for (int trial = 0; trial < 100; ++trial) {
    const Ellipsoid e = ellipsoidAt({1e5, -3e4, 12}, randomShape(rng, 1e-3, 10.0));
    expectIntersect(e, e, true);
  }
  const Ellipsoid disc = axisAligned({1, 2, 3}, {1, 1, 1e-6});
  expectIntersect(disc, disc, true);
}

TEST(EllipsoidsIntersect, FarApartDoNotIntersect) {
  expectIntersect(sphere({0, 0, 0}, 1.0), sphere({1e6, 0, 0}, 1.0), false);
  expectIntersect(axisAligned({0, 0, 0}, {100, 1, 1}), axisAligned({0, 1e6, 1e6}, {1, 100, 1}), false);
  expectIntersect(sphere({1e6, 1e6, 1e6}, 3.0), sphere({-1e6, -1e6, -1e6}, 3.0), false);
}

TEST(EllipsoidsIntersect, FlatDiscAgainstSphere) {
  // A disc of radius 1 in the xy plane, thickness 2e-6 (eigenvalue 1e-12).
  const Ellipsoid disc = axisAligned({0, 0, 0}, {1, 1, 1e-6});
  expectIntersect(disc, sphere({0, 0, 1.0 + 1e-6}, 1.0), true);   // touching the face
  expectIntersect(disc, sphere({0, 0, 0.5}, 1.0), true);
  expectIntersect(disc, sphere({0, 0, 1.0001}, 1.0), false);      // a gap of 1e-4 above it
  expectIntersect(disc, sphere({0, 0, -1.0001}, 1.0), false);
  expectIntersect(disc, sphere({2, 0, 0}, 1.0), true);            // touching the rim
  expectIntersect(disc, sphere({2.0001, 0, 0}, 1.0), false);
  expectIntersect(disc, sphere({0.5, 0.5, 0.9}, 0.2), false);     // above the middle
  // A disc with an exactly zero eigenvalue (the sphere is positive definite).
  const Ellipsoid flat = axisAligned({0, 0, 0}, {1, 1, 0});
  expectIntersect(flat, sphere({0, 0, 1.0}, 1.0), true);
  expectIntersect(flat, sphere({0, 0, 0.3}, 0.5), true);
  expectIntersect(flat, sphere({0, 0, 1.001}, 1.0), false);
  expectIntersect(flat, sphere({1.5, 0, 0.1}, 0.4), false);
  expectIntersect(flat, sphere({1.2, 0, 0}, 0.2), true);  // touching the rim in its plane
}

TEST(EllipsoidsIntersect, ThinDiscsRotatedAndTranslated) {
  // Rotating and translating both members of a pair must not change the answer.
  std::mt19937_64 rng(10);
  const Ellipsoid disc = axisAligned({0, 0, 0}, {1, 1, 1e-6});
  struct Case {
    Ellipsoid other;
    bool expected;
  };
  const std::vector<Case> cases = {
      {axisAligned({0, 0, 0.5}, {1, 1, 1e-6}), false},     // parallel disc above
      {axisAligned({1.5, 0, 0}, {1, 1, 1e-6}), true},      // coplanar, overlapping
      {axisAligned({2.0001, 0, 0}, {1, 1, 1e-6}), false},  // coplanar, apart
      {axisAligned({0.5, 0, 0.5}, {1, 1e-6, 1}), true},    // perpendicular, crossing
      {axisAligned({0, 0, 1.2}, {1, 1e-6, 1}), false},     // perpendicular, above
      {sphere({0, 0, 1.0001}, 1.0), false},
      {sphere({0, 0, 0.9999}, 1.0), true},
  };
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Matrix3d r = randomRotation(rng);
    const Eigen::Vector3d t(1e3 * trial, -50.0, 7.0);
    const Ellipsoid moved = ellipsoidAt(t, r * disc.shape * r.transpose());
    for (std::size_t i = 0; i < cases.size(); ++i) {
      const Ellipsoid other = ellipsoidAt(t + r * cases[i].other.center,
                                          r * cases[i].other.shape * r.transpose());
      EXPECT_EQ(intersects(moved, other), cases[i].expected) << "case " << i << " trial " << trial
                                                             << "\n" << describe(moved, other);
      EXPECT_EQ(intersects(other, moved), cases[i].expected)
          << "case " << i << " trial " << trial << " (arguments swapped)\n" << describe(moved, other);
    }
  }
}

TEST(EllipsoidsIntersect, NeedlesCrossingAtRightAngles) {
  // Needles of length 20 and radius 0.01 along x and along y.
  const Ellipsoid along_x = axisAligned({0, 0, 0}, {10, 0.01, 0.01});
  // Centred at x = 3, 0.015 above: at x = 3 the x-needle reaches z = 0.01 sqrt(0.91) = 0.00954,
  // the y-needle reaches down to 0.005, so they overlap.
  expectIntersect(along_x, axisAligned({3, 0, 0.015}, {0.01, 10, 0.01}), true);
  expectIntersect(along_x, axisAligned({0, 0, 0}, {0.01, 10, 0.01}), true);
  expectIntersect(along_x, axisAligned({0, 5, 0}, {0.01, 10, 0.01}), true);  // off-centre
  // 0.025 above: z <= 0.01 on the first, z >= 0.015 on the second.
  expectIntersect(along_x, axisAligned({3, 0, 0.025}, {0.01, 10, 0.01}), false);
  // Touching exactly: crossing at the middle, 0.02 apart.
  expectIntersect(along_x, axisAligned({0, 0, 0.02}, {0.01, 10, 0.01}), true);
  expectIntersect(along_x, axisAligned({0, 0, 0.02 + 1e-7}, {0.01, 10, 0.01}), false);
  // Beyond the tip of the x-needle.
  expectIntersect(along_x, axisAligned({10.02, 0, 0}, {0.01, 10, 0.01}), false);
  expectIntersect(along_x, axisAligned({10.0, 0, 0}, {0.01, 10, 0.01}), true);
}

TEST(EllipsoidsIntersect, ParallelNeedlesWithAGap) {
  const Ellipsoid a = axisAligned({0, 0, 0}, {10, 0.01, 0.01});
  expectIntersect(a, axisAligned({0, 0.021, 0}, {10, 0.01, 0.01}), false);
  expectIntersect(a, axisAligned({5, 0.021, 0}, {10, 0.01, 0.01}), false);
  expectIntersect(a, axisAligned({0, 0.02, 0}, {10, 0.01, 0.01}), true);   // touching
  expectIntersect(a, axisAligned({5, 0.015, 0}, {10, 0.01, 0.01}), true);  // overlapping, shifted
  // Identical needles shifted along x by s and across by h: same shape, so they intersect iff
  // (s/20)^2 + (h/0.02)^2 <= 1.
  expectIntersect(a, axisAligned({12, 0.0159, 0}, {10, 0.01, 0.01}), true);   // 0.36 + 0.632 < 1
  expectIntersect(a, axisAligned({12, 0.0161, 0}, {10, 0.01, 0.01}), false);  // 0.36 + 0.648 > 1
  // End to end on one line.
  expectIntersect(a, axisAligned({20, 0, 0}, {10, 0.01, 0.01}), true);
  expectIntersect(a, axisAligned({20.0001, 0, 0}, {10, 0.01, 0.01}), false);
}

TEST(EllipsoidsIntersect, NeedlesRotatedAndTranslated) {
  std::mt19937_64 rng(11);
  const Ellipsoid a = axisAligned({0, 0, 0}, {10, 0.01, 0.01});
  struct Case {
    Ellipsoid other;
    bool expected;
  };
  const std::vector<Case> cases = {
      {axisAligned({3, 0, 0.015}, {0.01, 10, 0.01}), true},
      {axisAligned({3, 0, 0.025}, {0.01, 10, 0.01}), false},
      {axisAligned({0, 0.021, 0}, {10, 0.01, 0.01}), false},
      {axisAligned({5, 0.015, 0}, {10, 0.01, 0.01}), true},
      {axisAligned({12, 0.0159, 0}, {10, 0.01, 0.01}), true},
      {axisAligned({12, 0.0161, 0}, {10, 0.01, 0.01}), false},
  };
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Matrix3d r = randomRotation(rng);
    const Eigen::Vector3d t(-400.0 + trial, 300.0, 2.0);
    const Ellipsoid moved = ellipsoidAt(t, r * a.shape * r.transpose());
    for (std::size_t i = 0; i < cases.size(); ++i) {
      const Ellipsoid other = ellipsoidAt(t + r * cases[i].other.center,
                                          r * cases[i].other.shape * r.transpose());
      EXPECT_EQ(intersects(moved, other), cases[i].expected) << "case " << i << " trial " << trial
                                                             << "\n" << describe(moved, other);
      EXPECT_EQ(intersects(other, moved), cases[i].expected)
          << "case " << i << " trial " << trial << " (arguments swapped)\n" << describe(moved, other);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// (7) contains.

TEST(EllipsoidContains, CentreSurfaceAndOutside) {
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> position(-1e3, 1e3);
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Matrix3d shape = randomShape(rng, 0.01, 5.0);
    const Ellipsoid e = ellipsoidAt({position(rng), position(rng), position(rng)}, shape);
    const Eigen::Matrix3d root = rootOf(shape);
    EXPECT_TRUE(contains(e, e.center));
    for (int i = 0; i < 20; ++i) {
      const Eigen::Vector3d u = randomUnitVector(rng);
      EXPECT_TRUE(contains(e, e.center + (1.0 - 1e-9) * (root * u))) << trial;
      EXPECT_TRUE(contains(e, e.center + 0.5 * (root * u))) << trial;
      EXPECT_FALSE(contains(e, e.center + (1.0 + 1e-6) * (root * u))) << trial;
      EXPECT_FALSE(contains(e, e.center + 3.0 * (root * u))) << trial;
    }
  }
}

TEST(EllipsoidContains, SurfacePointsOfAxisAlignedEllipsoid) {
  const Ellipsoid e = axisAligned({1, 2, 3}, {3, 2, 1});
  EXPECT_TRUE(contains(e, {4, 2, 3}));
  EXPECT_TRUE(contains(e, {1, 0, 3}));
  EXPECT_TRUE(contains(e, {1, 2, 2}));
  EXPECT_FALSE(contains(e, {4.001, 2, 3}));
  EXPECT_FALSE(contains(e, {3.5, 3.5, 3}));  // inside the box, outside the ellipsoid
  EXPECT_TRUE(contains(e, {1 + 3 * std::sqrt(0.5) * 0.999, 2 + 2 * std::sqrt(0.5) * 0.999, 3}));
}

TEST(EllipsoidContains, ThinDisc) {
  const Ellipsoid disc = axisAligned({0, 0, 0}, {1, 1, 1e-6});
  EXPECT_TRUE(contains(disc, {0.5, 0.5, 0}));
  EXPECT_TRUE(contains(disc, {0, 0, 0.9e-6}));
  EXPECT_FALSE(contains(disc, {0, 0, 1e-3}));
  EXPECT_FALSE(contains(disc, {0.8, 0.8, 0}));
}

TEST(EllipsoidId, OrderedByNodeThenFrameThenIndex) {
  EXPECT_LT((EllipsoidId{1, 9, 9}), (EllipsoidId{2, 0, 0}));
  EXPECT_LT((EllipsoidId{1, 1, 9}), (EllipsoidId{1, 2, 0}));
  EXPECT_LT((EllipsoidId{1, 1, 1}), (EllipsoidId{1, 1, 2}));
  EXPECT_EQ((EllipsoidId{3, 4, 5}), (EllipsoidId{3, 4, 5}));
  EXPECT_NE(toString(EllipsoidId{1, 2, 3}), toString(EllipsoidId{1, 23, 0}));
}

}  // namespace
}  // namespace fogmap
