#include "services/tracker/tracker_node.hpp"

#include "common/map.hpp"

#include <algorithm>
#include <chrono>
#include <map>
#include <utility>

namespace fogmap {

tracking::CloudFrame observationsOf(const GlobalMapMessage& global, double alpha, double ground_merge_m) {
  tracking::CloudFrame frame;
  frame.time_ns = global.header.sensor_time_ns;
  const auto& objects = global.map.objects;
  // Obstacles: union-find over the objects whose ground footprints (grown) overlap.
  DisjointSets sets(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) {
    for (std::size_t j = i + 1; j < objects.size(); ++j) {
      const Box& a = objects[i].box;
      const Box& b = objects[j].box;
      const bool apart = a.min.x() > b.max.x() + ground_merge_m || b.min.x() > a.max.x() + ground_merge_m ||
                         a.min.y() > b.max.y() + ground_merge_m || b.min.y() > a.max.y() + ground_merge_m;
      if (!apart) sets.unite(i, j);
    }
  }
  std::map<std::size_t, std::vector<const Ellipsoid*>> obstacles;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    for (const Ellipsoid& e : objects[i].ellipsoids) obstacles[sets.find(i)].push_back(&e);
  }
  const double alpha2 = alpha * alpha;
  for (const auto& [root, ellipsoids] : obstacles) {
    double total = 0.0;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const Ellipsoid* e : ellipsoids) {
      const double n = static_cast<double>(std::max<std::uint64_t>(e->point_count, 1));
      total += n;
      mean += n * e->center;
    }
    if (total <= 0.0) continue;
    mean /= total;
    // The mixture's covariance: the ellipsoids' own spreads plus the spread of their centres.
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    for (const Ellipsoid* e : ellipsoids) {
      const double n = static_cast<double>(std::max<std::uint64_t>(e->point_count, 1));
      const Eigen::Vector3d d = e->center - mean;
      covariance += n * (e->shape / alpha2 + d * d.transpose());
    }
    frame.observations.push_back({mean, covariance / total});
  }
  return frame;
}

TrackerNode::TrackerNode(tracking::Tracker tracker, double alpha, NowNs now, Publish publish,
                         std::optional<CentroidCollector> centroids)
    : tracker_(std::move(tracker)),
      alpha_(alpha),
      now_(std::move(now)),
      publish_(std::move(publish)),
      centroids_(std::move(centroids)),
      started_ns_(now_()) {}

std::vector<tracking::StepStats> TrackerNode::offer(const std::vector<tracking::CloudFrame>& frames, std::int64_t now_ns) {
  std::vector<tracking::StepStats> steps;
  for (const auto& frame : frames) {
    auto fused = tracker_.offerCloud(frame, now_ns);
    steps.insert(steps.end(), fused.begin(), fused.end());
  }
  return steps;
}

void TrackerNode::addDetections(tracking::DetectionFrame frame) {
  std::unique_lock lock(mutex_);
  const auto started = std::chrono::steady_clock::now();
  tracker_.addDetections(std::move(frame));
  publishFused(lock, tracker_.advance(now_()), started);
}

void TrackerNode::addGlobalMap(const GlobalMapMessage& global) {
  if (global.late) return;  // a revision of an epoch already offered, or a stale epoch
  // No sensor time: no node contributed data to the epoch (all failed or missing). There is
  // nothing to observe, and fusing it at time 0 would put the tracker's clock 56 years back.
  if (global.header.sensor_time_ns <= 0) return;
  const tracking::CloudFrame frame = observationsOf(global, alpha_);
  std::unique_lock lock(mutex_);
  const auto started = std::chrono::steady_clock::now();
  publishFused(lock, tracker_.offerCloud(frame, now_()), started);
}

CentroidVerdict TrackerNode::addCentroids(tracking::CentroidFrame frame) {
  if (!centroids_) return CentroidVerdict::kUnknownEdge;
  std::unique_lock lock(mutex_);
  const auto started = std::chrono::steady_clock::now();
  const std::int64_t now = now_();
  auto added = centroids_->add(std::move(frame), now);
  publishFused(lock, offer(added.ready, now), started);
  return added.verdict;
}

void TrackerNode::tick() {
  std::unique_lock lock(mutex_);
  const auto started = std::chrono::steady_clock::now();
  const std::int64_t now = now_();
  std::vector<tracking::StepStats> steps;
  if (centroids_) steps = offer(centroids_->expire(now), now);
  auto advanced = tracker_.advance(now);
  steps.insert(steps.end(), advanced.begin(), advanced.end());
  publishFused(lock, std::move(steps), started);
}

void TrackerNode::publishFused(std::unique_lock<std::mutex>& lock, std::vector<tracking::StepStats> steps,
                               std::chrono::steady_clock::time_point started) {
  if (steps.empty()) return;
  FusionReport report;
  report.fusion_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  TrackSnapshot snapshot;
  snapshot.lidar_time_ns = steps.back().time_ns;
  snapshot.association = tracker_.config().association;
  snapshot.tracks = tracker_.tracks();
  report.counters = tracker_.counters();
  if (centroids_) report.centroids = centroids_->counters();
  report.tracks = snapshot.tracks;
  const std::int64_t now = now_();
  // Seconds since each camera's newest capture; a camera not heard from yet counts from the start.
  for (const auto& camera : tracker_.cameras()) {
    const auto captured = tracker_.lastCapture().find(camera.name);
    const std::int64_t since = captured == tracker_.lastCapture().end() ? started_ns_ : captured->second;
    report.camera_staleness_s[camera.name] = static_cast<double>(now - since) * 1e-9;
  }
  report.steps = std::move(steps);
  lock.unlock();
  snapshot.published_time_ns = now;
  report.end_to_end_seconds = static_cast<double>(now - snapshot.lidar_time_ns) * 1e-9;
  if (publish_) publish_(snapshot, report);
}

tracking::TrackerCounters TrackerNode::counters() const {
  std::lock_guard lock(mutex_);
  return tracker_.counters();
}

std::optional<CentroidCounters> TrackerNode::centroidCounters() const {
  std::lock_guard lock(mutex_);
  if (!centroids_) return std::nullopt;
  return centroids_->counters();
}

std::vector<tracking::Track> TrackerNode::tracks() const {
  std::lock_guard lock(mutex_);
  return tracker_.tracks();
}

}  // namespace fogmap
