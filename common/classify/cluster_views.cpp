#include "common/classify/cluster_views.hpp"

#include <algorithm>

#include "common/perception/box_fitting.hpp"
#include "common/perception/object_features.hpp"

namespace fogmap {

std::vector<Cloud> pointsByCluster(std::span<const Point> points, const Clustering& clustering) {
  std::vector<Cloud> clusters(static_cast<std::size_t>(std::max(clustering.cluster_count, 0)));
  for (std::size_t i = 0; i < points.size() && i < clustering.labels.size(); ++i) {
    const std::int32_t label = clustering.labels[i];
    if (label >= 0 && static_cast<std::size_t>(label) < clusters.size()) {
      clusters[static_cast<std::size_t>(label)].push_back(points[i]);
    }
  }
  return clusters;
}

Expected<std::vector<std::optional<ClusterView>>> clusterViews(std::span<const Point> points, const Clustering& clustering,
                                                               const Eigen::Vector3d& sensor,
                                                               const ObjectClassifier* classifier,
                                                               std::size_t min_points) {
  const std::vector<Cloud> clusters = pointsByCluster(points, clustering);
  std::vector<std::optional<ClusterView>> views(clusters.size());
  for (std::size_t c = 0; c < clusters.size(); ++c) {
    if (clusters[c].empty() || clusters[c].size() < min_points) continue;
    auto box = fitOrientedBox(clusters[c], sensor);
    if (!box) return box.error();
    ClusterView view{clusters[c].size(), *box, std::nullopt};
    if (classifier != nullptr) view.label = classifier->classify(objectFeatures(clusters[c], *box, sensor));
    views[c] = view;
  }
  return views;
}

void attachViews(std::span<const std::optional<ClusterView>> views, Map& local) {
  for (MapObject& object : local.objects) {
    for (Ellipsoid& e : object.ellipsoids) {
      if (e.id.index >= views.size() || !views[e.id.index]) continue;
      e.box = views[e.id.index]->box;
      e.label = views[e.id.index]->label;
    }
  }
}

}  // namespace fogmap
