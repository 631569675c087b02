#include "common/perception/object_features.hpp"

#include <cmath>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "common/perception/box_fitting.hpp"

namespace fogmap {
namespace {

float at(const FeatureVector& f, Feature feature) { return f[static_cast<std::size_t>(feature)]; }

OrientedBox boxOf(const Cloud& points, const Eigen::Vector3d& sensor) {
  const auto box = fitOrientedBox(points, sensor);
  EXPECT_TRUE(box.ok());
  return box ? *box : OrientedBox{};
}

TEST(ObjectFeatures, APoleIsLinearVerticalAndEvenlyStacked) {
  Cloud pole;
  for (int k = 0; k < 400; ++k) pole.push_back({10.0F, 0.0F, static_cast<float>(-1.8 + 3.0 * (k + 0.5) / 400.0), 0.0F});
  const Eigen::Vector3d sensor(0.0, 0.0, 0.0);
  const FeatureVector f = objectFeatures(pole, boxOf(pole, sensor), sensor);
  EXPECT_NEAR(at(f, Feature::kLinearity), 1.0, 1e-6);
  EXPECT_NEAR(at(f, Feature::kPlanarity), 0.0, 1e-6);
  EXPECT_NEAR(at(f, Feature::kScattering), 0.0, 1e-6);
  EXPECT_NEAR(at(f, Feature::kVerticality), 1.0, 1e-6);
  for (const Feature q : {Feature::kLowerQuarter, Feature::kSecondQuarter, Feature::kThirdQuarter, Feature::kUpperQuarter}) {
    EXPECT_NEAR(at(f, q), 0.25, 0.0051) << featureName(q);
  }
  EXPECT_NEAR(at(f, Feature::kHeight), 3.0 * 399.0 / 400.0, 1e-5);
  EXPECT_NEAR(at(f, Feature::kTop), -1.8 + 3.0 * 399.5 / 400.0, 1e-5);
  EXPECT_NEAR(at(f, Feature::kRange), 10.0, 1e-6);
  EXPECT_NEAR(at(f, Feature::kLogPoints), std::log1p(400.0), 1e-5);
  EXPECT_NEAR(at(f, Feature::kUpperSpread), 0.0, 1e-6);
}

TEST(ObjectFeatures, AWallIsPlanarAndItsDensityIsPointsPerSolidAngleOverItsSeenFace) {
  // A 2 x 2 m wall facing the sensor 20 m away: points every 0.1 m, 21 x 21.
  Cloud wall;
  for (int a = 0; a <= 20; ++a) {
    for (int b = 0; b <= 20; ++b) wall.push_back({20.0F, static_cast<float>(-1.0 + 0.1 * a), static_cast<float>(0.1 * b), 0.0F});
  }
  const Eigen::Vector3d sensor(0.0, 0.0, 1.0);
  const OrientedBox box = boxOf(wall, sensor);
  const FeatureVector f = objectFeatures(wall, box, sensor);
  EXPECT_NEAR(at(f, Feature::kLinearity), 0.0, 1e-3);  // the two in-plane spreads are equal
  EXPECT_NEAR(at(f, Feature::kPlanarity), 1.0, 1e-3);
  EXPECT_NEAR(at(f, Feature::kScattering), 0.0, 1e-6);
  // The seen face is the box's length (2 m along y) by its height (2 m).
  EXPECT_NEAR(at(f, Feature::kDensity), 441.0 * 400.0 / (box.length * box.height), 1e-2);
  // A line of points scores the same at every yaw that keeps it within d0 = 1 cm of one edge
  // (within 0.57 degrees here): the search takes the middle of the tie, the line's own yaw.
  EXPECT_NEAR(box.length, 2.0, 1e-5);
  // The same wall seen edge-on from far along +y shows its width (0) by its height: the area floor.
  const Eigen::Vector3d side(20.0, 50.0, 1.0);
  const FeatureVector g = objectFeatures(wall, box, side);
  const double range = (box.centre.head<2>() - side.head<2>()).norm();
  const double edge_on = 441.0 * range * range / std::max(box.width * box.height, 0.01);
  EXPECT_NEAR(at(g, Feature::kDensity), edge_on, 1e-5 * edge_on);
}

TEST(ObjectFeatures, IntensityStatisticsAndSpreadsAreExact) {
  // A "T": a 1 m wide bar on top of a thin post; intensities 10, 20, 30, 40 in turn.
  Cloud t;
  const float intensity[] = {10.0F, 20.0F, 30.0F, 40.0F};
  int k = 0;
  for (int i = 0; i < 8; ++i) t.push_back({5.0F, 0.0F, static_cast<float>(0.1 * i), intensity[k++ % 4]});
  for (int i = 0; i <= 10; ++i) t.push_back({5.0F, static_cast<float>(-0.5 + 0.1 * i), 1.6F, intensity[k++ % 4]});
  t.push_back({std::nanf(""), 0.0F, 0.0F, 99.0F});  // left out
  const Eigen::Vector3d sensor(0.0, 0.0, 0.0);
  const FeatureVector f = objectFeatures(t, boxOf(t, sensor), sensor);
  double sum = 0.0, sq = 0.0;
  for (int i = 0; i < 19; ++i) {
    sum += intensity[i % 4];
    sq += intensity[i % 4] * intensity[i % 4];
  }
  const double mean = sum / 19.0;
  EXPECT_NEAR(at(f, Feature::kIntensityMean), mean, 1e-4);
  EXPECT_NEAR(at(f, Feature::kIntensityStd), std::sqrt(sq / 19.0 - mean * mean), 1e-4);
  EXPECT_NEAR(at(f, Feature::kLowerSpread), 0.0, 1e-6);  // the post: one vertical line
  // The bar: y from -0.5 to 0.5 every 0.1, mean 0, mean square 1.1 / 11: 2 x RMS = 2 sqrt(0.1) m.
  EXPECT_NEAR(at(f, Feature::kUpperSpread), 2.0 * std::sqrt(0.1), 1e-4);
  EXPECT_NEAR(at(f, Feature::kUpperQuarter), 11.0 / 19.0, 1e-6);
}

TEST(ObjectFeatures, DegenerateClustersGiveFiniteValues) {
  const Eigen::Vector3d sensor(0.0, 0.0, 0.0);
  const Cloud one = {{3.0F, 4.0F, 0.0F, 7.0F}};
  const FeatureVector f = objectFeatures(one, boxOf(one, sensor), sensor);
  for (std::size_t i = 0; i < kFeatureCount; ++i) EXPECT_TRUE(std::isfinite(f[i])) << featureName(static_cast<Feature>(i));
  EXPECT_EQ(at(f, Feature::kLinearity), 0.0F);
  EXPECT_NEAR(at(f, Feature::kRange), 5.0, 1e-6);
  EXPECT_EQ(at(f, Feature::kIntensityMean), 7.0F);
  const FeatureVector none = objectFeatures({}, OrientedBox{}, sensor);
  for (const float v : none) EXPECT_EQ(v, 0.0F);
}

TEST(ObjectFeatures, EveryFeatureHasItsOwnName) {
  std::set<std::string> names;
  for (std::size_t i = 0; i < kFeatureCount; ++i) {
    const std::string name(featureName(static_cast<Feature>(i)));
    EXPECT_NE(name, "unknown");
    names.insert(name);
  }
  EXPECT_EQ(names.size(), kFeatureCount);
}

}  // namespace
}  // namespace fogmap
