// fogctl train-classifier: the LiDAR-only classifier trained on simulated scenes of some seeds and
// scored on scenes of others (harness/classifier_training).
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "common/classify/object_classifier.hpp"
#include "harness/classifier_training.hpp"
#include "tools/fogctl/args.hpp"
#include "tools/fogctl/commands.hpp"

namespace fogmap::cli {
namespace {

using Clock = std::chrono::steady_clock;
constexpr const char* kWho = "fogctl train-classifier";

// "A-B" (inclusive) or "A,B,C": at most 10,000 seeds.
Expected<std::vector<std::uint64_t>> parseSeeds(const std::string& flag, const std::string& text) {
  std::vector<std::uint64_t> seeds;
  auto number = [&](const std::string& s) -> Expected<std::uint64_t> {
    if (s.empty() || s.find_first_not_of("0123456789") != std::string::npos || s.size() > 12) {
      return invalidArgument("--" + flag + " takes seeds as A-B or A,B,C (non-negative integers), got '" + text + "'");
    }
    return std::stoull(s);
  };
  if (const auto dash = text.find('-'); dash != std::string::npos) {
    const auto first = number(text.substr(0, dash));
    if (!first) return first.error();
    const auto last = number(text.substr(dash + 1));
    if (!last) return last.error();
    if (*last < *first || *last - *first >= 10000) {
      return invalidArgument("--" + flag + " A-B needs A <= B and at most 10000 seeds, got '" + text + "'");
    }
    for (auto s = *first; s <= *last; ++s) seeds.push_back(s);
    return seeds;
  }
  std::size_t start = 0;
  while (start <= text.size()) {
    const auto comma = text.find(',', start);
    const auto seed = number(text.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (!seed) return seed.error();
    seeds.push_back(*seed);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (seeds.size() > 10000) return invalidArgument("--" + flag + " takes at most 10000 seeds");
  return seeds;
}

void printCounts(const char* what, const std::vector<LabelledFeatures>& samples) {
  std::array<std::size_t, kObjectClassCount> n{};
  for (const auto& s : samples) ++n[static_cast<std::size_t>(s.object_class)];
  std::printf("%s: %zu samples:", what, samples.size());
  for (std::size_t k = 0; k < kObjectClassCount; ++k) {
    if (n[k] > 0) std::printf(" %s %zu", std::string(objectClassName(static_cast<ObjectClass>(k))).c_str(), n[k]);
  }
  std::printf("\n");
}

void printConfusion(const ConfusionMatrix& m) {
  std::printf("%-14s", "true \\ class");
  for (std::size_t k = 0; k < kObjectClassCount; ++k) std::printf(" %12s", std::string(objectClassName(static_cast<ObjectClass>(k))).c_str());
  std::printf(" %8s\n", "recall");
  for (std::size_t t = 0; t < kObjectClassCount; ++t) {
    std::size_t row = 0;
    for (const auto c : m.counts[t]) row += c;
    if (row == 0) continue;
    std::printf("%-14s", std::string(objectClassName(static_cast<ObjectClass>(t))).c_str());
    for (const auto c : m.counts[t]) std::printf(" %12zu", c);
    std::printf(" %8.3f\n", static_cast<double>(m.counts[t][t]) / static_cast<double>(row));
  }
  std::printf("accuracy %.3f over %zu samples\n", m.accuracy(), m.total());
}

int runTrainClassifier(int argc, char** argv) {
  const auto args =
      Args::parse(argc, argv, 2, {"train-seeds", "test-seeds", "objects", "lidars", "trees", "depth", "out", "kitti"}, {});
  if (!args) return fail(args.error(), kWho);
  const auto train_seeds = parseSeeds("train-seeds", args->get("train-seeds", "1-30"));
  if (!train_seeds) return fail(train_seeds.error(), kWho);
  const auto test_seeds = parseSeeds("test-seeds", args->get("test-seeds", "1001-1010"));
  if (!test_seeds) return fail(test_seeds.error(), kWho);
  for (const auto s : *test_seeds) {
    if (std::find(train_seeds->begin(), train_seeds->end(), s) != train_seeds->end()) {
      return fail(invalidArgument("seed " + std::to_string(s) + " is in both --train-seeds and --test-seeds"), kWho);
    }
  }
  harness::SimSampleOptions options;
  const auto objects = args->getInt("objects", options.objects);
  if (!objects || *objects < 1 || *objects > 500) return fail(invalidArgument("--objects must be 1 to 500"), kWho);
  const auto lidars = args->getInt("lidars", options.lidars);
  if (!lidars || *lidars < 1 || *lidars > 7) return fail(invalidArgument("--lidars must be 1 to 7 (the paper's spots)"), kWho);
  options.objects = static_cast<int>(*objects);
  options.lidars = static_cast<int>(*lidars);
  ForestParams forest;
  const auto trees = args->getInt("trees", forest.trees);
  if (!trees) return fail(trees.error(), kWho);
  const auto depth = args->getInt("depth", forest.max_depth);
  if (!depth) return fail(depth.error(), kWho);
  forest.trees = static_cast<int>(*trees);
  forest.max_depth = static_cast<int>(*depth);

  const auto start = Clock::now();
  const auto train = harness::simulatedSamples(*train_seeds, options);
  if (!train) return fail(train.error(), kWho);
  const auto test = harness::simulatedSamples(*test_seeds, options);
  if (!test) return fail(test.error(), kWho);
  printCounts("training", train->samples);
  printCounts("held out", test->samples);
  std::printf("clusters without a majority object (not used): %zu of %zu, %zu of %zu\n", train->unlabelled, train->clusters,
              test->unlabelled, test->clusters);
  const auto classifier = ObjectClassifier::train(train->samples, forest);
  if (!classifier) return fail(classifier.error(), kWho);
  ConfusionMatrix confusion;
  for (const auto& s : test->samples) confusion.add(s.object_class, classifier->classify(s.features).object_class);
  std::printf("held-out seeds, confusion matrix (rows: the truth):\n");
  printConfusion(confusion);
  // The real labelled KITTI frames, scored apart: the model never sees them in training.
  const std::filesystem::path kitti = args->get("kitti", "data/kitti_object");
  if (std::filesystem::is_directory(kitti)) {
    const auto objects = harness::kittiObjects(kitti, &*classifier);
    if (!objects) return fail(objects.error(), kWho);
    ConfusionMatrix kitti_confusion;
    std::printf("real KITTI objects of %s with at least 20 points in their box, as the edge ships them:\n", kitti.string().c_str());
    for (const auto& o : *objects) {
      const bool classed = o.found && o.found->label;
      std::string found = "its points are noise";
      if (classed) {
        found = std::string(objectClassName(o.found->label->object_class)) + " (" +
                std::to_string(o.found->label->confidence).substr(0, 4) + "), object of " + std::to_string(o.found->points) +
                " points";
      }
      std::printf("  %s %-10s %4zu points at %5.1f m: %s\n", o.frame.c_str(), o.type.c_str(), o.points_in_box, o.range_m,
                  found.c_str());
      kitti_confusion.add(o.truth, classed ? o.found->label->object_class : ObjectClass::kOther);
    }
    printConfusion(kitti_confusion);
  } else if (args->has("kitti")) {
    return fail(notFound(kitti.string() + ": no such KITTI object directory"), kWho);
  }
  const std::string out = args->get("out", "data/models/lidar_classifier.yml.gz");
  if (const Status saved = classifier->save(out); !saved) return fail(saved.error(), kWho);
  std::printf("model written to %s (%d trees, depth %d) in %.1f s\n", out.c_str(), forest.trees, forest.max_depth,
              std::chrono::duration<double>(Clock::now() - start).count());
  return 0;
}

}  // namespace

Command trainClassifierCommand() {
  return {"train-classifier",
          "[--train-seeds 1-30] [--test-seeds 1001-1010] [--objects 60] [--lidars 4] [--trees 100] [--depth 12] [--out FILE] "
          "[--kitti DIR]",
          "usage: fogctl train-classifier [--train-seeds 1-30] [--test-seeds 1001-1010] [--objects 60] [--lidars 4]\n"
          "                               [--trees 100] [--depth 12] [--out data/models/lidar_classifier.yml.gz]\n"
          "                               [--kitti data/kitti_object]\n"
          "Trains the LiDAR-only classifier (a random forest over each cluster's features) on simulated random\n"
          "scenes (fogctl scene random) of the training seeds, each seen by its LiDARs (VLP-16, HDL-32E and\n"
          "HDL-64E by seed) through ground removal, sensor-aware clustering and the L-shape box, every cluster\n"
          "labelled by the object most of its points hit; prints the confusion matrix on the scenes of the\n"
          "held-out seeds and writes the model.\n"
          "  --train-seeds, --test-seeds   A-B or A,B,C; no seed in both\n"
          "  --objects N    objects per scene (1 to 500)     --lidars K   LiDARs per scene (1 to 7)\n"
          "  --trees N      trees of the forest (1 to 10000) --depth D    their depth (1 to 64)\n"
          "  --out FILE     the model (OpenCV YAML; .gz compresses)\n"
          "  --kitti DIR    also score the real labelled KITTI frames of DIR (velodyne/, calib/, label_2/; default\n"
          "                 data/kitti_object when it exists): every Car, Van, Truck, Pedestrian and Cyclist with at\n"
          "                 least 20 points in its box, as the object holding most of them (as an edge with boxes\n"
          "                 ships it: sensor-aware clustering, vehicle parts joined)\n",
          runTrainClassifier};
}

}  // namespace fogmap::cli
