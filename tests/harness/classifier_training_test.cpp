#include "harness/classifier_training.hpp"

#include <filesystem>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "common/sim/generators.hpp"
#include "tests/support/source_dir.hpp"

namespace fogmap::harness {
namespace {

namespace fs = std::filesystem;
using test_support::kSourceDir;

TEST(ClassifierTraining, LabelsMapOntoTheClasses) {
  EXPECT_EQ(classOfSceneLabel("person"), ObjectClass::kPerson);
  EXPECT_EQ(classOfSceneLabel("car"), ObjectClass::kCar);
  EXPECT_EQ(classOfSceneLabel("pole"), ObjectClass::kPole);
  EXPECT_EQ(classOfSceneLabel("truck"), ObjectClass::kTruckOrBus);
  EXPECT_EQ(classOfSceneLabel("crate"), ObjectClass::kOther);
  EXPECT_EQ(classOfKittiType("Car"), ObjectClass::kCar);
  EXPECT_EQ(classOfKittiType("Van"), ObjectClass::kTruckOrBus);
  EXPECT_EQ(classOfKittiType("Pedestrian"), ObjectClass::kPerson);
  EXPECT_EQ(classOfKittiType("Cyclist"), ObjectClass::kCyclist);
  EXPECT_FALSE(classOfKittiType("DontCare").has_value());
  EXPECT_EQ(lidarModelOfSeed(0), "VLP-16");
  EXPECT_EQ(lidarModelOfSeed(1), "HDL-32E");
  EXPECT_EQ(lidarModelOfSeed(2), "HDL-64E");
}

// Every sample's class is the class of an object of the scene, and each kind the scene holds
// near a LiDAR is seen at least once.
TEST(ClassifierTraining, SimulatedSamplesCarryTheClassesOfTheSceneObjects) {
  SimSampleOptions options;
  options.objects = 30;
  options.lidars = 2;
  const std::vector<std::uint64_t> seeds = {2};
  const auto set = simulatedSamples(seeds, options);
  ASSERT_TRUE(set.ok()) << set.error().message;
  ASSERT_FALSE(set->samples.empty());
  std::set<ObjectClass> in_scene;
  for (const auto& o : sim::randomScene(options.objects, options.lidars, 2).objects) in_scene.insert(classOfSceneLabel(o.label));
  std::set<ObjectClass> sampled;
  for (const auto& s : set->samples) {
    EXPECT_TRUE(in_scene.count(s.object_class)) << objectClassName(s.object_class);
    sampled.insert(s.object_class);
    // The simulator models no reflectance: its intensity features are 0.
    EXPECT_EQ(s.features[static_cast<std::size_t>(Feature::kIntensityMean)], 0.0F);
  }
  EXPECT_EQ(sampled, in_scene);
  EXPECT_EQ(set->clusters, set->samples.size() + set->unlabelled);
}

// The committed model (data/models, made by `fogctl train-classifier` with its defaults: seeds
// 1-30) loads in this build, classifies scenes of seeds it never saw at 90 % or better (the issue's
// goal; `fogctl train-classifier` reports 98 % on seeds 1001-1010), and classes the labelled KITTI
// Car with at least 50 points as a car, one object as the edge ships it.
TEST(ClassifierTraining, TheCommittedModelMeetsItsGoalsOnUnseenScenesAndOnKitti) {
  const auto classifier = ObjectClassifier::load(kSourceDir / "data/models/lidar_classifier.yml.gz");
  ASSERT_TRUE(classifier.ok()) << classifier.error().message << " (retrain with fogctl train-classifier)";
  const std::vector<std::uint64_t> seeds = {2001, 2002, 2003};
  const auto held_out = simulatedSamples(seeds);
  ASSERT_TRUE(held_out.ok()) << held_out.error().message;
  ConfusionMatrix confusion;
  for (const auto& s : held_out->samples) confusion.add(s.object_class, classifier->classify(s.features).object_class);
  std::printf("held-out seeds 2001-2003: accuracy %.3f over %zu samples\n", confusion.accuracy(), confusion.total());
  EXPECT_GE(confusion.accuracy(), 0.90);

  const auto objects = kittiObjects(kSourceDir / "data/kitti_object", &*classifier);
  ASSERT_TRUE(objects.ok()) << objects.error().message;
  int cars = 0;
  for (const auto& o : *objects) {
    if (o.truth != ObjectClass::kCar || o.points_in_box < 50) continue;
    ASSERT_TRUE(o.found.has_value()) << o.frame << ": the car's points are noise";
    ASSERT_TRUE(o.found->label.has_value()) << o.frame;
    EXPECT_EQ(o.found->label->object_class, ObjectClass::kCar) << o.frame << " " << objectClassName(o.found->label->object_class);
    EXPECT_EQ(o.clusters, 1U) << o.frame << ": the car is not one object";
    ++cars;
  }
  EXPECT_GE(cars, 1);
}

TEST(ClassifierTraining, AMissingKittiDirectoryIsNamed) {
  const auto none = kittiObjects("/nonexistent-kitti", nullptr);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message.find("nonexistent-kitti"), std::string::npos) << none.error().message;
}

}  // namespace
}  // namespace fogmap::harness
