#include "common/geometry/geofence.hpp"

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "tests/support/geometry_builders.hpp"

namespace fogmap {
namespace {

using test_support::sphere;

Geofence singlePlane(const Eigen::Vector3d& normal, double offset) {
  return Geofence{"plane", {HalfSpace{normal, offset}}};
}

MapObject objectOf(std::vector<Ellipsoid> ellipsoids) {
  MapObject object;
  object.ellipsoids = std::move(ellipsoids);
  return object;
}

// ---------------------------------------------------------------------------------------------
// Exact hand cases.

TEST(Geofence, SphereTangentToPlaneFromInsideIsCrossing) {
  EXPECT_EQ(classify(sphere({0, 0, 1}, 1.0), singlePlane({0, 0, 1}, 0.0)), Containment::kCrossing);
}

TEST(Geofence, SphereTangentToPlaneFromOutsideIsCrossing) {
  EXPECT_EQ(classify(sphere({0, 0, -1}, 1.0), singlePlane({0, 0, 1}, 0.0)), Containment::kCrossing);
}

TEST(Geofence, SphereJustClearOfPlaneIsInsideOrOutside) {
  const Geofence fence = singlePlane({0, 0, 1}, 0.0);
  EXPECT_EQ(classify(sphere({0, 0, 1.0 + 1e-9}, 1.0), fence), Containment::kInside);
  EXPECT_EQ(classify(sphere({0, 0, -1.0 - 1e-9}, 1.0), fence), Containment::kOutside);
}

TEST(Geofence, NormalLengthDoesNotMatter) {
  // Powers of two keep the tangent case exact in floating point.
  for (double scale : {1.0 / 1024, 0.5, 1.0, 8.0, 4096.0}) {
    const Geofence fence = singlePlane(Eigen::Vector3d(0, 0, 1) * scale, -2.0 * scale);  // z >= 2
    EXPECT_EQ(classify(sphere({0, 0, 3}, 1.0), fence), Containment::kCrossing) << scale;
    EXPECT_EQ(classify(sphere({0, 0, 3.5}, 1.0), fence), Containment::kInside) << scale;
    EXPECT_EQ(classify(sphere({0, 0, 0.5}, 1.0), fence), Containment::kOutside) << scale;
    EXPECT_EQ(classify(sphere({5, -4, 1.5}, 1.0), fence), Containment::kCrossing) << scale;
  }
}

TEST(Geofence, TiltedPlaneUsesEllipsoidExtentAlongNormal) {
  // Ellipsoid with semi-axes 3 (x) and 0.5 (y, z); the plane x + y >= 0 at 45 degrees.
  Ellipsoid e;
  e.center = {1.0, 1.0, 0.0};
  e.shape = Eigen::Vector3d(9.0, 0.25, 0.25).asDiagonal();
  // Distance of the centre from the plane: 2/sqrt(2) = 1.414; half-width along the unit normal:
  // sqrt((9 + 0.25) / 2) = 2.15, so the ellipsoid crosses although its centre is well inside.
  EXPECT_EQ(classify(e, singlePlane({1, 1, 0}, 0.0)), Containment::kCrossing);
  // Along y alone the half-width is 0.5 < 1.
  EXPECT_EQ(classify(e, singlePlane({0, 1, 0}, 0.0)), Containment::kInside);
}

TEST(Geofence, FlatEllipsoidParallelToPlane) {
  // A disc of radius 1 in the plane z = 0.5 (zero eigenvalue along z).
  Ellipsoid disc;
  disc.center = {0, 0, 0.5};
  disc.shape = Eigen::Vector3d(1.0, 1.0, 0.0).asDiagonal();
  EXPECT_EQ(classify(disc, singlePlane({0, 0, 1}, 0.0)), Containment::kInside);
  EXPECT_EQ(classify(disc, singlePlane({0, 0, 1}, -0.5)), Containment::kCrossing);  // lies in it
  EXPECT_EQ(classify(disc, singlePlane({0, 0, 1}, -0.6)), Containment::kOutside);
}

TEST(Geofence, BoxGeofenceHasSixAxisAlignedHalfSpaces) {
  const Eigen::Vector3d lo(-1, 2, -3);
  const Eigen::Vector3d hi(4, 5, 6);
  const Geofence fence = boxGeofence("yard", lo, hi);
  EXPECT_EQ(fence.name, "yard");
  ASSERT_EQ(fence.half_spaces.size(), 6U);
  EXPECT_TRUE(validateGeofence(fence).ok());
  auto inside = [&](const Eigen::Vector3d& p) {
    for (const HalfSpace& h : fence.half_spaces) {
      if (h.normal.dot(p) + h.offset < 0.0) return false;
    }
    return true;
  };
  for (const HalfSpace& h : fence.half_spaces) {
    EXPECT_EQ((h.normal.array() != 0.0).count(), 1);
  }
  // Corners and the centre are in (closed box); points just beyond each face are out.
  for (int corner = 0; corner < 8; ++corner) {
    Eigen::Vector3d p;
    for (int d = 0; d < 3; ++d) p[d] = ((corner >> d) & 1) != 0 ? hi[d] : lo[d];
    EXPECT_TRUE(inside(p)) << p.transpose();
  }
  const Eigen::Vector3d mid = (lo + hi) / 2;
  EXPECT_TRUE(inside(mid));
  for (int d = 0; d < 3; ++d) {
    Eigen::Vector3d below = mid;
    below[d] = lo[d] - 1e-9;
    Eigen::Vector3d above = mid;
    above[d] = hi[d] + 1e-9;
    EXPECT_FALSE(inside(below)) << d;
    EXPECT_FALSE(inside(above)) << d;
  }
}

TEST(Geofence, BoxClassifiesInsideCrossingOutside) {
  const Geofence fence = boxGeofence("box", {0, 0, 0}, {10, 10, 10});
  EXPECT_EQ(classify(sphere({5, 5, 5}, 1.0), fence), Containment::kInside);
  EXPECT_EQ(classify(sphere({5, 5, 5}, 5.0), fence), Containment::kCrossing);  // touches all faces
  EXPECT_EQ(classify(sphere({5, 5, 5}, 50.0), fence), Containment::kCrossing);  // contains the box
  EXPECT_EQ(classify(sphere({10, 5, 5}, 1.0), fence), Containment::kCrossing);
  EXPECT_EQ(classify(sphere({12, 5, 5}, 1.0), fence), Containment::kOutside);
  EXPECT_EQ(classify(sphere({-3, -3, -3}, 1.0), fence), Containment::kOutside);
}

TEST(Geofence, SphereNearBoxEdgeButOutsideIsConservativelyCrossing) {
  // The sphere misses the box (distance to the edge x = y = 1 is 0.707 > 0.6), but no single face
  // plane separates it, so the conservative per-plane test must not call it outside.
  const Geofence fence = boxGeofence("box", {0, 0, 0}, {1, 1, 1});
  EXPECT_EQ(classify(sphere({1.5, 1.5, 0.5}, 0.6), fence), Containment::kCrossing);
}

// ---------------------------------------------------------------------------------------------
// Objects and maps.

TEST(Geofence, ObjectAggregatesItsEllipsoids) {
  const Geofence fence = boxGeofence("box", {0, 0, 0}, {10, 10, 10});
  const Ellipsoid in_a = sphere({2, 2, 2}, 1.0);
  const Ellipsoid in_b = sphere({7, 7, 7}, 1.0);
  const Ellipsoid out_a = sphere({20, 2, 2}, 1.0);
  const Ellipsoid out_b = sphere({-5, -5, 2}, 1.0);
  const Ellipsoid cross = sphere({10, 5, 5}, 1.0);
  EXPECT_EQ(classify(objectOf({in_a, in_b}), fence), Containment::kInside);
  EXPECT_EQ(classify(objectOf({out_a, out_b}), fence), Containment::kOutside);
  EXPECT_EQ(classify(objectOf({in_a, out_a}), fence), Containment::kCrossing);
  EXPECT_EQ(classify(objectOf({out_a, cross}), fence), Containment::kCrossing);
  EXPECT_EQ(classify(objectOf({cross, in_b}), fence), Containment::kCrossing);
  EXPECT_EQ(classify(objectOf({out_a, in_a, out_b}), fence), Containment::kCrossing);
}

TEST(Geofence, ObjectHalfInsideIsCrossing) {
  const Geofence fence = boxGeofence("box", {0, 0, 0}, {10, 10, 10});
  // A chain of small spheres from inside the box to outside it; none crosses a face itself.
  std::vector<Ellipsoid> chain;
  for (double x = 6.0; x < 14.0; x += 0.5) {
    if (std::abs(x - 10.0) > 0.3) chain.push_back(sphere({x, 5, 5}, 0.2));
  }
  EXPECT_EQ(classify(objectOf(chain), fence), Containment::kCrossing);
}

TEST(Geofence, EmptyObjectIsOutside) {
  EXPECT_EQ(classify(MapObject{}, boxGeofence("box", {0, 0, 0}, {1, 1, 1})), Containment::kOutside);
}

TEST(Geofence, IntrusionsListsObjectsNotOutsideInMapOrder) {
  const Geofence fence = boxGeofence("box", {0, 0, 0}, {10, 10, 10});
  Map map;
  map.objects.push_back(objectOf({sphere({20, 20, 20}, 1.0)}));                          // outside
  map.objects.push_back(objectOf({sphere({5, 5, 5}, 1.0)}));                             // inside
  map.objects.push_back(objectOf({sphere({0, 5, 5}, 1.0)}));                             // crossing
  map.objects.push_back(objectOf({sphere({-20, 5, 5}, 1.0), sphere({5, 50, 5}, 2.0)}));  // outside
  map.objects.push_back(objectOf({sphere({5, 5, 5}, 1.0), sphere({30, 5, 5}, 1.0)}));    // crossing
  const std::vector<GeofenceHit> hits = intrusions(map, fence);
  ASSERT_EQ(hits.size(), 3U);
  EXPECT_EQ(hits[0].object_index, 1U);
  EXPECT_EQ(hits[0].containment, Containment::kInside);
  EXPECT_EQ(hits[1].object_index, 2U);
  EXPECT_EQ(hits[1].containment, Containment::kCrossing);
  EXPECT_EQ(hits[2].object_index, 4U);
  EXPECT_EQ(hits[2].containment, Containment::kCrossing);
}

TEST(Geofence, IntrusionsOfEmptyMapIsEmpty) {
  EXPECT_TRUE(intrusions(Map{}, boxGeofence("box", {0, 0, 0}, {1, 1, 1})).empty());
}

TEST(Geofence, ContainmentNames) {
  EXPECT_STREQ(containmentName(Containment::kInside), "inside");
  EXPECT_STREQ(containmentName(Containment::kCrossing), "crossing");
  EXPECT_STREQ(containmentName(Containment::kOutside), "outside");
}

// ---------------------------------------------------------------------------------------------
// Validation.

TEST(Geofence, ValidateRejectsEmptyGeofenceNamingIt) {
  const Status status = validateGeofence(Geofence{"parking-lot", {}});
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(status.error().message.find("parking-lot"), std::string::npos) << status.error().message;
}

TEST(Geofence, ValidateRejectsBadHalfSpacesNamingTheIndex) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<HalfSpace> bad = {
      {Eigen::Vector3d::Zero(), 1.0},
      {Eigen::Vector3d(nan, 0, 1), 1.0},
      {Eigen::Vector3d(0, inf, 1), 1.0},
      {Eigen::Vector3d(0, 0, 1), nan},
      {Eigen::Vector3d(0, 0, 1), -inf},
  };
  for (const HalfSpace& h : bad) {
    Geofence fence = boxGeofence("gate", {0, 0, 0}, {1, 1, 1});
    fence.half_spaces.insert(fence.half_spaces.begin() + 3, h);  // index 3 is the bad one
    const Status status = validateGeofence(fence);
    ASSERT_FALSE(status.ok()) << h.normal.transpose() << " " << h.offset;
    EXPECT_EQ(status.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(status.error().message.find("gate"), std::string::npos) << status.error().message;
    EXPECT_NE(status.error().message.find('3'), std::string::npos) << status.error().message;
  }
}

TEST(Geofence, ValidateRejectsNormalsWhoseSquareUnderflowsOrOverflows) {
  for (double length : {1e-200, 1e200}) {
    const Status status = validateGeofence(singlePlane({0, 0, length}, 0.0));
    ASSERT_FALSE(status.ok()) << length;
    EXPECT_EQ(status.error().code, ErrorCode::kInvalidArgument);
  }
}

TEST(Geofence, ValidateAcceptsSmallAndLargeNonUnitNormals) {
  EXPECT_TRUE(validateGeofence(singlePlane({0, 0, 1e-30}, 5.0)).ok());
  EXPECT_TRUE(validateGeofence(singlePlane({0, 0, 1e30}, 5.0)).ok());
  EXPECT_TRUE(validateGeofence(singlePlane({3, -4, 12}, -1e6)).ok());
}

// ---------------------------------------------------------------------------------------------
// Point-sampling oracle on random ellipsoids and random convex polyhedra.

struct RandomCase {
  Ellipsoid ellipsoid;
  Eigen::Matrix3d root;  // shape = root * root^T, maps the unit ball onto the ellipsoid
  Geofence fence;
};

using test_support::randomRotation;
using test_support::randomUnitVector;

RandomCase randomCase(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> axis(0.1, 3.0);
  std::uniform_real_distribution<double> position(-6.0, 6.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  RandomCase c;
  const Eigen::Matrix3d rotation = randomRotation(rng);
  const Eigen::Vector3d semi_axes(axis(rng), axis(rng), axis(rng));
  c.root = rotation * semi_axes.asDiagonal();
  c.ellipsoid.center = {position(rng), position(rng), position(rng)};
  c.ellipsoid.shape = c.root * c.root.transpose();

  const Eigen::Vector3d fence_center(position(rng) / 3, position(rng) / 3, position(rng) / 3);
  if (unit(rng) < 0.4) {
    std::uniform_real_distribution<double> half(0.5, 6.0);
    const Eigen::Vector3d h(half(rng), half(rng), half(rng));
    c.fence = boxGeofence("box", fence_center - h, fence_center + h);
  } else {
    // Random planes at random distances from the centre; normals of random length so that the
    // classifier's scale invariance is exercised too.
    std::uniform_int_distribution<int> count(1, 10);
    std::uniform_real_distribution<double> distance(0.5, 8.0);
    std::uniform_real_distribution<double> log_scale(-2.0, 2.0);
    c.fence.name = "polyhedron";
    const int planes = count(rng);
    for (int i = 0; i < planes; ++i) {
      const Eigen::Vector3d n = randomUnitVector(rng);
      const double scale = std::pow(10.0, log_scale(rng));
      // n.(x - centre) + distance >= 0
      c.fence.half_spaces.push_back({scale * n, scale * (distance(rng) - n.dot(fence_center))});
    }
  }
  return c;
}

// Points of the ellipsoid: the centre, the extreme points along every plane normal (the exact
// support points, where the classifier's decision is sharpest), surface points and interior points.
std::vector<Eigen::Vector3d> samplePoints(const RandomCase& c, std::mt19937_64& rng, int count) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Ellipsoid& e = c.ellipsoid;
  std::vector<Eigen::Vector3d> points{e.center};
  for (const HalfSpace& h : c.fence.half_spaces) {
    const Eigen::Vector3d mn = e.shape * h.normal;
    const double width = std::sqrt(h.normal.dot(mn));
    points.push_back(e.center + mn / width);
    points.push_back(e.center - mn / width);
  }
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d u = randomUnitVector(rng);
    // Half on the surface, half in the interior (uniform in the ball: radius ~ cbrt(U)).
    const double r = i % 2 == 0 ? 1.0 : std::cbrt(unit(rng));
    points.push_back(e.center + c.root * (r * u));
  }
  return points;
}

// Tolerance on n.x + d, relative to the size of the terms, for rounding in the sampled points.
double tolerance(const HalfSpace& h, const Eigen::Vector3d& p) {
  return 1e-9 * (h.normal.norm() * (p.norm() + 1.0) + std::abs(h.offset));
}

bool surelyInsidePolyhedron(const Geofence& fence, const Eigen::Vector3d& p) {
  for (const HalfSpace& h : fence.half_spaces) {
    if (h.normal.dot(p) + h.offset <= tolerance(h, p)) return false;
  }
  return true;
}

bool possiblyInsidePolyhedron(const Geofence& fence, const Eigen::Vector3d& p) {
  for (const HalfSpace& h : fence.half_spaces) {
    if (h.normal.dot(p) + h.offset < -tolerance(h, p)) return false;
  }
  return true;
}

TEST(Geofence, ClassificationAgreesWithSampledPoints) {
  std::mt19937_64 rng(20240611);
  constexpr int kCases = 2000;
  int inside = 0;
  int outside = 0;
  int crossing = 0;
  int crossing_with_points_on_both_sides = 0;
  for (int trial = 0; trial < kCases; ++trial) {
    const RandomCase c = randomCase(rng);
    ASSERT_TRUE(validateGeofence(c.fence).ok());
    const Containment result = classify(c.ellipsoid, c.fence);
    const std::vector<Eigen::Vector3d> points = samplePoints(c, rng, 600);
    bool any_in = false;
    bool any_out = false;
    for (const Eigen::Vector3d& p : points) {
      if (result == Containment::kInside) {
        ASSERT_TRUE(possiblyInsidePolyhedron(c.fence, p))
            << "trial " << trial << ": classified inside but point " << p.transpose()
            << " is outside the polyhedron";
      }
      // Conservativeness: a point of the ellipsoid inside the fence forbids "outside".
      if (surelyInsidePolyhedron(c.fence, p)) {
        ASSERT_NE(result, Containment::kOutside)
            << "trial " << trial << ": classified outside but point " << p.transpose()
            << " is inside the polyhedron";
        any_in = true;
      }
      if (!possiblyInsidePolyhedron(c.fence, p)) any_out = true;
    }
    switch (result) {
      case Containment::kInside: ++inside; break;
      case Containment::kOutside: ++outside; break;
      case Containment::kCrossing:
        ++crossing;
        if (any_in && any_out) ++crossing_with_points_on_both_sides;
        break;
    }
  }
  // The generator must exercise all three outcomes, and most "crossing" answers should be real
  // crossings (the rest are the conservative corner cases).
  EXPECT_GT(inside, kCases / 10);
  EXPECT_GT(outside, kCases / 10);
  EXPECT_GT(crossing, kCases / 10);
  EXPECT_GT(crossing_with_points_on_both_sides, crossing / 2);
}

TEST(Geofence, CrossingIsDecidedPlaneByPlane) {
  // For each single plane the test is exact: the extreme points along the normal straddle the
  // plane exactly when the answer is crossing.
  std::mt19937_64 rng(77);
  for (int trial = 0; trial < 2000; ++trial) {
    const RandomCase c = randomCase(rng);
    for (const HalfSpace& h : c.fence.half_spaces) {
      const Geofence one{"one", {h}};
      const Eigen::Vector3d mn = c.ellipsoid.shape * h.normal;
      const double width = std::sqrt(h.normal.dot(mn));
      const Eigen::Vector3d lowest = c.ellipsoid.center - mn / width;
      const Eigen::Vector3d highest = c.ellipsoid.center + mn / width;
      const double lo = h.normal.dot(lowest) + h.offset;
      const double hi = h.normal.dot(highest) + h.offset;
      const double tol = tolerance(h, highest) + tolerance(h, lowest);
      switch (classify(c.ellipsoid, one)) {
        case Containment::kInside: EXPECT_GT(lo, -tol) << trial; break;
        case Containment::kOutside: EXPECT_LT(hi, tol) << trial; break;
        case Containment::kCrossing:
          EXPECT_LE(lo, tol) << trial;
          EXPECT_GE(hi, -tol) << trial;
          break;
      }
    }
  }
}

}  // namespace
}  // namespace fogmap
