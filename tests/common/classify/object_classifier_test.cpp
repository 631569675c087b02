#include "common/classify/object_classifier.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "tests/support/scratch_dir.hpp"

namespace fogmap {
namespace {

namespace fs = std::filesystem;

// Features drawn around a class's typical values (size, shape, height profile), 10 % noise.
FeatureVector draw(ObjectClass c, std::mt19937& rng) {
  std::normal_distribution<double> noise(1.0, 0.1);
  FeatureVector f{};
  auto set = [&](Feature k, double v) { f[static_cast<std::size_t>(k)] = static_cast<float>(v * noise(rng)); };
  switch (c) {
    case ObjectClass::kPerson: set(Feature::kLength, 0.6); set(Feature::kWidth, 0.4); set(Feature::kHeight, 1.7); set(Feature::kLinearity, 0.6); set(Feature::kVerticality, 0.95); break;
    case ObjectClass::kCar: set(Feature::kLength, 4.4); set(Feature::kWidth, 1.8); set(Feature::kHeight, 1.5); set(Feature::kLinearity, 0.5); set(Feature::kVerticality, 0.1); break;
    case ObjectClass::kPole: set(Feature::kLength, 0.25); set(Feature::kWidth, 0.2); set(Feature::kHeight, 3.5); set(Feature::kLinearity, 0.97); set(Feature::kVerticality, 1.0); break;
    default: set(Feature::kLength, 1.0); set(Feature::kWidth, 1.0); set(Feature::kHeight, 1.0); set(Feature::kLinearity, 0.2); set(Feature::kVerticality, 0.5); break;
  }
  set(Feature::kRange, 15.0);
  set(Feature::kLogPoints, 5.0);
  return f;
}

std::vector<LabelledFeatures> samples(int per_class, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<LabelledFeatures> out;
  for (int i = 0; i < per_class; ++i) {
    for (const ObjectClass c : {ObjectClass::kPerson, ObjectClass::kCar, ObjectClass::kPole, ObjectClass::kOther}) {
      out.push_back({draw(c, rng), c});
    }
  }
  return out;
}

TEST(ObjectClassifier, LearnsSeparableClassesAndClassifiesHeldOutSamples) {
  const auto train = samples(60, 1);
  const auto test = samples(50, 2);
  const auto classifier = ObjectClassifier::train(train, ForestParams{50, 8, 2, 1});
  ASSERT_TRUE(classifier.ok()) << classifier.error().message;
  ConfusionMatrix confusion;
  for (const auto& s : test) {
    const ObjectLabel c = classifier->classify(s.features);
    EXPECT_GE(c.confidence, 0.0);
    EXPECT_LE(c.confidence, 1.0);
    confusion.add(s.object_class, c.object_class);
  }
  EXPECT_EQ(confusion.total(), test.size());
  EXPECT_GE(confusion.accuracy(), 0.95);
  // A clear person: most of the trees agree.
  std::mt19937 rng(3);
  FeatureVector person = draw(ObjectClass::kPerson, rng);
  const ObjectLabel p = classifier->classify(person);
  EXPECT_EQ(p.object_class, ObjectClass::kPerson);
  EXPECT_GT(p.confidence, 0.5);
}

TEST(ObjectClassifier, ASavedModelLoadsAndClassifiesAlikeAndTrainingRepeats) {
  const auto train = samples(40, 5);
  const auto first = ObjectClassifier::train(train, ForestParams{30, 8, 2, 7});
  const auto second = ObjectClassifier::train(train, ForestParams{30, 8, 2, 7});
  ASSERT_TRUE(first.ok() && second.ok());
  const test_support::ScratchDir dir("classifier-roundtrip");
  const fs::path file = dir.path() / "model.yml";
  ASSERT_TRUE(first->save(file).ok());
  const auto loaded = ObjectClassifier::load(file);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  for (const auto& s : samples(20, 6)) {
    const ObjectLabel a = first->classify(s.features);
    const ObjectLabel b = loaded->classify(s.features);
    const ObjectLabel c = second->classify(s.features);
    EXPECT_EQ(a.object_class, b.object_class);
    EXPECT_DOUBLE_EQ(a.confidence, b.confidence);
    EXPECT_EQ(a.object_class, c.object_class);
    EXPECT_DOUBLE_EQ(a.confidence, c.confidence);
  }
}

TEST(ObjectClassifier, AMissingCorruptOrForeignModelIsRefusedNamingTheFile) {
  const fs::path missing = fs::temp_directory_path() / "fogmap_no_such_classifier.yml";
  const auto none = ObjectClassifier::load(missing);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message.find(missing.string()), std::string::npos) << none.error().message;

  const test_support::ScratchDir dir("classifier-refused");
  const fs::path garbage = dir.path() / "garbage.yml";
  std::ofstream(garbage) << "%YAML:1.0\n---\nthis: [is, not\n";
  const auto corrupt = ObjectClassifier::load(garbage);
  ASSERT_FALSE(corrupt.ok());
  EXPECT_NE(corrupt.error().message.find(garbage.string()), std::string::npos) << corrupt.error().message;

  const fs::path other = dir.path() / "other.yml";
  std::ofstream(other) << "%YAML:1.0\n---\nsomething: 1\n";
  const auto foreign = ObjectClassifier::load(other);
  ASSERT_FALSE(foreign.ok());
  EXPECT_NE(foreign.error().message.find("not a fogmap classifier"), std::string::npos) << foreign.error().message;

  // A model trained on other features: its feature list differs from this build's.
  const auto classifier = ObjectClassifier::train(samples(10, 8), ForestParams{5, 4, 2, 1});
  ASSERT_TRUE(classifier.ok());
  const fs::path renamed = dir.path() / "renamed.yml";
  ASSERT_TRUE(classifier->save(renamed).ok());
  std::string yaml = test_support::readFile(renamed);
  const auto at = yaml.find("log_points");
  ASSERT_NE(at, std::string::npos);
  yaml.replace(at, 10, "point_count");
  std::ofstream(renamed) << yaml;
  const auto stale = ObjectClassifier::load(renamed);
  ASSERT_FALSE(stale.ok());
  EXPECT_NE(stale.error().message.find("point_count"), std::string::npos) << stale.error().message;
  EXPECT_NE(stale.error().message.find("log_points"), std::string::npos) << stale.error().message;
}

TEST(ObjectClassifier, TrainingRefusesWhatCannotMakeAClassifier) {
  EXPECT_FALSE(ObjectClassifier::train({}).ok());
  std::vector<LabelledFeatures> one_class(5, LabelledFeatures{FeatureVector{}, ObjectClass::kCar});
  const auto single = ObjectClassifier::train(one_class);
  ASSERT_FALSE(single.ok());
  EXPECT_NE(single.error().message.find("two classes"), std::string::npos);
  auto bad = samples(5, 9);
  bad[3].features[static_cast<std::size_t>(Feature::kHeight)] = std::nanf("");
  const auto nan = ObjectClassifier::train(bad);
  ASSERT_FALSE(nan.ok());
  EXPECT_NE(nan.error().message.find("height"), std::string::npos) << nan.error().message;
  EXPECT_FALSE(ObjectClassifier::train(samples(5, 9), ForestParams{0, 8, 2, 1}).ok());
  EXPECT_FALSE(ObjectClassifier::train(samples(5, 9), ForestParams{10, 0, 2, 1}).ok());
  EXPECT_FALSE(ObjectClassifier::train(samples(5, 9), ForestParams{10, 8, 0, 1}).ok());
}

TEST(ObjectClassifier, ClassNamesRoundTrip) {
  for (std::size_t k = 0; k < kObjectClassCount; ++k) {
    const auto c = static_cast<ObjectClass>(k);
    EXPECT_EQ(parseObjectClass(objectClassName(c)), c);
  }
  EXPECT_FALSE(parseObjectClass("bicycle").has_value());
  ConfusionMatrix empty;
  EXPECT_EQ(empty.accuracy(), 0.0);
}

}  // namespace
}  // namespace fogmap
