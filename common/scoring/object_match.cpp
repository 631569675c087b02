#include "common/scoring/object_match.hpp"

#include <algorithm>
#include <map>
#include <string>

namespace fogmap {

Expected<std::vector<ObjectOutcome>> matchEachObject(std::span<const std::int64_t> truth,
                                                     std::span<const std::int64_t> clusters,
                                                     const ObjectMatchParams& params) {
  if (truth.size() != clusters.size()) {
    return invalidArgument("matchObjects: " + std::to_string(truth.size()) + " true labels but " +
                           std::to_string(clusters.size()) + " cluster labels");
  }
  // Points of each true object, and how many of them each cluster has.
  std::map<std::int64_t, std::size_t> size_of;
  std::map<std::int64_t, std::map<std::int64_t, std::size_t>> overlap;  // true -> cluster -> points
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (truth[i] < 0) continue;
    ++size_of[truth[i]];
    if (clusters[i] >= 0) ++overlap[truth[i]][clusters[i]];
  }
  auto holds = [&](std::int64_t object, std::size_t points) {
    return static_cast<double>(points) >= params.share * static_cast<double>(size_of.at(object));
  };
  // Which counted true objects each cluster holds.
  std::map<std::int64_t, std::size_t> objects_held_by;
  for (const auto& [object, by_cluster] : overlap) {
    if (size_of.at(object) < params.min_points) continue;
    for (const auto& [cluster, points] : by_cluster) {
      if (holds(object, points)) ++objects_held_by[cluster];
    }
  }
  std::vector<ObjectOutcome> out;
  for (const auto& [object, size] : size_of) {
    if (size < params.min_points) continue;
    const auto it = overlap.find(object);
    std::size_t holding = 0;
    std::int64_t best = -1;
    std::size_t best_points = 0;
    if (it != overlap.end()) {
      for (const auto& [cluster, points] : it->second) {
        if (holds(object, points)) ++holding;
        if (points > best_points) {
          best_points = points;
          best = cluster;
        }
      }
    }
    const bool found = best >= 0 && static_cast<double>(best_points) >= params.found * static_cast<double>(size);
    const bool split = holding >= 2;
    const bool merged = found && objects_held_by[best] >= 2;
    out.push_back({object, size, found && !split && !merged, split, merged, !found});
  }
  return out;
}

ObjectMatch countOutcomes(std::span<const ObjectOutcome> outcomes) {
  ObjectMatch out;
  out.objects_true = outcomes.size();
  for (const auto& o : outcomes) {
    if (o.found_whole) ++out.found_whole;
    if (o.split) ++out.split;
    if (o.merged) ++out.merged;
    if (o.missed) ++out.missed;
  }
  return out;
}

Expected<ObjectMatch> matchObjects(std::span<const std::int64_t> truth, std::span<const std::int64_t> clusters,
                                   const ObjectMatchParams& params) {
  auto outcomes = matchEachObject(truth, clusters, params);
  if (!outcomes) return outcomes.error();
  return countOutcomes(*outcomes);
}

}  // namespace fogmap
