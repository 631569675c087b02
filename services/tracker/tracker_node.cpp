#include "services/tracker/tracker_node.hpp"

#include "common/geometry/map.hpp"
#include "common/geometry/object_shape.hpp"
#include "common/perception/box_fitting.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <optional>
#include <utility>

namespace fogmap {

namespace {

// Where a view (one sensor's ellipsoid) places its object: a narrow object's (kNarrowObjectMaxM) at
// the centre of its box grown to a square away from the face or corner its sensor saw, on its axis;
// any other at the ellipsoid's centre.
Eigen::Vector3d placedCentre(const Ellipsoid& e) {
  if (!e.box || e.box->anchor == BoxAnchor::kNone || !(e.box->length <= kNarrowObjectMaxM) || vehiclePriorFor(*e.box, e.label)) {
    return e.center;
  }
  const double side = e.box->length;
  Eigen::Vector3d centre = e.center;
  centre.head<2>() = grownFromAnchor(*e.box, BoxPrior{side, side, side}).centre.head<2>();
  return centre;
}

}  // namespace

tracking::CloudFrame observationsOf(const GlobalMapMessage& global, double alpha, double ground_merge_m) {
  tracking::CloudFrame frame;
  frame.time_ns = global.header.sensor_time_ns;
  const auto& objects = global.map.objects;
  // Each object's box and class (where its edges give them) and its vehicle box: its box grown to
  // its class's size from the faces seen. Computed once per object; an obstacle of one object (the
  // common case) reuses them.
  struct Seen {
    std::optional<OrientedBox> box;
    std::optional<ObjectLabel> label;
    std::optional<OrientedBox> vehicle;
  };
  std::vector<Seen> seen(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) {
    seen[i] = {objectBox(objects[i]), objectLabel(objects[i]), std::nullopt};
    if (!seen[i].box) continue;
    if (const auto prior = vehiclePriorFor(*seen[i].box, seen[i].label)) seen[i].vehicle = grownFromAnchor(*seen[i].box, *prior);
  }
  // Obstacles: union-find over the objects whose ground footprints (grown) overlap, and over the
  // parts of one vehicle (each grown to a whole vehicle, they overlap: a car cut in two is one car).
  DisjointSets sets(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) {
    for (std::size_t j = i + 1; j < objects.size(); ++j) {
      const Box& a = objects[i].box;
      const Box& b = objects[j].box;
      const bool apart = a.min.x() > b.max.x() + ground_merge_m || b.min.x() > a.max.x() + ground_merge_m ||
                         a.min.y() > b.max.y() + ground_merge_m || b.min.y() > a.max.y() + ground_merge_m;
      const bool one_vehicle = seen[i].vehicle && seen[j].vehicle && footprintsOverlap(*seen[i].vehicle, *seen[j].vehicle);
      if (!apart || one_vehicle) sets.unite(i, j);
    }
  }
  std::map<std::size_t, std::vector<const Ellipsoid*>> obstacles;
  std::map<std::size_t, std::vector<std::size_t>> members;  // the objects of each obstacle
  for (std::size_t i = 0; i < objects.size(); ++i) {
    for (const Ellipsoid& e : objects[i].ellipsoids) obstacles[sets.find(i)].push_back(&e);
    members[sets.find(i)].push_back(i);
  }
  const double alpha2 = alpha * alpha;
  for (const auto& [root, ellipsoids] : obstacles) {
    double total = 0.0;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    std::vector<Eigen::Vector3d> placed;  // per ellipsoid: where its view places the object
    placed.reserve(ellipsoids.size());
    for (const Ellipsoid* e : ellipsoids) {
      const double n = static_cast<double>(std::max<std::uint64_t>(e->point_count, 1));
      total += n;
      placed.push_back(placedCentre(*e));
      mean += n * placed.back();
    }
    if (total <= 0.0) continue;
    mean /= total;
    // The mixture's covariance: the ellipsoids' own spreads plus the spread of their centres.
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    for (std::size_t k = 0; k < ellipsoids.size(); ++k) {
      const Ellipsoid* e = ellipsoids[k];
      const double n = static_cast<double>(std::max<std::uint64_t>(e->point_count, 1));
      const Eigen::Vector3d d = placed[k] - mean;
      covariance += n * (e->shape / alpha2 + d * d.transpose());
    }
    tracking::CloudObservation observation{mean, covariance / total, static_cast<std::size_t>(total), std::nullopt, std::nullopt};
    // Boxes and classes, where the edges give them: a vehicle is measured at the centre of its box
    // grown to its class's size from the faces its sensors saw, not at the mean of the points of
    // the faces they saw, which moves as they see other faces.
    const std::vector<std::size_t>& parts = members.at(root);
    if (parts.size() == 1) {
      observation.lidar_class = seen[parts[0]].label;
      observation.box = seen[parts[0]].box;
    } else if (std::any_of(parts.begin(), parts.end(), [&](std::size_t i) { return seen[i].box || seen[i].label; })) {
      MapObject views;  // the obstacle's views together, in canonical order
      for (const Ellipsoid* e : ellipsoids) views.ellipsoids.push_back(*e);
      std::sort(views.ellipsoids.begin(), views.ellipsoids.end(), [](const Ellipsoid& a, const Ellipsoid& b) { return a.id < b.id; });
      observation.lidar_class = objectLabel(views);
      observation.box = objectBox(views);
    }
    if (observation.box) {
      if (const auto prior = vehiclePriorFor(*observation.box, observation.lidar_class)) {
        observation.position.head<2>() = grownFromAnchor(*observation.box, *prior).centre.head<2>();
        // The box centre is known to the spread of its fit, not to the spread of the car's points.
        const double sigma = kVehicleCentreSigmaM;
        observation.covariance.topLeftCorner<2, 2>() = Eigen::Matrix2d::Identity() * sigma * sigma;
        observation.covariance(0, 2) = observation.covariance(2, 0) = 0.0;
        observation.covariance(1, 2) = observation.covariance(2, 1) = 0.0;
      }
    }
    frame.observations.push_back(std::move(observation));
  }
  return frame;
}

namespace {

std::string msText(double ns) { return std::to_string(std::llround(ns * 1e-6)) + " ms"; }

}  // namespace

TrackerNodeLimits trackerNodeLimitsFor(const TopologyConfig& topology) {
  TrackerNodeLimits config;
  config.period_ns = static_cast<std::int64_t>(std::llround(topology.period_ms * 1e6));
  config.window_ns = static_cast<std::int64_t>(std::llround(topology.admission.window_periods * topology.period_ms * 1e6));
  return config;
}

TrackerNode::TrackerNode(tracking::Tracker tracker, double alpha, NowNs now, Publish publish,
                         std::optional<CentroidCollector> centroids, TrackerNodeLimits limits)
    : tracker_(std::move(tracker)),
      alpha_(alpha),
      now_(std::move(now)),
      publish_(std::move(publish)),
      centroids_(std::move(centroids)),
      limits_(std::move(limits)),
      started_ns_(now_()) {
  if (!limits_.stopwatch) limits_.stopwatch = steadyNowNs;
}

std::vector<tracking::StepStats> TrackerNode::offer(const std::vector<tracking::CloudFrame>& frames, std::int64_t now_ns) {
  std::vector<tracking::StepStats> steps;
  for (const auto& frame : frames) {
    auto fused = tracker_.offerCloud(frame, now_ns);
    steps.insert(steps.end(), fused.begin(), fused.end());
  }
  return steps;
}

std::optional<TrackerNode::Refusal> TrackerNode::addDetections(tracking::DetectionFrame frame) {
  std::unique_lock lock(mutex_);
  const std::int64_t started = limits_.stopwatch();
  const std::int64_t now = now_();
  const std::int64_t capture = frame.capture_time_ns;
  const std::int64_t window = limits_.window_ns;
  const std::string beyond = ", beyond the admission window of " + msText(static_cast<double>(window));
  if (capture > now && capture - now > window) {
    return Refusal{"clock_skew", "camera '" + frame.camera + "': captured " + msText(static_cast<double>(capture - now)) +
                                     " ahead of the tracker's clock" + beyond + " (check the camera's clock)"};
  }
  // A capture in the past is not refused here: a slow detector's frames arrive late (HOG on a busy
  // machine takes longer than max_detection_wait_s + eps_sync_s), and the camera is still heard. One
  // no LiDAR frame can use any more is counted stale by the tracker; it never moves the camera's
  // newest capture back, and it is the first evicted from the camera's buffer.
  tracker_.addDetections(std::move(frame));
  publishFused(lock, tracker_.advance(now), started);
  return std::nullopt;
}

std::optional<TrackerNode::Refusal> TrackerNode::addGlobalMap(const GlobalMapMessage& global) {
  // A revision of an epoch already offered. A late first publication (the root fell behind) is
  // still the epoch's first picture: fused, as the root publishes epochs in order.
  if (global.revision != 0) return std::nullopt;
  // No sensor time: no node contributed data to the epoch (all failed or missing). There is
  // nothing to observe, and fusing it at time 0 would put the tracker's clock 56 years back.
  if (global.header.sensor_time_ns <= 0) return std::nullopt;
  const tracking::CloudFrame frame = observationsOf(global, alpha_);
  std::unique_lock lock(mutex_);
  const std::int64_t started = limits_.stopwatch();
  const std::int64_t now = now_();
  const std::int64_t sensed = global.header.sensor_time_ns;
  if (sensed > now && sensed - now > limits_.window_ns) {
    return Refusal{"clock_skew", "global map of epoch " + std::to_string(global.header.epoch) + ": sensor time " +
                                     msText(static_cast<double>(sensed - now)) +
                                     " ahead of the tracker's clock, beyond the admission window of " +
                                     msText(static_cast<double>(limits_.window_ns))};
  }
  publishFused(lock, tracker_.offerCloud(frame, now), started);
  return std::nullopt;
}

TrackerNode::CentroidAdmission TrackerNode::addCentroids(tracking::CentroidFrame frame) {
  if (!centroids_) return {CentroidVerdict::kUnknownEdge, "this tracker takes no centroids"};
  std::unique_lock lock(mutex_);
  const std::int64_t started = limits_.stopwatch();
  const std::int64_t now = now_();
  auto added = centroids_->add(std::move(frame), now);
  publishFused(lock, offer(added.ready, now), started);
  return {added.verdict, std::move(added.detail)};
}

std::map<std::string, double> TrackerNode::tick() {
  std::unique_lock lock(mutex_);
  const std::int64_t started = limits_.stopwatch();
  const std::int64_t now = now_();
  std::vector<tracking::StepStats> steps;
  if (centroids_) steps = offer(centroids_->expire(now), now);
  auto advanced = tracker_.advance(now);
  steps.insert(steps.end(), advanced.begin(), advanced.end());
  auto stale = staleness(now);
  publishFused(lock, std::move(steps), started);
  return stale;
}

std::map<std::string, double> TrackerNode::staleness(std::int64_t now_ns) const {
  std::map<std::string, double> out;
  for (const auto& camera : tracker_.cameras()) {
    const auto captured = tracker_.lastCapture().find(camera.name);
    const std::int64_t since = captured == tracker_.lastCapture().end() ? started_ns_ : captured->second;
    // A capture up to the admission window ahead of this clock is admitted (clocks differ a little):
    // it is fresh, not "negative seconds old".
    out[camera.name] = std::max(0.0, static_cast<double>(now_ns - since) * 1e-9);
  }
  return out;
}

void TrackerNode::updateBudget(const std::vector<tracking::StepStats>& steps, double seconds) {
  if (limits_.period_ns <= 0 || limits_.fusion_share <= 0.0) return;
  std::size_t measurements = 0;
  for (const auto& step : steps) measurements += step.measurements;
  if (measurements == 0) return;
  const double sample = seconds / static_cast<double>(measurements);
  // Up at once (a flood must not make the tracker fall behind), down slowly (one quick step is no
  // reason to take in a flood again).
  cost_per_measurement_s_ = std::max(sample, 0.8 * cost_per_measurement_s_ + 0.2 * sample);
  if (cost_per_measurement_s_ <= 0.0) return;
  const double allowed_s = limits_.fusion_share * static_cast<double>(limits_.period_ns) * 1e-9;
  const double fits = std::floor(allowed_s / cost_per_measurement_s_);
  const auto budget = fits >= 1e9 ? std::size_t{1'000'000'000} : static_cast<std::size_t>(fits);
  tracker_.setMeasurementBudget(std::max(limits_.min_budget, budget));
}

void TrackerNode::publishFused(std::unique_lock<std::mutex>& lock, std::vector<tracking::StepStats> steps,
                               std::int64_t started_ns) {
  if (steps.empty()) return;
  FusionReport report;
  report.fusion_seconds = static_cast<double>(limits_.stopwatch() - started_ns) * 1e-9;
  updateBudget(steps, report.fusion_seconds);
  report.measurement_budget = tracker_.measurementBudget();
  TrackSnapshot snapshot;
  snapshot.lidar_time_ns = steps.back().time_ns;
  snapshot.association = tracker_.config().association;
  snapshot.tracks = tracker_.publishedTracks();
  report.counters = tracker_.counters();
  if (centroids_) report.centroids = centroids_->counters();
  report.tracks = tracker_.tracks();  // the gauges count every live track, published or not
  const std::int64_t now = now_();
  report.camera_staleness_s = staleness(now);
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

std::size_t TrackerNode::measurementBudget() const {
  std::lock_guard lock(mutex_);
  return tracker_.measurementBudget();
}

}  // namespace fogmap
