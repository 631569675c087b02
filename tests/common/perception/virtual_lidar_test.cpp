#include "common/perception/virtual_lidar.hpp"

#include <cmath>
#include <cstddef>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace fogmap {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

// Points on all sides of the sensor, with the point's index in the intensity (exact below 2^24) so
// that a point can be recognised after the views moved it to their own frames. Besides random
// azimuths, points lie exactly on and just beside every boundary of every split tested.
Cloud scanAllAround() {
  std::mt19937 rng(20240611);
  std::uniform_real_distribution<double> azimuth_deg(0.0, 360.0);
  std::uniform_real_distribution<double> range_m(0.5, 30.0);
  std::uniform_real_distribution<double> height_m(-2.0, 2.0);
  std::vector<double> azimuths;
  for (int i = 0; i < 5000; ++i) azimuths.push_back(azimuth_deg(rng));
  for (int views : {1, 2, 3, 4, 6, 7, 8}) {
    for (int k = 0; k <= views; ++k) {
      const double boundary = 360.0 * k / views;
      for (double offset : {-1e-9, 0.0, 1e-9, -2.5, 2.5, -5.0, 5.0}) azimuths.push_back(boundary + offset);
    }
  }
  Cloud scan;
  for (double a : azimuths) {
    const double r = range_m(rng);
    scan.push_back({static_cast<float>(r * std::cos(a * kDegToRad)), static_cast<float>(r * std::sin(a * kDegToRad)),
                    static_cast<float>(height_m(rng)), static_cast<float>(scan.size())});
  }
  scan.push_back({0.0F, 0.0F, 1.0F, static_cast<float>(scan.size())});  // on the axis: azimuth 0
  return scan;
}

// Azimuth of a direction in degrees, in (-180, 180].
double azimuthDeg(double x, double y) { return std::atan2(y, x) / kDegToRad; }

struct Coverage {
  std::vector<int> views_per_point;
  double max_round_trip_error_m = 0.0;
  double max_abs_azimuth_in_own_frame_deg = 0.0;
};

// Puts every view back into the scan frame with its pose and records which points came back.
Coverage coverage(const Cloud& scan, int views, double overlap_deg) {
  Coverage result;
  result.views_per_point.assign(scan.size(), 0);
  for (int k = 0; k < views; ++k) {
    const SectorSplit split{views, k, overlap_deg};
    const Eigen::Isometry3d pose = sectorPose(split);
    for (const Point& p : sectorView(scan, split)) {
      const auto index = static_cast<std::size_t>(p.intensity);
      ++result.views_per_point[index];
      const Eigen::Vector3d back = pose * p.xyz().cast<double>();
      result.max_round_trip_error_m =
          std::max(result.max_round_trip_error_m, (back - scan[index].xyz().cast<double>()).cwiseAbs().maxCoeff());
      if (std::hypot(p.x, p.y) > 0.0F) {
        result.max_abs_azimuth_in_own_frame_deg =
            std::max(result.max_abs_azimuth_in_own_frame_deg, std::abs(azimuthDeg(p.x, p.y)));
      }
    }
  }
  return result;
}

TEST(VirtualLidar, ViewsWithoutOverlapPartitionTheScan) {
  const Cloud scan = scanAllAround();
  for (int views : {1, 2, 3, 4, 6, 7, 8}) {
    const Coverage c = coverage(scan, views, 0.0);
    for (std::size_t i = 0; i < scan.size(); ++i) {
      ASSERT_EQ(c.views_per_point[i], 1) << "point " << i << " with " << views << " views";
    }
  }
}

TEST(VirtualLidar, ViewsWithOverlapCoverEveryPointAtMostTwice) {
  const Cloud scan = scanAllAround();
  for (int views : {2, 3, 4, 6, 7, 8}) {
    for (double overlap_deg : {1.0, 10.0, 30.0}) {
      if (overlap_deg >= 360.0 / views) continue;
      const Coverage c = coverage(scan, views, overlap_deg);
      std::size_t doubled = 0;
      for (std::size_t i = 0; i < scan.size(); ++i) {
        ASSERT_GE(c.views_per_point[i], 1) << "point " << i << " lost with " << views << " views, " << overlap_deg;
        ASSERT_LE(c.views_per_point[i], 2) << "point " << i << " with " << views << " views, " << overlap_deg;
        if (c.views_per_point[i] == 2) ++doubled;
      }
      EXPECT_GT(doubled, 0U) << "the overlap must share points between neighbours";
    }
  }
}

TEST(VirtualLidar, OverlapWidensTheSectorByHalfOnEachSide) {
  // 4 views of 90 degrees with 20 degrees of overlap: sector 1 spans [80, 190).
  const SectorSplit split{4, 1, 20.0};
  auto at = [](double azimuth_deg) {
    return Point{static_cast<float>(10.0 * std::cos(azimuth_deg * kDegToRad)),
                 static_cast<float>(10.0 * std::sin(azimuth_deg * kDegToRad)), 0.0F, 0.0F};
  };
  const Cloud inside = {at(81.0), at(135.0), at(189.0)};
  const Cloud outside = {at(79.0), at(191.0), at(-45.0)};
  EXPECT_EQ(sectorView(inside, split).size(), 3U);
  EXPECT_TRUE(sectorView(outside, split).empty());
}

TEST(VirtualLidar, ViewsPutTheSectorCentreOnPlusX) {
  const Cloud scan = scanAllAround();
  for (int views : {3, 4, 8}) {
    const double overlap_deg = 10.0;
    const Coverage c = coverage(scan, views, overlap_deg);
    EXPECT_LE(c.max_abs_azimuth_in_own_frame_deg, 180.0 / views + overlap_deg / 2.0 + 1e-4) << views << " views";
  }
}

TEST(VirtualLidar, PoseRoundTripIsExact) {
  const Cloud scan = scanAllAround();
  for (int views : {1, 3, 4, 7}) {
    const Coverage c = coverage(scan, views, 10.0);
    EXPECT_LT(c.max_round_trip_error_m, 1e-5) << views << " views";
  }
}

TEST(VirtualLidar, SectorPoseIsARotationAboutZByTheCentralAzimuth) {
  const SectorSplit split{6, 2, 10.0};  // sector [120, 180): centre 150 degrees
  const Eigen::Isometry3d pose = sectorPose(split);
  EXPECT_LT(pose.translation().norm(), 1e-12);
  const Eigen::Vector3d forward = pose * Eigen::Vector3d::UnitX();
  EXPECT_NEAR(azimuthDeg(forward.x(), forward.y()), 150.0, 1e-9);
  EXPECT_NEAR(forward.z(), 0.0, 1e-12);
  EXPECT_LT((pose * Eigen::Vector3d::UnitZ() - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
}

TEST(VirtualLidar, IntensityIsKept) {
  const Cloud scan = {{5.0F, 1.0F, 0.5F, 0.75F}};
  const Cloud view = sectorView(scan, SectorSplit{1, 0, 0.0});
  ASSERT_EQ(view.size(), 1U);
  EXPECT_EQ(view[0].intensity, 0.75F);
}

}  // namespace
}  // namespace fogmap
