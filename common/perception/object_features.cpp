#include "common/perception/object_features.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "common/geometry/symmetric_eigen.hpp"

namespace fogmap {
namespace {

float finiteOr0(double value) { return std::isfinite(value) ? static_cast<float>(value) : 0.0F; }

// 2 x RMS horizontal distance of points from their own centroid.
double horizontalSpread(const std::vector<Eigen::Vector3d>& points) {
  if (points.empty()) return 0.0;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : points) mean += p.head<2>();
  mean /= static_cast<double>(points.size());
  double sum = 0.0;
  for (const auto& p : points) sum += (p.head<2>() - mean).squaredNorm();
  return 2.0 * std::sqrt(sum / static_cast<double>(points.size()));
}

}  // namespace

std::string_view featureName(Feature feature) {
  switch (feature) {
    case Feature::kLength: return "length";
    case Feature::kWidth: return "width";
    case Feature::kHeight: return "height";
    case Feature::kTop: return "top";
    case Feature::kRange: return "range";
    case Feature::kLogPoints: return "log_points";
    case Feature::kDensity: return "density";
    case Feature::kLinearity: return "linearity";
    case Feature::kPlanarity: return "planarity";
    case Feature::kScattering: return "scattering";
    case Feature::kVerticality: return "verticality";
    case Feature::kLowerQuarter: return "lower_quarter";
    case Feature::kSecondQuarter: return "second_quarter";
    case Feature::kThirdQuarter: return "third_quarter";
    case Feature::kUpperQuarter: return "upper_quarter";
    case Feature::kUpperSpread: return "upper_spread";
    case Feature::kLowerSpread: return "lower_spread";
    case Feature::kIntensityMean: return "intensity_mean";
    case Feature::kIntensityStd: return "intensity_std";
    case Feature::kCount: break;
  }
  return "unknown";
}

FeatureVector objectFeatures(std::span<const Point> points, const OrientedBox& box, const Eigen::Vector3d& sensor) {
  FeatureVector f{};
  auto set = [&f](Feature feature, double value) { f[static_cast<std::size_t>(feature)] = finiteOr0(value); };
  set(Feature::kLength, box.length);
  set(Feature::kWidth, box.width);
  set(Feature::kHeight, box.height);
  set(Feature::kTop, box.centre.z() + 0.5 * box.height - sensor.z());
  const Eigen::Vector2d to_box = box.centre.head<2>() - sensor.head<2>();
  const double range = to_box.norm();
  set(Feature::kRange, range);

  std::vector<Eigen::Vector3d> finite;
  finite.reserve(points.size());
  double intensity_sum = 0.0;
  double intensity_sq = 0.0;
  for (const Point& p : points) {
    if (!isFinitePoint(p)) continue;
    finite.emplace_back(p.x, p.y, p.z);
    const double i = std::isfinite(p.intensity) ? p.intensity : 0.0;
    intensity_sum += i;
    intensity_sq += i * i;
  }
  const auto n = static_cast<double>(finite.size());
  set(Feature::kLogPoints, std::log1p(n));
  if (finite.empty()) return f;

  // The face the sensor looks at more: the length's when the line of sight is across the length.
  const double c = std::cos(box.yaw);
  const double s = std::sin(box.yaw);
  const Eigen::Vector2d sight = range > 0.0 ? Eigen::Vector2d(to_box / range) : Eigen::Vector2d(1.0, 0.0);
  const double across_length = std::abs(-s * sight.x() + c * sight.y());  // |sight . width axis|
  const double seen_width = across_length >= std::sqrt(0.5) ? box.length : box.width;
  set(Feature::kDensity, n * range * range / std::max(seen_width * box.height, 0.01));

  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : finite) mean += p;
  mean /= n;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const auto& p : finite) covariance += (p - mean) * (p - mean).transpose();
  covariance /= n;
  const SymmetricEigen<3> eigen = symmetricEigen(covariance);
  const Eigen::Vector3d l = eigen.values.cwiseMax(0.0);  // ascending
  if (l(2) > 0.0) {
    set(Feature::kLinearity, (l(2) - l(1)) / l(2));
    set(Feature::kPlanarity, (l(1) - l(0)) / l(2));
    set(Feature::kScattering, l(0) / l(2));
    set(Feature::kVerticality, std::abs(eigen.vectors.col(2).z()));
  }

  // Height profile over the box's height (from its bottom), and the spread above and below its middle.
  const double bottom = box.centre.z() - 0.5 * box.height;
  std::array<double, 4> quarters{};
  std::vector<Eigen::Vector3d> upper, lower;
  for (const auto& p : finite) {
    const double t = box.height > 0.0 ? (p.z() - bottom) / box.height : 0.0;
    const int q = std::clamp(static_cast<int>(std::floor(4.0 * t)), 0, 3);
    quarters[static_cast<std::size_t>(q)] += 1.0;
    (t >= 0.5 ? upper : lower).push_back(p);
  }
  set(Feature::kLowerQuarter, quarters[0] / n);
  set(Feature::kSecondQuarter, quarters[1] / n);
  set(Feature::kThirdQuarter, quarters[2] / n);
  set(Feature::kUpperQuarter, quarters[3] / n);
  set(Feature::kUpperSpread, horizontalSpread(upper));
  set(Feature::kLowerSpread, horizontalSpread(lower));

  const double intensity_mean = intensity_sum / n;
  set(Feature::kIntensityMean, intensity_mean);
  set(Feature::kIntensityStd, std::sqrt(std::max(0.0, intensity_sq / n - intensity_mean * intensity_mean)));
  return f;
}

}  // namespace fogmap
