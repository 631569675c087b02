#pragma once
// LiDAR-only classification of objects (the DEBS 2019 Grand Challenge task): a random forest
// (OpenCV's ml module) over a cluster's features (common/perception/object_features.hpp). Domain
// types only; OpenCV stays inside the unit. A model file records the feature names it was trained
// on, and a model trained on other features is refused.
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string_view>

#include "common/base/status.hpp"
#include "common/geometry/object_class.hpp"
#include "common/perception/object_features.hpp"

namespace fogmap {

struct LabelledFeatures {
  FeatureVector features{};
  ObjectClass object_class = ObjectClass::kOther;
};

struct ForestParams {
  int trees = 100;
  int max_depth = 12;
  int min_samples = 2;   // at a leaf
  std::uint64_t seed = 1;  // OpenCV's random generator, for a training that repeats
};

// Counts of (true class, predicted class).
struct ConfusionMatrix {
  std::array<std::array<std::size_t, kObjectClassCount>, kObjectClassCount> counts{};
  void add(ObjectClass truth, ObjectClass predicted);
  std::size_t total() const;
  double accuracy() const;  // 0 when empty
};

class ObjectClassifier {
 public:
  // Errors (invalid argument) without samples, with non-finite features, with fewer than two
  // classes among the labels, or with parameters out of range (trees 1 to 10,000, depth 1 to 64,
  // min_samples at least 1).
  static Expected<ObjectClassifier> train(std::span<const LabelledFeatures> samples, const ForestParams& params = {});
  // Errors naming the file: missing, not a model, or trained on other features.
  static Expected<ObjectClassifier> load(const std::filesystem::path& file);
  Status save(const std::filesystem::path& file) const;

  // The class with the most votes; confidence is the fraction of the trees that vote for it.
  // Non-finite features are read as 0.
  ObjectLabel classify(const FeatureVector& features) const;

  ObjectClassifier(ObjectClassifier&&) noexcept;
  ObjectClassifier& operator=(ObjectClassifier&&) noexcept;
  ~ObjectClassifier();

 private:
  struct Model;
  explicit ObjectClassifier(std::unique_ptr<Model> model);
  std::unique_ptr<Model> model_;
};

}  // namespace fogmap
