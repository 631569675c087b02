#pragma once
// What a LiDAR-only classifier reads of a cluster (the DEBS 2019 Grand Challenge task: classify
// urban objects from their points): its oriented box, how its points spread (PCA), how they stack
// up (a height profile), how many there are against what the range allows, and their intensity.
// Pure: the points and the box in one frame, the sensor's position in it.
#include <array>
#include <cstddef>
#include <span>
#include <string_view>

#include <Eigen/Core>

#include "common/geometry/cloud.hpp"
#include "common/geometry/oriented_box.hpp"

namespace fogmap {

// The features in order; featureName gives each a name (for model files and reports).
enum class Feature : std::size_t {
  kLength,           // the box's, m
  kWidth,
  kHeight,
  kTop,              // the box's top z minus the sensor's z, m: where the object reaches
  kRange,            // horizontal distance from the sensor to the box's centre, m
  kLogPoints,        // log(1 + points)
  kDensity,          // points x range^2 / max(visible area, 0.01 m^2): points per solid angle, over
                     // the area the sensor sees (length or width, whichever faces it more, x height)
  kLinearity,        // PCA of the points, eigenvalues l1 >= l2 >= l3: (l1 - l2) / l1
  kPlanarity,        // (l2 - l3) / l1
  kScattering,       // l3 / l1
  kVerticality,      // |z| of the first principal axis: 1 for a pole, 0 for a lying bar
  kLowerQuarter,     // fraction of the points in each quarter of the box's height, bottom first
  kSecondQuarter,
  kThirdQuarter,
  kUpperQuarter,
  kUpperSpread,      // horizontal spread (2 x RMS distance from the axis through the centroid)
  kLowerSpread,      //   of the upper half of the points, and of the lower half, m
  kIntensityMean,    // of the points' intensity, as the sensor gives it
  kIntensityStd,
  kCount
};
inline constexpr std::size_t kFeatureCount = static_cast<std::size_t>(Feature::kCount);
using FeatureVector = std::array<float, kFeatureCount>;

std::string_view featureName(Feature feature);

// The features of a cluster's finite points with its box (fitOrientedBox), seen from `sensor`.
// Every value is finite: a cluster without finite points gives zeros but its box's; a single
// point, eigenvalues of 0, gives linearity, planarity and scattering of 0.
FeatureVector objectFeatures(std::span<const Point> points, const OrientedBox& box, const Eigen::Vector3d& sensor);

}  // namespace fogmap
