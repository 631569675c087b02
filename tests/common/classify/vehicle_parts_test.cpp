// joinedVehicleParts: a car a sensor sees in pieces is one cluster; two cars, or a car and a person,
// stay apart. On hand-made faces with known answers, and on the real labelled KITTI car.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/base/angles.hpp"
#include "common/camera/kitti.hpp"
#include "common/classify/cluster_views.hpp"
#include "common/io/cloud_io.hpp"
#include "common/perception/box_fitting.hpp"
#include "common/perception/lidar_models.hpp"
#include "common/perception/preprocess.hpp"
#include "common/perception/sensor_clustering.hpp"
#include "tests/support/scratch_dir.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap {
namespace {

namespace fs = std::filesystem;
using test_support::kSourceDir;

const Eigen::Vector3d kSensor = Eigen::Vector3d::Zero();

// A face seen from the sensor at the origin: points every 0.1 m from (x, y0) to (x, y1) at heights
// z0 .. z1 (every 0.1 m), all on cluster `label`.
void addFace(Cloud& points, std::vector<std::int32_t>& labels, std::int32_t label, double x, double y0, double y1, double z0,
             double z1) {
  for (double z = z0; z <= z1 + 1e-9; z += 0.1) {
    for (double y = y0; y <= y1 + 1e-9; y += 0.1) {
      points.push_back({static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)});
      labels.push_back(label);
    }
  }
}

// The views as an edge makes them, with the given class per cluster.
std::vector<std::optional<ClusterView>> viewsOf(const Cloud& points, const Clustering& clustering,
                                                const std::vector<std::optional<ObjectClass>>& classes) {
  auto views = clusterViews(points, clustering, kSensor, nullptr);
  EXPECT_TRUE(views.ok());
  for (std::size_t c = 0; c < views->size(); ++c) {
    if ((*views)[c] && classes[c]) (*views)[c]->label = ObjectLabel{*classes[c], 0.9};
  }
  return *views;
}

// Two parts each rule but `rule` would join: both classed car, their boxes grown to a car overlap;
// joinedVehicleParts must keep them apart.
void expectApartByTheirRule(const Cloud& points, const std::vector<std::int32_t>& labels, const std::string& rule) {
  SCOPED_TRACE(rule);
  const Clustering clustering = canonicalize(labels);
  const auto views = viewsOf(points, clustering, {ObjectClass::kCar, ObjectClass::kCar});
  ASSERT_TRUE(views[0] && views[1]);
  ASSERT_TRUE(footprintsOverlap(grownToPrior(views[0]->box, kSensor, BoxPrior{}), grownToPrior(views[1]->box, kSensor, BoxPrior{})))
      << "the case must test the " << rule << " rule, not the overlap";
  const auto joined = joinedVehicleParts(points, clustering, views, kSensor);
  ASSERT_TRUE(joined.ok()) << joined.error().message;
  EXPECT_FALSE(joined->has_value());
}

// The lower band of a car's rear 20 m ahead, 1.7 m wide, and an upper band at `upper_x`, both
// classed car, joined or not.
Expected<std::optional<JoinedParts>> bandsJoined(double upper_x, Clustering* clustering) {
  Cloud points;
  std::vector<std::int32_t> labels;
  addFace(points, labels, 0, 20.0, -0.85, 0.85, 0.3, 0.5);
  addFace(points, labels, 1, upper_x, -0.8, 0.8, 0.9, 1.2);
  *clustering = canonicalize(labels);
  const auto views = viewsOf(points, *clustering, {ObjectClass::kCar, ObjectClass::kCar});
  return joinedVehicleParts(points, *clustering, views, kSensor);
}

// The rear of a car seen as two bands a missing ring apart and 0.5 m apart in depth (a bumper, then
// a sloped boot): one car, one cluster.
TEST(VehicleParts, TheTwoBandsOfOneCarsRearAreOneCluster) {
  Clustering clustering;
  const auto joined = bandsJoined(20.5, &clustering);
  ASSERT_TRUE(joined.ok()) << joined.error().message;
  ASSERT_TRUE(joined->has_value());
  EXPECT_EQ(clustering.cluster_count, 2);
  EXPECT_EQ((*joined)->clustering.cluster_count, 1);
  EXPECT_TRUE(std::all_of((*joined)->clustering.labels.begin(), (*joined)->clustering.labels.end(), [](std::int32_t l) { return l == 0; }));
}

// Parts that are no vehicle's (a person's class and a short box) are never joined, even where a
// car's part would be.
TEST(VehicleParts, PartsThatAreNoVehiclesStayApart) {
  Cloud points;
  std::vector<std::int32_t> labels;
  addFace(points, labels, 0, 20.0, -0.7, 0.7, 0.3, 0.5);  // 1.4 m: a vehicle only by its class
  addFace(points, labels, 1, 20.5, -0.6, 0.6, 0.9, 1.2);
  const Clustering clustering = canonicalize(labels);
  for (const auto second : {ObjectClass::kPerson, ObjectClass::kOther, ObjectClass::kCar}) {
    const auto views = viewsOf(points, clustering, {ObjectClass::kCar, second});
    const auto joined = joinedVehicleParts(points, clustering, views, kSensor);
    ASSERT_TRUE(joined.ok());
    EXPECT_EQ(joined->has_value(), second == ObjectClass::kCar) << objectClassName(second);
  }
}

// Each rule alone keeps two vehicles' parts apart, on cases where the others would join them.
// The lower band of a car's rear under a wider part 3 m square (a lorry's load hanging over it):
// one lies above the other and their boxes grown to a car overlap, but together they are wider
// than any car.
TEST(VehicleParts, StackedPartsWiderThanAnyCarStayApart) {
  Cloud points;
  std::vector<std::int32_t> labels;
  addFace(points, labels, 0, 20.0, -0.9, 0.9, 0.3, 0.5);
  for (double x = 20.5; x <= 23.5 + 1e-9; x += 0.1) addFace(points, labels, 1, x, -1.5, 1.5, 1.6, 1.7);
  expectApartByTheirRule(points, labels, "size");
}

// The lower band of a car's rear, and 2 m behind it, what is seen of someone over its roof, classed
// car (a small blob): within a car's size, stacked as the sensor sees them, their grown boxes
// overlap, but they lie 2 m apart in range.
TEST(VehicleParts, WhatIsSeenOverACarsRoofStaysApart) {
  Cloud points;
  std::vector<std::int32_t> labels;
  addFace(points, labels, 0, 20.0, -0.85, 0.85, 0.3, 1.3);
  addFace(points, labels, 1, 22.0, -0.2, 0.2, 1.4, 1.7);
  expectApartByTheirRule(points, labels, "range");
}

// Two parts side by side, 2.0 m wide together (part of a car's rear and a wall or a parked car
// beside it): within a car's size and their grown boxes overlap, but neither lies above the
// other: at the same heights, or one higher but beside the other as the sensor sees them.
TEST(VehicleParts, PartsSideBySideStayApart) {
  for (const double upper : {0.3, 1.3}) {
    Cloud points;
    std::vector<std::int32_t> labels;
    addFace(points, labels, 0, 20.0, -0.8, 0.3, 0.3, 1.2);
    addFace(points, labels, 1, 20.0, 0.5, 1.2, upper, upper + 0.9);
    expectApartByTheirRule(points, labels, "stacking, upper part from " + std::to_string(upper) + " m");
  }
}

// Stacked bands whose boxes grown to a car do not overlap: the upper band 5 m beyond the lower.
TEST(VehicleParts, StackedBandsFurtherApartThanOneCarStayApart) {
  Clustering clustering;
  const auto joined = bandsJoined(25.0, &clustering);
  ASSERT_TRUE(joined.ok()) << joined.error().message;
  EXPECT_FALSE(joined->has_value());
}

// The real labelled KITTI frames, through the edge's steps (ground removal, sensor-aware clustering
// for the HDL-64E, views with the bundled classifier, vehicle parts joined): every labelled Car with
// at least 50 points (one, in 000002, 34 m away) is one object whose box, grown to a car from the
// face its sensor saw, has its centre within 0.5 m of the label's and its yaw within 15 degrees
// (modulo 180): the goal. Without the join the car is two clusters, a bumper and a sloped
// boot 0.5 m apart with a ring between them that returned nothing, and the larger one's box is
// 0.53 m off.
TEST(VehicleParts, TheLabelledKittiCarIsOneObjectWithItsCentreAndYaw) {
  const auto classifier = ObjectClassifier::load(kSourceDir / "data/models/lidar_classifier.yml.gz");
  ASSERT_TRUE(classifier.ok()) << classifier.error().message;
  const auto model = lidarModel("HDL-64E");
  ASSERT_TRUE(model.ok());
  SensorClusteringParams sensor_params;
  sensor_params.links.beams = beamTableOf(*model);
  int checked = 0;
  for (const std::string id : {"000001", "000002"}) {
    SCOPED_TRACE("kitti " + id);
    const fs::path data = kSourceDir / "data/kitti_object";
    const auto scan = readKittiBin(data / "velodyne" / (id + ".bin"));
    ASSERT_TRUE(scan.ok()) << scan.error().message;
    const auto calibration = camera::parseKittiCalibration(test_support::readFile(data / "calib" / (id + ".txt")));
    ASSERT_TRUE(calibration.ok()) << calibration.error().message;
    const auto labels = camera::parseKittiLabels(test_support::readFile(data / "label_2" / (id + ".txt")));
    ASSERT_TRUE(labels.ok()) << labels.error().message;
    const auto ground = removeGround(scan->points, GroundParams{});
    ASSERT_TRUE(ground.ok()) << ground.error().message;
    const Cloud& points = ground->non_ground;
    const auto clustered = sensorAwareClusters(points, sensor_params);
    ASSERT_TRUE(clustered.ok()) << clustered.error().message;
    const auto views = clusterViews(points, *clustered, kSensor, &*classifier);
    ASSERT_TRUE(views.ok()) << views.error().message;
    const auto joined = joinedVehicleParts(points, *clustered, *views, kSensor);
    ASSERT_TRUE(joined.ok()) << joined.error().message;
    const Clustering& clusters = joined->has_value() ? (*joined)->clustering : *clustered;
    const auto& car_views = joined->has_value() ? (*joined)->views : *views;
    for (const auto& label : *labels) {
      if (label.type != "Car") continue;
      const camera::VelodyneBox truth = camera::labelBoxInVelodyne(label, *calibration);
      std::map<std::int32_t, int> votes;  // cluster -> the label's points in it
      int inside = 0;
      for (std::size_t i = 0; i < points.size(); ++i) {
        if (truth.contains(points[i].xyz().cast<double>())) {
          ++inside;
          ++votes[clusters.labels[i]];
        }
      }
      std::cout << "kitti " << id << " Car at " << truth.centre.head<2>().transpose() << ": " << inside << " points";
      for (const auto& [cluster, count] : votes) std::cout << " " << cluster << ":" << count;
      std::cout << "\n";
      if (inside < 50) continue;
      votes.erase(-1);  // points below the clusters' min_points are nobody's object
      ASSERT_EQ(votes.size(), 1u) << "the car is not one object";
      const std::int32_t car = votes.begin()->first;
      std::map<std::int32_t, int> parts;  // the sensor-aware clusters the car's cluster joined
      for (std::size_t i = 0; i < points.size(); ++i) {
        if (clusters.labels[i] == car) ++parts[clustered->labels[i]];
      }
      for (const auto& [part, count] : parts) {
        std::cout << "  part " << part << ": " << count << " points";
        if (part >= 0 && (*views)[static_cast<std::size_t>(part)]) {
          const ClusterView& v = *(*views)[static_cast<std::size_t>(part)];
          std::cout << ", box at " << v.box.centre.transpose() << ", " << v.box.length << " x " << v.box.width << " x " << v.box.height
                    << " m, " << (v.label ? objectClassName(v.label->object_class) : "no class");
        }
        std::cout << "\n";
      }
      ASSERT_TRUE(car_views[static_cast<std::size_t>(car)]) << "the car has no view";
      const ClusterView& view = *car_views[static_cast<std::size_t>(car)];
      ASSERT_TRUE(view.label && view.label->object_class == ObjectClass::kCar) << "the car is not classed car";
      const OrientedBox* fitted = &view.box;
      const OrientedBox box = grownToPrior(*fitted, kSensor, BoxPrior{});
      const double centre_error = (box.centre.head<2>() - truth.centre.head<2>()).norm();
      const double yaw_error = axisAngleBetween(box.yaw, truth.yaw) / kDegToRad;
      std::cout << "  one cluster of " << view.points << " points, fitted " << fitted->length << " x " << fitted->width
                << " m: centre error " << centre_error << " m, yaw error " << yaw_error << " deg\n";
      EXPECT_LT(centre_error, 0.5);
      EXPECT_LT(yaw_error, 15.0);
      ++checked;
    }
  }
  EXPECT_EQ(checked, 1);
}

}  // namespace
}  // namespace fogmap
