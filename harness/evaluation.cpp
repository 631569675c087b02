#include "harness/evaluation.hpp"

#include <algorithm>
#include <string>
#include <utility>

#include "common/perception/clustering.hpp"

namespace fogmap::harness {

PointObjects madcPointObjects(const GlobalMapMessage& madc, const EdgeView& view) {
  std::map<EllipsoidId, std::int64_t> object_of;
  for (std::size_t o = 0; o < madc.map.objects.size(); ++o) {
    for (const auto& e : madc.map.objects[o].ellipsoids) object_of[e.id] = static_cast<std::int64_t>(o);
  }
  PointObjects out;
  std::int64_t noise = -1;
  for (const auto& [node, labels] : view.local_labels) {
    auto& objects = out[node];
    objects.reserve(labels.size());
    for (const auto l : labels) {
      std::int64_t o = noise;
      if (l >= 0) {
        const auto found = object_of.find({node, madc.header.epoch, static_cast<std::uint32_t>(l)});
        if (found != object_of.end()) o = found->second;
      }
      if (o == noise) --noise;
      objects.push_back(o);
    }
  }
  return out;
}

Expected<PointObjects> baselinePointObjects(const GlobalMapMessage& baseline, const EdgeView& view) {
  std::map<std::uint32_t, const std::vector<std::int32_t>*> central;
  for (const auto& nl : baseline.point_labels) central[nl.node] = &nl.labels;
  PointObjects out;
  std::int64_t noise = -1;
  for (const auto& [node, labels] : view.local_labels) {
    const auto it = central.find(node);
    if (it == central.end() || it->second->size() != labels.size()) {
      return invalidArgument("node " + std::to_string(node) + ": the baseline has " +
                             (it == central.end() ? std::string("no labels") : std::to_string(it->second->size()) + " labels") +
                             ", the edge " + std::to_string(labels.size()) + " points");
    }
    auto& objects = out[node];
    for (const auto l : *it->second) objects.push_back(l >= 0 ? l : noise--);
  }
  return out;
}

Expected<TruthScores> scoreAgainstTruth(const PointObjects& objects, const EdgeView& view, const ObjectMatchParams& params) {
  if (view.truth.empty()) return invalidArgument("the view has no truth (not a simulated scene)");
  std::vector<std::int64_t> found;
  std::vector<std::int64_t> truth;          // negative: no object
  std::vector<std::int64_t> truth_singles;  // the same, with every non-object point its own singleton
  std::int64_t single = -1;
  for (const auto& [node, node_truth] : view.truth) {
    const auto it = objects.find(node);
    if (it == objects.end() || it->second.size() != node_truth.size()) {
      return invalidArgument("node " + std::to_string(node) + ": " + std::to_string(node_truth.size()) +
                             " points with truth, " +
                             (it == objects.end() ? std::string("no labels") : std::to_string(it->second.size()) + " labels"));
    }
    found.insert(found.end(), it->second.begin(), it->second.end());
    for (const auto t : node_truth) {
      truth.push_back(t);
      truth_singles.push_back(t >= 0 ? t : single--);
    }
  }
  TruthScores scores;
  scores.point_count = found.size();
  auto rand = randScores(found, truth_singles);
  if (!rand) return rand.error();
  scores.points = *rand;
  auto outcomes = matchEachObject(truth, found, params);
  if (!outcomes) return outcomes.error();
  scores.objects = countOutcomes(*outcomes);
  scores.outcomes = std::move(*outcomes);
  return scores;
}

PrecisionRecall ellipsoidPrecisionRecall(const EdgeView& view, const EllipsoidParams& params) {
  PrecisionRecall out;
  double precision_sum = 0.0;
  double recall_sum = 0.0;
  for (const auto& [node, node_truth] : view.truth) {
    const auto points_it = view.points.find(node);
    const auto labels_it = view.local_labels.find(node);
    if (points_it == view.points.end() || labels_it == view.local_labels.end()) continue;
    const Cloud& points = points_it->second;
    const std::vector<std::int32_t>& labels = labels_it->second;
    if (points.size() != labels.size() || points.size() != node_truth.size()) continue;
    const Clustering clustering = canonicalize(labels);
    const auto summaries = summarizeClusters(points, clustering);
    std::map<std::int64_t, std::size_t> object_size;
    for (const auto t : node_truth) {
      if (t >= 0) ++object_size[t];
    }
    // Points of no true object vote too (as -1): a cluster mostly of them is not an object's.
    std::vector<std::map<std::int64_t, std::size_t>> votes(summaries.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
      const auto c = clustering.labels[i];
      if (c >= 0) ++votes[static_cast<std::size_t>(c)][node_truth[i] >= 0 ? node_truth[i] : -1];
    }
    for (std::size_t c = 0; c < summaries.size(); ++c) {
      if (votes[c].empty()) continue;
      const auto best = std::max_element(votes[c].begin(), votes[c].end(),
                                         [](const auto& a, const auto& b) { return a.second < b.second; });
      const std::int64_t object = best->first;
      if (object < 0) continue;  // mostly of no true object: ground left over
      const Ellipsoid e = ellipsoidFromSummary(summaries[c], {node, 0, static_cast<std::uint32_t>(c)}, params);
      std::size_t covered = 0;
      std::size_t correct = 0;
      for (std::size_t i = 0; i < points.size(); ++i) {
        if (!contains(e, Eigen::Vector3d(points[i].x, points[i].y, points[i].z))) continue;
        ++covered;
        if (node_truth[i] == object) ++correct;
      }
      precision_sum += covered > 0 ? static_cast<double>(correct) / static_cast<double>(covered) : 0.0;
      recall_sum += static_cast<double>(correct) / static_cast<double>(object_size.at(object));
      ++out.clusters;
    }
  }
  if (out.clusters > 0) {
    out.precision = precision_sum / static_cast<double>(out.clusters);
    out.recall = recall_sum / static_cast<double>(out.clusters);
  }
  return out;
}

}  // namespace fogmap::harness
