#include "common/classify/object_classifier.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/ml.hpp>

namespace fogmap {
namespace {

constexpr int kFormat = 1;
float finiteOr0(float value) { return std::isfinite(value) ? value : 0.0F; }

}  // namespace

void ConfusionMatrix::add(ObjectClass truth, ObjectClass predicted) {
  ++counts[static_cast<std::size_t>(truth)][static_cast<std::size_t>(predicted)];
}

std::size_t ConfusionMatrix::total() const {
  std::size_t n = 0;
  for (const auto& row : counts) {
    for (const auto c : row) n += c;
  }
  return n;
}

double ConfusionMatrix::accuracy() const {
  const std::size_t n = total();
  if (n == 0) return 0.0;
  std::size_t right = 0;
  for (std::size_t k = 0; k < kObjectClassCount; ++k) right += counts[k][k];
  return static_cast<double>(right) / static_cast<double>(n);
}

struct ObjectClassifier::Model {
  cv::Ptr<cv::ml::RTrees> forest;
};

ObjectClassifier::ObjectClassifier(std::unique_ptr<Model> model) : model_(std::move(model)) {}
ObjectClassifier::ObjectClassifier(ObjectClassifier&&) noexcept = default;
ObjectClassifier& ObjectClassifier::operator=(ObjectClassifier&&) noexcept = default;
ObjectClassifier::~ObjectClassifier() = default;

Expected<ObjectClassifier> ObjectClassifier::train(std::span<const LabelledFeatures> samples, const ForestParams& params) {
  if (samples.empty()) return invalidArgument("a classifier needs labelled samples, got none");
  if (params.trees < 1 || params.trees > 10000) {
    return invalidArgument("forest trees must be 1 to 10000, got " + std::to_string(params.trees));
  }
  if (params.max_depth < 1 || params.max_depth > 64) {
    return invalidArgument("forest max_depth must be 1 to 64, got " + std::to_string(params.max_depth));
  }
  if (params.min_samples < 1) return invalidArgument("forest min_samples must be at least 1, got " + std::to_string(params.min_samples));
  cv::Mat data(static_cast<int>(samples.size()), static_cast<int>(kFeatureCount), CV_32F);
  cv::Mat responses(static_cast<int>(samples.size()), 1, CV_32S);
  std::set<ObjectClass> classes;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    for (std::size_t k = 0; k < kFeatureCount; ++k) {
      const float v = samples[i].features[k];
      if (!std::isfinite(v)) {
        return invalidArgument("sample " + std::to_string(i) + " has a non-finite " + std::string(featureName(static_cast<Feature>(k))));
      }
      data.at<float>(static_cast<int>(i), static_cast<int>(k)) = v;
    }
    responses.at<int>(static_cast<int>(i), 0) = static_cast<int>(samples[i].object_class);
    classes.insert(samples[i].object_class);
  }
  if (classes.size() < 2) return invalidArgument("a classifier needs samples of at least two classes, got one");
  auto model = std::make_unique<Model>();
  try {
    cv::theRNG().state = params.seed;
    model->forest = cv::ml::RTrees::create();
    model->forest->setMaxDepth(params.max_depth);
    model->forest->setMinSampleCount(params.min_samples);
    model->forest->setMaxCategories(static_cast<int>(kObjectClassCount));
    model->forest->setUseSurrogates(false);
    model->forest->setCalculateVarImportance(false);
    model->forest->setActiveVarCount(0);  // the square root of the features at each split
    model->forest->setTermCriteria(cv::TermCriteria(cv::TermCriteria::MAX_ITER, params.trees, 0.0));
    if (!model->forest->train(cv::ml::TrainData::create(data, cv::ml::ROW_SAMPLE, responses))) {
      return Error{ErrorCode::kInternal, "the random forest did not train"};
    }
  } catch (const cv::Exception& e) {
    return Error{ErrorCode::kInternal, std::string("training the random forest failed: ") + e.what()};
  }
  return ObjectClassifier(std::move(model));
}

Status ObjectClassifier::save(const std::filesystem::path& file) const {
  try {
    cv::FileStorage out(file.string(), cv::FileStorage::WRITE);
    if (!out.isOpened()) return ioError(file.string() + ": cannot write the classifier model");
    out << "fogmap_classifier" << kFormat;
    out << "features" << "[";
    for (std::size_t k = 0; k < kFeatureCount; ++k) out << std::string(featureName(static_cast<Feature>(k)));
    out << "]";
    out << "classes" << "[";
    for (std::size_t k = 0; k < kObjectClassCount; ++k) out << std::string(objectClassName(static_cast<ObjectClass>(k)));
    out << "]";
    out << "model" << "{";
    model_->forest->write(out);
    out << "}";
    out.release();
  } catch (const cv::Exception& e) {
    return ioError(file.string() + ": writing the classifier model failed: " + e.what());
  }
  return {};
}

Expected<ObjectClassifier> ObjectClassifier::load(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) return notFound(file.string() + ": no classifier model file");
  auto model = std::make_unique<Model>();
  try {
    cv::FileStorage in(file.string(), cv::FileStorage::READ);
    if (!in.isOpened()) return invalidArgument(file.string() + ": not a classifier model (not OpenCV YAML, XML or JSON)");
    if (in["fogmap_classifier"].empty() || static_cast<int>(in["fogmap_classifier"]) != kFormat) {
      return invalidArgument(file.string() + ": not a fogmap classifier model (no fogmap_classifier: " + std::to_string(kFormat) + ")");
    }
    std::vector<std::string> features;
    in["features"] >> features;
    for (std::size_t k = 0; k < std::max(features.size(), kFeatureCount); ++k) {
      const std::string expected = k < kFeatureCount ? std::string(featureName(static_cast<Feature>(k))) : "(none)";
      const std::string found = k < features.size() ? features[k] : "(none)";
      if (expected != found) {
        return invalidArgument(file.string() + ": trained on other features: feature " + std::to_string(k) + " is " + found +
                               ", this build computes " + expected);
      }
    }
    model->forest = cv::Algorithm::read<cv::ml::RTrees>(in["model"]);
  } catch (const cv::Exception& e) {
    return invalidArgument(file.string() + ": not a classifier model: " + e.what());
  }
  if (model->forest.empty() || !model->forest->isTrained() || !model->forest->isClassifier()) {
    return invalidArgument(file.string() + ": holds no trained random forest classifier");
  }
  return ObjectClassifier(std::move(model));
}

ObjectLabel ObjectClassifier::classify(const FeatureVector& features) const {
  cv::Mat sample(1, static_cast<int>(kFeatureCount), CV_32F);
  for (std::size_t k = 0; k < kFeatureCount; ++k) sample.at<float>(0, static_cast<int>(k)) = finiteOr0(features[k]);
  cv::Mat votes;
  model_->forest->getVotes(sample, votes, 0);
  // Row 0: the class labels; row 1: this sample's votes for each.
  ObjectLabel out;
  int best = -1;
  int total = 0;
  for (int c = 0; c < votes.cols; ++c) {
    const int v = votes.at<int>(1, c);
    total += v;
    if (best < 0 || v > votes.at<int>(1, best)) best = c;
  }
  if (best < 0 || total == 0) return out;
  const int label = votes.at<int>(0, best);
  if (label >= 0 && label < static_cast<int>(kObjectClassCount)) out.object_class = static_cast<ObjectClass>(label);
  out.confidence = static_cast<double>(votes.at<int>(1, best)) / static_cast<double>(total);
  return out;
}

}  // namespace fogmap
