#include "common/perception/virtual_lidar.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/base/angles.hpp"

namespace fogmap {
namespace {

constexpr double kFullTurnDeg = 360.0;

double sectorWidthDeg(const SectorSplit& split) { return kFullTurnDeg / split.views; }

double sectorCentreDeg(const SectorSplit& split) { return (split.index + 0.5) * sectorWidthDeg(split); }

// Azimuth in [0, 360) degrees.
double azimuthDeg(const Point& p) {
  double azimuth = std::atan2(static_cast<double>(p.y), static_cast<double>(p.x)) * kRadToDeg;
  if (azimuth < 0.0) azimuth += kFullTurnDeg;
  // A tiny negative angle plus 360 can round to 360 itself, which is the start of sector 0.
  if (azimuth >= kFullTurnDeg) azimuth -= kFullTurnDeg;
  return azimuth;
}

bool inView(double azimuth_deg, const SectorSplit& split) {
  const double width = sectorWidthDeg(split);
  // Every point has one home sector, found by one floor, so that sectors without overlap
  // partition the scan exactly: no point is lost or doubled at a boundary by rounding.
  const int home = std::clamp(static_cast<int>(std::floor(azimuth_deg / width)), 0, split.views - 1);
  if (home == split.index) return true;
  // Otherwise the point is in the view when it lies in the overlap margin around the sector:
  // its angle past the widened start, taken modulo a full turn, is below the widened width.
  const double half_overlap = split.overlap_deg / 2.0;
  const double start = split.index * width - half_overlap;
  double past_start = std::fmod(azimuth_deg - start, kFullTurnDeg);
  if (past_start < 0.0) past_start += kFullTurnDeg;
  return past_start < width + split.overlap_deg;
}

}  // namespace

Eigen::Isometry3d sectorPose(const SectorSplit& split) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.rotate(Eigen::AngleAxisd(sectorCentreDeg(split) * kDegToRad, Eigen::Vector3d::UnitZ()));
  return pose;
}

Cloud sectorView(std::span<const Point> scan, const SectorSplit& split) {
  const Eigen::Matrix3d scan_to_sector = sectorPose(split).linear().transpose();
  Cloud view;
  for (const Point& p : scan) {
    const double azimuth = azimuthDeg(p);
    // A point without a direction (NaN x or y) belongs to no sector.
    if (!std::isfinite(azimuth) || !inView(azimuth, split)) continue;
    const Eigen::Vector3d q = scan_to_sector * p.xyz().cast<double>();
    view.push_back({static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()), p.intensity});
  }
  return view;
}

}  // namespace fogmap
