#include "common/classify/cluster_views.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "common/geometry/oriented_box.hpp"
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

namespace {

// One box lies above the other as `sensor` sees it: their heights overlap by at most
// kStackedOverlapM, their near faces are at most kStackedDepthM apart in range, and their
// footprints' azimuth intervals from the sensor overlap by at least kStackedAzimuthShare of the
// narrower one.
constexpr double kStackedOverlapM = 0.05;
constexpr double kStackedAzimuthShare = 0.5;
constexpr double kStackedDepthM = 1.0;  // what is seen over a car's roof lies further behind it

// The azimuths of a footprint's corners, as angles from `reference` (radians, in (-pi, pi]).
std::pair<double, double> azimuthInterval(const OrientedBox& box, const Eigen::Vector2d& sensor, const Eigen::Vector2d& reference) {
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (const Eigen::Vector2d& corner : box.footprint()) {
    const Eigen::Vector2d d = corner - sensor;
    const double angle = std::atan2(reference.x() * d.y() - reference.y() * d.x(), reference.dot(d));
    lo = std::min(lo, angle);
    hi = std::max(hi, angle);
  }
  return {lo, hi};
}

// The horizontal distance from `sensor` to the nearest point of a box's footprint.
double nearestDistance(const OrientedBox& box, const Eigen::Vector2d& sensor) {
  const Eigen::Vector2d d = sensor - box.centre.head<2>();
  const Eigen::Vector2d along(std::cos(box.yaw), std::sin(box.yaw));
  const Eigen::Vector2d across(-along.y(), along.x());
  const double u = std::max(std::abs(d.dot(along)) - box.length / 2.0, 0.0);
  const double v = std::max(std::abs(d.dot(across)) - box.width / 2.0, 0.0);
  return std::hypot(u, v);
}

bool stacked(const OrientedBox& a, const OrientedBox& b, const Eigen::Vector3d& sensor) {
  const double a_top = a.centre.z() + a.height / 2.0, a_bottom = a.centre.z() - a.height / 2.0;
  const double b_top = b.centre.z() + b.height / 2.0, b_bottom = b.centre.z() - b.height / 2.0;
  if (!(a_top <= b_bottom + kStackedOverlapM || b_top <= a_bottom + kStackedOverlapM)) return false;
  const Eigen::Vector2d at = sensor.head<2>();
  if (std::abs(nearestDistance(a, at) - nearestDistance(b, at)) > kStackedDepthM) return false;
  const Eigen::Vector2d reference = a.centre.head<2>() - at;
  if (!(reference.squaredNorm() > 0.0)) return false;  // a box around the sensor is above nothing
  const auto [a_lo, a_hi] = azimuthInterval(a, at, reference);
  const auto [b_lo, b_hi] = azimuthInterval(b, at, reference);
  const double overlap = std::min(a_hi, b_hi) - std::max(a_lo, b_lo);
  return overlap >= kStackedAzimuthShare * std::min(a_hi - a_lo, b_hi - b_lo);
}

}  // namespace

Expected<std::optional<JoinedParts>> joinedVehicleParts(std::span<const Point> points, const Clustering& clustering,
                                                       std::span<const std::optional<ClusterView>> views,
                                                       const Eigen::Vector3d& sensor) {
  // The vehicles' views, each with its prior and its box grown to it.
  struct Part {
    std::size_t cluster;
    BoxPrior prior;
    OrientedBox grown;
  };
  std::vector<Part> parts;
  for (std::size_t c = 0; c < views.size(); ++c) {
    if (!views[c]) continue;
    if (const auto prior = vehiclePriorFor(views[c]->box, views[c]->label)) {
      parts.push_back({c, *prior, grownToPrior(views[c]->box, sensor, *prior)});
    }
  }
  if (parts.size() < 2) return std::optional<JoinedParts>{};
  DisjointSets sets(views.size());
  std::vector<Cloud> joined(views.size());  // per set's root: the points of its clusters, once a pair is a candidate
  bool filled = false;
  std::vector<BoxPrior> joined_prior(views.size());
  bool any = false;
  for (std::size_t a = 0; a < parts.size(); ++a) {
    for (std::size_t b = a + 1; b < parts.size(); ++b) {
      const std::size_t ra = sets.find(parts[a].cluster);
      const std::size_t rb = sets.find(parts[b].cluster);
      if (ra == rb || !stacked(views[parts[a].cluster]->box, views[parts[b].cluster]->box, sensor) ||
          !footprintsOverlap(parts[a].grown, parts[b].grown)) {
        continue;
      }
      if (!filled) {
        std::vector<Cloud> clusters = pointsByCluster(points, clustering);
        for (const Part& p : parts) {
          joined[p.cluster] = std::move(clusters[p.cluster]);
          joined_prior[p.cluster] = p.prior;
        }
        filled = true;
      }
      Cloud together = joined[ra];
      together.insert(together.end(), joined[rb].begin(), joined[rb].end());
      const auto box = fitOrientedBox(together, sensor);
      if (!box) return box.error();
      const BoxPrior& larger = joined_prior[ra].length_m >= joined_prior[rb].length_m ? joined_prior[ra] : joined_prior[rb];
      if (box->length > kVehiclePartsMaxLength * larger.length_m || box->width > larger.max_width_m) continue;
      sets.unite(ra, rb);
      const std::size_t root = sets.find(ra);
      joined[root] = std::move(together);
      joined_prior[root] = larger;
      any = true;
    }
  }
  if (!any) return std::optional<JoinedParts>{};
  std::vector<std::int32_t> labels(clustering.labels.size(), -1);
  for (std::size_t i = 0; i < labels.size(); ++i) {
    const std::int32_t l = clustering.labels[i];
    if (l >= 0 && static_cast<std::size_t>(l) < views.size()) labels[i] = static_cast<std::int32_t>(sets.find(static_cast<std::size_t>(l)));
  }
  JoinedParts out{canonicalize(labels), {}};
  out.views.resize(static_cast<std::size_t>(out.clustering.cluster_count));
  // Each old cluster's new label, and each new cluster's part of most points.
  std::vector<std::int32_t> new_label(views.size(), -1);
  for (std::size_t i = 0; i < labels.size(); ++i) {
    const std::int32_t l = clustering.labels[i];
    if (l >= 0 && static_cast<std::size_t>(l) < views.size()) new_label[static_cast<std::size_t>(l)] = out.clustering.labels[i];
  }
  std::vector<std::size_t> parts_in(out.views.size(), 0);
  std::vector<std::size_t> largest(out.views.size(), views.size());
  for (std::size_t c = 0; c < views.size(); ++c) {
    if (new_label[c] < 0) continue;
    const auto k = static_cast<std::size_t>(new_label[c]);
    ++parts_in[k];
    if (views[c] && (largest[k] == views.size() || views[c]->points > views[largest[k]]->points)) largest[k] = c;
  }
  for (std::size_t k = 0; k < out.views.size(); ++k) {
    if (largest[k] == views.size()) continue;
    const ClusterView& part = *views[largest[k]];
    if (parts_in[k] == 1) {
      out.views[k] = part;
      continue;
    }
    const std::size_t root = sets.find(largest[k]);
    const auto box = orientedBoxAtYaw(joined[root], part.box.yaw, sensor);
    if (!box) return box.error();
    out.views[k] = ClusterView{joined[root].size(), *box, part.label};
  }
  return std::optional<JoinedParts>(std::move(out));
}

Expected<SensorObjects> sensorObjects(std::span<const Point> points, Clustering clustering, const Eigen::Vector3d& sensor,
                                      const ObjectClassifier* classifier, std::size_t min_points) {
  auto views = clusterViews(points, clustering, sensor, classifier, min_points);
  if (!views) return views.error();
  auto joined = joinedVehicleParts(points, clustering, *views, sensor);
  if (!joined) return joined.error();
  if (!*joined) return SensorObjects{std::move(clustering), std::move(*views), 0};
  const auto parts_joined = static_cast<std::size_t>(clustering.cluster_count - (*joined)->clustering.cluster_count);
  return SensorObjects{std::move((*joined)->clustering), std::move((*joined)->views), parts_joined};
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
