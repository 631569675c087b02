#include "common/geometry/compact_ellipsoid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
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
using test_support::randomUnitVector;
using test_support::shapeOf;

// An ellipsoid known by its parts: centre, rotation (column i = direction of semi-axis i) and
// semi-axes, so the test has its own exact surface and normals.
struct Parts {
  Eigen::Vector3d center;
  Eigen::Matrix3d rotation;
  Eigen::Vector3d semi_axes;
};

Ellipsoid ellipsoidOf(const Parts& parts, const EllipsoidId& id = {}, std::uint64_t point_count = 0) {
  Ellipsoid e;
  e.id = id;
  e.center = parts.center;
  e.shape = shapeOf(parts.rotation, parts.semi_axes);
  e.point_count = point_count;
  return e;
}

// The parts of any ellipsoid, from the test's own eigen-decomposition.
Parts partsOf(const Ellipsoid& e) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(e.shape);
  return {e.center, solver.eigenvectors(), solver.eigenvalues().cwiseMax(0.0).cwiseSqrt()};
}

double logUniform(std::mt19937_64& rng, double lo, double hi) {
  std::uniform_real_distribution<double> u(std::log(lo), std::log(hi));
  return std::exp(u(rng));
}

// Semi-axes log-uniform in [0.01, 30] m, with every fifth a near-sphere, an exact sphere, a needle
// or a disc.
Eigen::Vector3d randomSemiAxes(std::mt19937_64& rng, int trial) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const double a = logUniform(rng, 0.01, 30.0);
  switch (trial % 10) {
    case 0: return {a, a * (1.0 + 1e-9 * unit(rng)), a * (1.0 + 1e-7 * unit(rng))};  // near-sphere
    case 1: return {a, a, a};                                                        // sphere
    case 2: return {logUniform(rng, 5.0, 30.0), 0.01 * (1.0 + 0.5 * (1 + unit(rng))), 0.01};  // needle
    case 3: return {logUniform(rng, 5.0, 30.0), logUniform(rng, 5.0, 30.0), 0.01};        // disc
    default: return {a, logUniform(rng, 0.01, 30.0), logUniform(rng, 0.01, 30.0)};
  }
}

// A random ellipsoid within 300 m per axis of an origin somewhere within 100 km.
struct Sample {
  Parts parts;
  Ellipsoid exact;
  CompactOrigin origin;
};

Sample randomSampleNear(std::mt19937_64& rng, int trial, const CompactOrigin& origin) {
  std::uniform_real_distribution<double> near(-300.0, 300.0);
  std::uniform_int_distribution<std::uint32_t> u16(0, 65535);
  const Eigen::Vector3d base(origin.x_cm / 100.0, origin.y_cm / 100.0, origin.z_cm / 100.0);
  Parts parts{base + Eigen::Vector3d(near(rng), near(rng), near(rng)), randomRotation(rng),
              randomSemiAxes(rng, trial)};
  const Ellipsoid exact = ellipsoidOf(parts, EllipsoidId{5, 77, u16(rng)}, u16(rng));
  return {parts, exact, origin};
}

Sample randomSample(std::mt19937_64& rng, int trial) {
  std::uniform_real_distribution<double> far(-1e5, 1e5);
  return randomSampleNear(rng, trial, compactOriginNear({far(rng), far(rng), far(rng)}));
}

Ellipsoid roundTrip(const Ellipsoid& e, const CompactOrigin& origin) {
  std::string bytes;
  EXPECT_TRUE(appendCompact(e, origin, bytes));
  EXPECT_EQ(bytes.size(), kCompactEllipsoidBytes);
  Expected<Ellipsoid> decoded = decodeCompact(bytes, origin, e.id.node, e.id.frame);
  EXPECT_TRUE(decoded.ok()) << (decoded.ok() ? "" : decoded.error().message);
  return decoded.ok() ? decoded.value() : e;
}

std::string describe(const Ellipsoid& e) {
  std::ostringstream out;
  out.precision(17);
  out << "centre [" << e.center.transpose() << "] shape [" << e.shape.row(0) << "; " << e.shape.row(1)
      << "; " << e.shape.row(2) << "]";
  return out.str();
}

// Points of `from`'s surface pushed outward along its normal by `distance`, that lie in the interior
// of `to`. None when every point of to's surface lies within distance of from's: to is inside the
// outer parallel body of from, whose boundary the pushed points are. Samples are random directions
// and the six ends of the axes.
int pushedPointsInside(const Parts& from, const Ellipsoid& to, double distance, std::mt19937_64& rng,
                       int samples) {
  int inside = 0;
  for (int i = 0; i < samples + 6; ++i) {
    const Eigen::Vector3d u =
        i < 6 ? Eigen::Vector3d(Eigen::Vector3d::Unit(i / 2) * (i % 2 == 0 ? 1.0 : -1.0)) : randomUnitVector(rng);
    const Eigen::Vector3d p = from.center + from.rotation * from.semi_axes.cwiseProduct(u);
    const Eigen::Vector3d normal = (from.rotation * u.cwiseQuotient(from.semi_axes)).normalized();
    // A relative 1e-9 on the Mahalanobis value is a radial 5e-10: well under a micrometre here.
    if (quadraticForm(to, p + distance * normal) < 1.0 - 1e-9) ++inside;
  }
  return inside;
}

// ---------------------------------------------------------------------------------------------
// (1) The format.

TEST(CompactEllipsoidFormat, RecordIsTwentyTwoBytesAndRecordsConcatenate) {
  std::mt19937_64 rng(101);
  const CompactOrigin origin = compactOriginNear({1234.5, -678.9, 10.0});
  std::string block = "header";  // appending keeps what is there
  std::vector<std::string> singles;
  std::vector<Ellipsoid> exact;
  for (int trial = 0; trial < 200; ++trial) {
    const Sample s = randomSampleNear(rng, trial, origin);
    std::string single;
    ASSERT_TRUE(appendCompact(s.exact, origin, single)) << trial;
    ASSERT_EQ(single.size(), kCompactEllipsoidBytes) << trial;
    const std::size_t before = block.size();
    ASSERT_TRUE(appendCompact(s.exact, origin, block)) << trial;
    ASSERT_EQ(block.size(), before + kCompactEllipsoidBytes) << trial;
    singles.push_back(single);
    exact.push_back(s.exact);
  }
  ASSERT_EQ(block.substr(0, 6), "header");
  const std::string_view records = std::string_view(block).substr(6);
  ASSERT_EQ(records.size(), 200 * kCompactEllipsoidBytes);
  Expected<std::vector<Ellipsoid>> all = decodeCompactBlock(records, origin, 5, 77);
  ASSERT_TRUE(all.ok()) << all.error().message;
  ASSERT_EQ(all->size(), 200U);
  for (std::size_t i = 0; i < singles.size(); ++i) {
    EXPECT_EQ(records.substr(i * kCompactEllipsoidBytes, kCompactEllipsoidBytes), singles[i]) << i;
    Expected<Ellipsoid> one = decodeCompact(singles[i], origin, 5, 77);
    ASSERT_TRUE(one.ok()) << one.error().message;
    EXPECT_EQ((*all)[i], *one) << i;
    EXPECT_EQ((*all)[i].id, exact[i].id) << i;
  }
  // The same ellipsoid packs to the same bytes.
  std::string again;
  ASSERT_TRUE(appendCompact(exact[0], origin, again));
  EXPECT_EQ(again, singles[0]);
}

TEST(CompactEllipsoidFormat, AxisAlignedEllipsoidHasTheDocumentedBytes) {
  Ellipsoid e;
  e.id = EllipsoidId{9, 3, 7};
  e.center = {1.23, -4.56, 7.89};
  e.shape = Eigen::Vector3d(0.01, 0.04, 0.09).asDiagonal();
  e.point_count = 1234;
  const CompactOrigin origin{100, 0, -50};
  std::string bytes;
  ASSERT_TRUE(appendCompact(e, origin, bytes));
  const std::array<unsigned char, kCompactEllipsoidBytes> expected = {
      0x17, 0x00, 0x38, 0xFE, 0x47, 0x03,  // centre 23, -456, 839 cm from the origin
      0x64, 0x00, 0xC8, 0x00, 0x2C, 0x01,  // semi-axes 100, 200, 300 mm, ascending
      0xFF, 0xBF, 0xFF, 0xDF, 0xFF, 0x0F,  // q = (1, 0, 0, 0): w dropped, x y z at code 16383
      0xD2, 0x04,                          // point_count 1234
      0x07, 0x00};                         // index 7
  ASSERT_EQ(bytes.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(static_cast<unsigned char>(bytes[i]), expected[i]) << "byte " << i;
  }
  Expected<Ellipsoid> decoded = decodeCompact(bytes, origin, 9, 3);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_EQ(decoded->id, e.id);
  EXPECT_EQ(decoded->point_count, 1234U);
  EXPECT_EQ(decoded->center, Eigen::Vector3d(1.23, -4.56, 7.89));
  EXPECT_LT((decoded->shape - e.shape).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(CompactEllipsoidFormat, HandWrittenRecordDecodesToTheDocumentedShape) {
  // A quarter turn about z, q = (1/sqrt2, 0, 0, 1/sqrt2): z dropped (index 3), w x y kept as codes
  // 32766, 16383, 16383; W = 32766 | 16383 << 15 | 16383 << 30 | 3 << 45.
  const std::array<unsigned char, kCompactEllipsoidBytes> record = {
      0xFF, 0xFF, 0x00, 0x80, 0xFF, 0x7F,  // centre -1, -32768, 32767 cm
      0x64, 0x00, 0xC8, 0x00, 0x2C, 0x01,  // semi-axes 0.1, 0.2, 0.3 m
      0xFE, 0xFF, 0xFF, 0xDF, 0xFF, 0x6F,  // orientation
      0xFF, 0xFF,                          // point_count 65535
      0x34, 0x12};                         // index 0x1234
  const std::string bytes(record.begin(), record.end());
  const CompactOrigin origin{-100, 0, std::numeric_limits<std::int32_t>::max()};
  Expected<Ellipsoid> e = decodeCompact(bytes, origin, 4000000000U, 1ULL << 40);
  ASSERT_TRUE(e.ok()) << e.error().message;
  EXPECT_EQ(e->id, (EllipsoidId{4000000000U, 1ULL << 40, 0x1234}));
  EXPECT_EQ(e->point_count, 65535U);
  EXPECT_EQ(e->center, Eigen::Vector3d(-1.01, -327.68, (2147483647.0 + 32767.0) / 100.0));
  // The 0.1 m axis turned from x onto y.
  const Eigen::Matrix3d expected = Eigen::Vector3d(0.04, 0.01, 0.09).asDiagonal();
  EXPECT_LT((e->shape - expected).cwiseAbs().maxCoeff(), 1e-12) << describe(*e);
}

// ---------------------------------------------------------------------------------------------
// (2) Round trips against the stated error bound.

TEST(CompactEllipsoidRoundTrip, CentreAndSemiAxesWithinHalfAStep) {
  std::mt19937_64 rng(102);
  for (int trial = 0; trial < 5000; ++trial) {
    const Sample s = randomSample(rng, trial);
    ASSERT_TRUE(fitsCompact(s.exact, s.origin)) << trial << " " << describe(s.exact);
    const Ellipsoid decoded = roundTrip(s.exact, s.origin);
    EXPECT_EQ(decoded.id, s.exact.id) << trial;
    EXPECT_EQ(decoded.point_count, s.exact.point_count) << trial;
    EXPECT_LE((decoded.center - s.exact.center).cwiseAbs().maxCoeff(), kCompactCentreErrorM + 1e-9) << trial;
    Eigen::Vector3d exact_axes = s.parts.semi_axes;
    std::sort(exact_axes.begin(), exact_axes.end());
    const Eigen::Vector3d decoded_axes = partsOf(decoded).semi_axes;  // ascending
    EXPECT_LE((decoded_axes - exact_axes).cwiseAbs().maxCoeff(), kCompactSemiAxisErrorM + 1e-9)
        << trial << " exact " << exact_axes.transpose() << " decoded " << decoded_axes.transpose();
    EXPECT_EQ(decoded.shape, decoded.shape.transpose()) << trial;
  }
}

TEST(CompactEllipsoidRoundTrip, EachSurfaceWithinTheStatedBoundOfTheOther) {
  std::mt19937_64 rng(103);
  int oracle_caught = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const Sample s = randomSample(rng, trial);
    const Ellipsoid decoded = roundTrip(s.exact, s.origin);
    const double bound = compactSurfaceErrorBound(s.parts.semi_axes.maxCoeff());
    // The decoded ellipsoid lies in the exact one's outer parallel body at distance `bound`, and
    // the other way round: the Hausdorff distance of the two is at most the bound.
    EXPECT_EQ(pushedPointsInside(s.parts, decoded, bound, rng, 64), 0)
        << trial << " bound " << bound << "\nexact " << describe(s.exact) << "\ndecoded " << describe(decoded);
    EXPECT_EQ(pushedPointsInside(partsOf(decoded), s.exact, bound, rng, 64), 0)
        << trial << " bound " << bound << "\nexact " << describe(s.exact) << "\ndecoded " << describe(decoded);
    // The oracle sees an error of twice the bound: the exact ellipsoid moved along its longest axis.
    if (trial % 10 == 0) {
      Ellipsoid moved = s.exact;
      Eigen::Index longest = 0;
      s.parts.semi_axes.maxCoeff(&longest);
      moved.center += 2.0 * bound * s.parts.rotation.col(longest);
      oracle_caught += pushedPointsInside(s.parts, moved, bound, rng, 64) > 0 ? 1 : 0;
    }
  }
  EXPECT_EQ(oracle_caught, 300);
}

TEST(CompactEllipsoidRoundTrip, AxisDirectionsWithinTheStatedAngle) {
  // With distinct semi-axes the decoded shape's eigenvectors are the decoded rotation's columns, so
  // the angle between matching axes is at most the rotation error theta.
  std::mt19937_64 rng(104);
  double worst = 0.0;
  for (int trial = 0; trial < 3000; ++trial) {
    Sample s = randomSample(rng, trial);
    const double a = logUniform(rng, 0.05, 10.0);
    s.parts.semi_axes = Eigen::Vector3d(a, 2.0 * a, 4.0 * a);
    s.exact = ellipsoidOf(s.parts);
    const Parts decoded = partsOf(roundTrip(s.exact, s.origin));
    for (int i = 0; i < 3; ++i) {
      const double cosine = std::min(1.0, std::abs(decoded.rotation.col(i).dot(s.parts.rotation.col(i))));
      const double angle = std::acos(cosine);
      worst = std::max(worst, angle);
      EXPECT_LE(angle, kCompactOrientationErrorRad) << trial << " axis " << i;
    }
  }
  // Quantisation does turn the axes (the bound is not vacuous), by up to about half of theta.
  EXPECT_GT(worst, 0.1 * kCompactOrientationErrorRad);
}

TEST(CompactEllipsoidRoundTrip, ReencodingADecodedEllipsoidWithDistinctSemiAxesChangesNothing) {
  // A relay that decodes and packs again (an aggregator forwarding upward) does not drift when the
  // shape fixes its axes: the decoded values sit on the grid, so they pack to the same bytes.
  std::mt19937_64 rng(107);
  for (int trial = 0; trial < 2000; ++trial) {
    Sample s = randomSample(rng, trial);
    const double a = logUniform(rng, 0.02, 10.0);
    s.parts.semi_axes = Eigen::Vector3d(a, 1.5 * a, 3.0 * a);
    s.exact = ellipsoidOf(s.parts, s.exact.id, s.exact.point_count);
    std::string first;
    ASSERT_TRUE(appendCompact(s.exact, s.origin, first));
    std::string second;
    ASSERT_TRUE(appendCompact(decodeCompact(first, s.origin, 5, 77).value(), s.origin, second)) << trial;
    EXPECT_EQ(first, second) << trial;
  }
}

TEST(CompactEllipsoidRoundTrip, ReencodingMovesTheSurfaceByAtMostTheBound) {
  // Where two semi-axes are equal in mm (needles, discs, spheres) the shape leaves the rotation
  // about the third free, the eigen-solver picks another one off the grid, and packing again rounds
  // it anew: the shape may move, but by no more than one hop's bound.
  std::mt19937_64 rng(108);
  int moved = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Sample s = randomSample(rng, trial);
    const Ellipsoid once = roundTrip(s.exact, s.origin);
    const Ellipsoid twice = roundTrip(once, s.origin);
    EXPECT_EQ(twice.center, once.center) << trial;
    EXPECT_EQ(twice.id, once.id) << trial;
    EXPECT_EQ(twice.point_count, once.point_count) << trial;
    const Parts once_parts = partsOf(once);
    const double bound = compactSurfaceErrorBound(once_parts.semi_axes.maxCoeff());
    EXPECT_EQ(pushedPointsInside(once_parts, twice, bound, rng, 32), 0) << trial;
    EXPECT_EQ(pushedPointsInside(partsOf(twice), once, bound, rng, 32), 0) << trial;
    if ((twice.shape - once.shape).cwiseAbs().maxCoeff() > 1e-9 * once.shape.norm()) ++moved;
  }
  // The needles (one trial in ten) are where it happens.
  EXPECT_GT(moved, 0);
}

// ---------------------------------------------------------------------------------------------
// (3) Intersection kept away from the threshold.

// Outer approximation of E(M) (+) ball(d): E((1 + 1/p) M + (1 + p) d^2 I) for any p > 0.
Ellipsoid grown(const Ellipsoid& e, double d, double p) {
  Ellipsoid g = e;
  g.shape = (1.0 + 1.0 / p) * e.shape + (1.0 + p) * d * d * Eigen::Matrix3d::Identity();
  return g;
}

// An ellipsoid E_in with E_in (+) ball(d) inside E(M), by the same bound solved for E_in:
// M_in = p / (1 + p) (M - (1 + p) d^2 I), when that is positive definite.
std::optional<Ellipsoid> shrunk(const Ellipsoid& e, double d, double p, double smallest_axis) {
  if (!(p > 0.0) || !((1.0 + p) * d * d < 0.999 * smallest_axis * smallest_axis)) return std::nullopt;
  Ellipsoid s = e;
  s.shape = p / (1.0 + p) * (e.shape - (1.0 + p) * d * d * Eigen::Matrix3d::Identity());
  return s;
}

// Grown and shrunk sets for a few p around the optimum for each axis (p = a/d grows axis a by
// exactly d; p = a/d - 1 shrinks it by exactly d).
std::vector<Ellipsoid> grownSet(const Ellipsoid& e, const Eigen::Vector3d& axes, double d) {
  std::vector<Ellipsoid> out;
  for (int i = 0; i < 3; ++i) out.push_back(grown(e, d, axes[i] / d));
  return out;
}

std::vector<Ellipsoid> shrunkSet(const Ellipsoid& e, const Eigen::Vector3d& axes, double d) {
  std::vector<Ellipsoid> out;
  const double smallest = axes.minCoeff();
  for (const double p : {smallest / d - 1.0, 0.5 * (smallest * smallest / (d * d) - 1.0),
                         0.9 * (smallest * smallest / (d * d) - 1.0)}) {
    if (auto s = shrunk(e, d, p, smallest)) out.push_back(*s);
  }
  return out;
}

TEST(CompactEllipsoidIntersection, AnswerKeptForPairsAwayFromTheThreshold) {
  std::mt19937_64 rng(105);
  std::uniform_real_distribution<double> reach(0.0, 1.2);
  int robust_apart = 0;
  int robust_meeting = 0;
  for (int trial = 0; trial < 8000; ++trial) {
    const Sample a = randomSample(rng, trial);
    Sample b = randomSample(rng, trial / 10);
    // b near a, at a random fraction of the sum of their longest semi-axes.
    b.parts.center = a.parts.center + reach(rng) * (a.parts.semi_axes.maxCoeff() + b.parts.semi_axes.maxCoeff()) *
                                          randomUnitVector(rng);
    b.exact = ellipsoidOf(b.parts);
    b.origin = a.origin;
    if (!fitsCompact(b.exact, b.origin)) continue;
    const double da = compactSurfaceErrorBound(a.parts.semi_axes.maxCoeff());
    const double db = compactSurfaceErrorBound(b.parts.semi_axes.maxCoeff());
    const bool exact = intersects(a.exact, b.exact);
    bool robust = false;
    if (exact) {
      for (const Ellipsoid& sa : shrunkSet(a.exact, a.parts.semi_axes, da)) {
        for (const Ellipsoid& sb : shrunkSet(b.exact, b.parts.semi_axes, db)) robust = robust || intersects(sa, sb);
      }
    } else {
      for (const Ellipsoid& ga : grownSet(a.exact, a.parts.semi_axes, da)) {
        for (const Ellipsoid& gb : grownSet(b.exact, b.parts.semi_axes, db)) robust = robust || !intersects(ga, gb);
      }
    }
    if (!robust) continue;
    (exact ? robust_meeting : robust_apart) += 1;
    const Ellipsoid decoded_a = roundTrip(a.exact, a.origin);
    const Ellipsoid decoded_b = roundTrip(b.exact, b.origin);
    EXPECT_EQ(intersects(decoded_a, decoded_b), exact)
        << trial << "\nA " << describe(a.exact) << "\nB " << describe(b.exact);
  }
  // Enough of each kind for the check to mean something.
  EXPECT_GT(robust_apart, 500);
  EXPECT_GT(robust_meeting, 500);
}

// ---------------------------------------------------------------------------------------------
// (4) What does not fit.

TEST(CompactEllipsoidFits, RefusesWhatCannotBePacked) {
  const CompactOrigin origin{1000, -2000, 300};
  Ellipsoid ok;
  ok.id = EllipsoidId{1, 2, 3};
  ok.center = {10.0, -20.0, 3.0};
  ok.shape = shapeOf(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix(),
                     Eigen::Vector3d(0.2, 1.0, 4.0));
  ok.point_count = 100;
  ASSERT_TRUE(fitsCompact(ok, origin));

  auto refused = [&](const Ellipsoid& e, const char* why) {
    EXPECT_FALSE(fitsCompact(e, origin)) << why;
    std::string out = "kept";
    EXPECT_FALSE(appendCompact(e, origin, out)) << why;
    EXPECT_EQ(out, "kept") << why << ": nothing appended";
  };
  Ellipsoid e = ok;
  e.center.x() = std::numeric_limits<double>::quiet_NaN();
  refused(e, "NaN centre");
  e = ok;
  e.center.z() = std::numeric_limits<double>::infinity();
  refused(e, "infinite centre");
  e = ok;
  e.shape(0, 1) = e.shape(1, 0) = std::numeric_limits<double>::quiet_NaN();
  refused(e, "NaN shape");
  e = ok;
  e.center = {10.0 + 400.0, -20.0, 3.0};
  refused(e, "centre 400 m from the origin");
  e = ok;
  e.center = {10.0, -20.0 - 327.70, 3.0};
  refused(e, "centre 327.70 m from the origin");
  e = ok;
  e.shape = shapeOf(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.2, 1.0, 80.0));
  refused(e, "semi-axis 80 m");
  e = ok;
  e.shape = shapeOf(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.0001, 1.0, 2.0));
  refused(e, "semi-axis 0.1 mm");
  e = ok;
  e.shape = Eigen::Vector3d(1.0, 2.0, -0.01).asDiagonal();
  refused(e, "a negative eigenvalue");
  e = ok;
  e.shape = Eigen::Vector3d(1.0, 2.0, 0.0).asDiagonal();
  refused(e, "a flat shape");
  e = ok;
  e.shape(0, 1) += 0.1;
  refused(e, "an asymmetric shape");
  e = ok;
  e.point_count = 70000;
  refused(e, "point_count 70000");
  e = ok;
  e.id.index = 70000;
  refused(e, "index 70000");

  // The edges of the ranges fit.
  e = ok;
  e.center = {10.0 + 327.67, -20.0 - 327.67, 3.0 + 327.67};
  EXPECT_TRUE(fitsCompact(e, origin)) << "centre 327.67 m from the origin";
  e = ok;
  e.shape = shapeOf(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.001, 1.0, 65.5));
  EXPECT_TRUE(fitsCompact(e, origin)) << "semi-axes 1 mm and 65.5 m";
  e = ok;
  e.point_count = 65535;
  e.id.index = 65535;
  EXPECT_TRUE(fitsCompact(e, origin)) << "point_count and index 65535";
  e = ok;
  e.shape = shapeOf(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.001, 1.0, 65.5356));
  refused(e, "a semi-axis of 65.5356 m (rounds to 65,536 mm)");
}

// A decoded record fits a record again, also at the ends of the semi-axis range, where the shape
// rebuilt in double may put an axis a hair beyond the record's value (a relay re-encodes what it
// decoded; found by fuzz_upload, fuzz/corpus/fuzz_upload/relay_of_one_node_blocks_far_apart).
TEST(CompactEllipsoid, DecodedRecordsAtTheEndsOfTheRangesFitARecordAgain) {
  std::mt19937_64 rng(65535);
  const CompactOrigin origin{0, 0, 0};
  for (int k = 0; k < 2000; ++k) {
    Ellipsoid e;
    e.id = {4, 17, 20};
    e.center = {-20.0, 5.0, -0.01};
    e.shape = shapeOf(randomRotation(rng), Eigen::Vector3d(0.001, 59.392, 65.535));
    e.point_count = 6992;
    std::string record;
    ASSERT_TRUE(appendCompact(e, origin, record)) << k;
    const auto decoded = decodeCompact(record, origin, 4, 17);
    ASSERT_TRUE(decoded.ok()) << decoded.error().message;
    ASSERT_TRUE(fitsCompact(*decoded, origin)) << "rotation " << k;
  }
}

TEST(CompactEllipsoidOrigin, RoundsToCentimetresAndClamps) {
  EXPECT_EQ(compactOriginNear({1.234, -5.675, 0.004}), (CompactOrigin{123, -568, 0}));
  EXPECT_EQ(compactOriginNear({1e9, -1e9, std::numeric_limits<double>::quiet_NaN()}),
            (CompactOrigin{std::numeric_limits<std::int32_t>::max(), std::numeric_limits<std::int32_t>::min(), 0}));
}

// ---------------------------------------------------------------------------------------------
// (5) Bad records.

std::string recordWith(std::uint16_t semi_axis_1_mm, std::uint64_t orientation) {
  std::string r(kCompactEllipsoidBytes, '\0');
  r[6] = r[10] = 1;  // semi-axes 0 and 2: 1 mm
  r[8] = static_cast<char>(semi_axis_1_mm & 0xFF);
  r[9] = static_cast<char>(semi_axis_1_mm >> 8);
  for (int i = 0; i < 6; ++i) r[12 + i] = static_cast<char>((orientation >> (8 * i)) & 0xFF);
  r[20] = 42;  // index
  return r;
}

constexpr std::uint64_t kIdentity = 16383ULL | 16383ULL << 15 | 16383ULL << 30;

TEST(CompactEllipsoidDecode, RefusesBadRecordsNamingTheField) {
  ASSERT_TRUE(decodeCompact(recordWith(5, kIdentity), {}, 3, 9).ok());

  auto refusal = [](std::string_view record) {
    Expected<Ellipsoid> e = decodeCompact(record, {}, 3, 9);
    EXPECT_FALSE(e.ok());
    if (e.ok()) return std::string();
    EXPECT_EQ(e.error().code, ErrorCode::kInvalidArgument);
    return e.error().message;
  };
  std::string message = refusal(recordWith(0, kIdentity));
  EXPECT_NE(message.find("3/9/42"), std::string::npos) << message;
  EXPECT_NE(message.find("semi-axis 1 is 0"), std::string::npos) << message;
  // Three kept components of 1/sqrt2: squared norm 3/2.
  message = refusal(recordWith(5, 32766ULL | 32766ULL << 15 | 32766ULL << 30));
  EXPECT_NE(message.find("orientation"), std::string::npos) << message;
  EXPECT_NE(message.find("squared norm 1.5"), std::string::npos) << message;
  message = refusal(recordWith(5, kIdentity | 1ULL << 47));
  EXPECT_NE(message.find("reserved bit"), std::string::npos) << message;
  message = refusal(recordWith(5, kIdentity).substr(0, 21));
  EXPECT_NE(message.find("22 bytes, got 21"), std::string::npos) << message;

  // In a block, the message says which record.
  const std::string block = recordWith(5, kIdentity) + recordWith(5, kIdentity) + recordWith(0, kIdentity);
  Expected<std::vector<Ellipsoid>> decoded = decodeCompactBlock(block, {}, 3, 9);
  ASSERT_FALSE(decoded.ok());
  EXPECT_NE(decoded.error().message.find("record 2 of 3"), std::string::npos) << decoded.error().message;
  decoded = decodeCompactBlock(block.substr(0, 50), {}, 3, 9);
  ASSERT_FALSE(decoded.ok());
  EXPECT_NE(decoded.error().message.find("50 bytes"), std::string::npos) << decoded.error().message;
  decoded = decodeCompactBlock("", {}, 3, 9);
  ASSERT_TRUE(decoded.ok());
  EXPECT_TRUE(decoded->empty());
}

TEST(CompactEllipsoidDecode, HostileRecordsGivePositiveDefiniteShapesOrAreRefused) {
  std::mt19937_64 rng(106);
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_int_distribution<int> pick(0, 7);
  std::uniform_int_distribution<std::int32_t> any_cm(std::numeric_limits<std::int32_t>::min(),
                                                     std::numeric_limits<std::int32_t>::max());
  const std::array<std::uint16_t, 6> edges = {0, 1, 0x7FFF, 0x8000, 0xFFFE, 0xFFFF};
  int decoded = 0;
  int refused = 0;
  for (int trial = 0; trial < 50000; ++trial) {
    // Half-words random or at the edges of their ranges; the reserved bit cleared in most records,
    // so that the other checks are reached.
    std::string record(kCompactEllipsoidBytes, '\0');
    for (std::size_t i = 0; i < kCompactEllipsoidBytes; i += 2) {
      const int how = pick(rng);
      const std::uint16_t v = how < 5 ? static_cast<std::uint16_t>(byte(rng) | byte(rng) << 8) : edges[static_cast<std::size_t>(byte(rng)) % edges.size()];
      record[i] = static_cast<char>(v & 0xFF);
      record[i + 1] = static_cast<char>(v >> 8);
    }
    if (trial % 4 != 0) record[17] = static_cast<char>(record[17] & 0x7F);
    const CompactOrigin origin{any_cm(rng), any_cm(rng), any_cm(rng)};
    Expected<Ellipsoid> e = decodeCompact(record, origin, 1, 2);
    if (!e.ok()) {
      ++refused;
      EXPECT_EQ(e.error().code, ErrorCode::kInvalidArgument);
      EXPECT_FALSE(e.error().message.empty());
      continue;
    }
    ++decoded;
    ASSERT_TRUE(e->center.allFinite()) << trial;
    ASSERT_TRUE(e->shape.allFinite()) << trial;
    ASSERT_EQ(e->shape, e->shape.transpose()) << trial;
    ASSERT_EQ(Eigen::LLT<Eigen::Matrix3d>(e->shape).info(), Eigen::Success) << trial << " " << describe(*e);
    // The semi-axes are the stored ones, whatever the rotation.
    std::array<double, 3> stored{};
    for (std::size_t i = 0; i < 3; ++i) {
      stored[i] = (static_cast<unsigned char>(record[6 + 2 * i]) | static_cast<unsigned char>(record[7 + 2 * i]) << 8) / 1000.0;
    }
    std::sort(stored.begin(), stored.end());
    const Eigen::Vector3d axes = partsOf(*e).semi_axes;
    for (int i = 0; i < 3; ++i) {
      ASSERT_NEAR(axes[i], stored[static_cast<std::size_t>(i)], 1e-9 * stored[2] + 1e-9) << trial << " " << describe(*e);
    }
  }
  EXPECT_GT(decoded, 5000);
  EXPECT_GT(refused, 5000);
}

// A record without its index is the record's first 20 bytes; its block gives the index.
TEST(CompactEllipsoidFormat, ARecordWithoutItsIndexIsTheRecordLessItsLastTwoBytes) {
  std::mt19937_64 rng(103);
  const CompactOrigin origin = compactOriginNear({-40.0, 25.0, 1.0});
  std::string with_index;
  std::string without_index;
  std::vector<Ellipsoid> exact;
  for (int trial = 0; trial < 50; ++trial) {
    const Sample s = randomSampleNear(rng, trial, origin);
    std::string record;
    ASSERT_TRUE(appendCompact(s.exact, origin, record)) << trial;
    std::string bare;
    ASSERT_TRUE(appendCompact(s.exact, origin, bare, CompactIndex::kImplicit)) << trial;
    ASSERT_EQ(bare.size(), kCompactRecordBytesWithoutIndex) << trial;
    EXPECT_EQ(bare, record.substr(0, kCompactRecordBytesWithoutIndex)) << trial;
    // Decoded with the index the block gives, it is the ellipsoid the full record decodes to.
    const Expected<Ellipsoid> full = decodeCompact(record, origin, 5, 77);
    const Expected<Ellipsoid> given = decodeCompact(bare, origin, 5, 77, s.exact.id.index);
    ASSERT_TRUE(full.ok() && given.ok()) << trial;
    EXPECT_EQ(*full, *given) << trial;
  }
  // Each kind of record has its own size.
  Ellipsoid ball;
  ball.center = {-40.0, 25.0, 1.0};
  ball.shape = Eigen::Matrix3d::Identity();
  std::string bare;
  ASSERT_TRUE(appendCompact(ball, origin, bare, CompactIndex::kImplicit));
  const auto wrong = decodeCompact(bare, origin, 5, 77);
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.error().message.find("22 bytes, got 20"), std::string::npos) << wrong.error().message;
  const auto short_one = decodeCompact(bare.substr(0, 19), origin, 5, 77, 3U);
  ASSERT_FALSE(short_one.ok());
  EXPECT_NE(short_one.error().message.find("without its index has 20 bytes, got 19"), std::string::npos)
      << short_one.error().message;
}

TEST(CompactEllipsoidFormat, ABlockWithoutIndicesNumbersItsRecordsFromItsFirstIndex) {
  const CompactOrigin origin{};
  std::string records;
  for (int k = 0; k < 3; ++k) {
    Ellipsoid e;
    e.center = {static_cast<double>(k), 0.0, 0.0};
    e.shape = Eigen::Matrix3d::Identity() * 0.25;
    e.point_count = 10;
    ASSERT_TRUE(appendCompact(e, origin, records, CompactIndex::kImplicit));
  }
  const auto block = decodeCompactBlock(records, origin, 2, 9, 40U);
  ASSERT_TRUE(block.ok()) << block.error().message;
  ASSERT_EQ(block->size(), 3U);
  for (std::uint32_t k = 0; k < 3; ++k) EXPECT_EQ((*block)[k].id, (EllipsoidId{2, 9, 40 + k}));
  // The last indices there are, and one past them.
  const auto last = decodeCompactBlock(records, origin, 2, 9, 0xFFFFFFFDU);
  ASSERT_TRUE(last.ok()) << last.error().message;
  EXPECT_EQ(last->back().id.index, 0xFFFFFFFFU);
  const auto beyond = decodeCompactBlock(records, origin, 2, 9, 0xFFFFFFFEU);
  ASSERT_FALSE(beyond.ok());
  EXPECT_NE(beyond.error().message.find("runs past the last index"), std::string::npos) << beyond.error().message;
  // A size that is no multiple of 20 bytes.
  const auto ragged = decodeCompactBlock(std::string_view(records).substr(1), origin, 2, 9, 0U);
  ASSERT_FALSE(ragged.ok());
  EXPECT_NE(ragged.error().message.find("not a multiple of 20"), std::string::npos) << ragged.error().message;
}

}  // namespace
}  // namespace fogmap
