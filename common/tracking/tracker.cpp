#include "common/tracking/tracker.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <numeric>
#include <set>
#include <utility>

#include "common/base/angles.hpp"
#include "common/perception/box_fitting.hpp"
#include "common/tracking/assignment.hpp"

namespace fogmap::tracking {

namespace {

double seconds(std::int64_t ns) { return static_cast<double>(ns) * 1e-9; }
std::int64_t nanoseconds(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

Eigen::Vector2d ground(const CloudObservation& o) { return o.position.head<2>(); }

// A vehicle's measured point: its box grown from its anchor to `size`, the length along `heading`
// (the face or corner its sensor saw stays where it was seen; a car's side seen in part is as long
// as its rear is wide, and the heading tells them apart).
Eigen::Vector2d grownCentre(const OrientedBox& box, const BoxPrior& size, double heading) {
  return grownFromAnchor(box, size, heading).centre.head<2>();
}

// Of the two directions along `axis`, the one nearer `toward`.
double alongNearer(double axis, double toward) {
  return wrapToPi(headingAngleBetween(axis, toward) <= 0.5 * std::numbers::pi ? axis : axis + std::numbers::pi);
}

}  // namespace

std::optional<double> vehicleHeading(const CloudObservation& o, const Eigen::Vector2d& velocity, std::optional<double> previous) {
  if (!o.box) return previous;
  if (!vehiclePriorFor(*o.box, o.lidar_class)) return std::nullopt;
  const double axis = o.box->yaw;
  if (velocity.norm() >= kHeadingMinSpeedMps) {
    const double motion = std::atan2(velocity.y(), velocity.x());
    const double along = alongNearer(axis, motion);
    return headingAngleBetween(along, motion) <= kHeadingAxisTrustRad ? along : motion;
  }
  if (!previous) return std::nullopt;  // standing, never seen moving: which end is the front is not known
  return alongNearer(axis, *previous);
}

namespace {

// The measurement covariance on the ground plane, with a floor so that a tight cluster (or a
// degenerate one) never makes the filter over-confident.
Eigen::Matrix2d groundCovariance(const CloudObservation& o, double min_sigma_m) {
  Eigen::Matrix2d r = o.covariance.topLeftCorner<2, 2>();
  r = 0.5 * (r + r.transpose());
  return r + Eigen::Matrix2d::Identity() * min_sigma_m * min_sigma_m;
}

std::string bestLabel(const std::map<std::string, double>& votes) {
  std::string best = kUnknownLabel;
  double best_score = 0.0;
  for (const auto& [label, score] : votes) {
    if (score > best_score) {  // ties: the first in name order, so the result is deterministic
      best = label;
      best_score = score;
    }
  }
  return best;
}

// Recovery takes only tracks lost at most this long: an object that turns round is found again
// within a frame or two, and a reach that grew with a long loss would revive a lost track with
// whatever clutter appears metres away.
constexpr double kRecoveryWindowS = 0.5;

// "In front of the camera" is z > 0 in the paper; a millimetre keeps the division well away from 0.
constexpr double kInFrontM = 1e-3;

// The observation's pixel lies inside `box`.
bool overlaid(const CloudObservation& o, const camera::PinholeCamera& camera, const camera::Box2d& box) {
  const auto pixel = camera.project(o.position, kInFrontM);
  return pixel && pixel->x() >= box.left && pixel->x() <= box.right && pixel->y() >= box.top && pixel->y() <= box.bottom;
}

}  // namespace

std::optional<std::size_t> overlay(const std::vector<CloudObservation>& observations, const camera::PinholeCamera& camera,
                                   const camera::Box2d& box, const Eigen::Vector3d& sensor_position) {
  std::optional<std::size_t> nearest;
  double nearest_distance = std::numeric_limits<double>::infinity();
  for (std::size_t g = 0; g < observations.size(); ++g) {
    if (!overlaid(observations[g], camera, box)) continue;
    const double distance = (ground(observations[g]) - sensor_position.head<2>()).norm();
    if (distance < nearest_distance) {
      nearest_distance = distance;
      nearest = g;
    }
  }
  return nearest;
}

std::optional<std::size_t> overlayByBox(const std::vector<CloudObservation>& observations, const camera::PinholeCamera& camera,
                                        const camera::Box2d& box, const Eigen::Vector3d& sensor_position) {
  std::optional<std::size_t> best_boxed;
  double best_iou = kMinOverlayIou;
  std::optional<std::size_t> nearest_unboxed;
  double nearest_distance = std::numeric_limits<double>::infinity();
  for (std::size_t g = 0; g < observations.size(); ++g) {
    const auto& o = observations[g];
    if (!overlaid(o, camera, box)) continue;
    if (o.box) {
      const auto corners = o.box->corners();
      const auto image = camera::projectPoints(camera, corners, kInFrontM);
      const double fit = image ? camera::iou(*image, box) : 0.0;
      if (fit >= best_iou) {
        best_iou = fit;
        best_boxed = g;
      }
      continue;
    }
    const double distance = (ground(o) - sensor_position.head<2>()).norm();
    if (distance < nearest_distance) {
      nearest_distance = distance;
      nearest_unboxed = g;
    }
  }
  return best_boxed ? best_boxed : nearest_unboxed;
}

Tracker::Tracker(TrackerConfig config, std::vector<camera::PinholeCamera> cameras)
    : config_(config), cameras_(std::move(cameras)) {}

Expected<Tracker> Tracker::create(TrackerConfig config, std::vector<camera::PinholeCamera> cameras) {
  if (auto status = validate(config); !status) return status.error();
  std::set<std::string> names;
  for (const auto& c : cameras) {
    if (auto status = camera::validate(c); !status) return status.error();
    if (!names.insert(c.name).second) return invalidArgument("tracker: camera '" + c.name + "' is listed twice");
  }
  return Tracker(config, std::move(cameras));
}

void Tracker::addDetections(DetectionFrame frame) {
  const bool known = std::any_of(cameras_.begin(), cameras_.end(), [&](const auto& c) { return c.name == frame.camera; });
  if (!known) {
    ++counters_.detection_frames_unknown_camera;
    return;
  }
  auto& newest = last_capture_ns_[frame.camera];
  newest = std::max(newest, frame.capture_time_ns);
  if (last_cloud_ns_ && frame.capture_time_ns < *last_cloud_ns_ - nanoseconds(config_.eps_sync_s)) {
    ++counters_.detection_frames_stale;  // every LiDAR frame still to come is further away in time
    return;
  }
  auto& queue = pending_[frame.camera];
  const auto at = std::upper_bound(queue.begin(), queue.end(), frame.capture_time_ns,
                                   [](std::int64_t t, const DetectionFrame& f) { return t < f.capture_time_ns; });
  queue.insert(at, std::move(frame));
  if (queue.size() > config_.max_buffered_frames) {
    queue.erase(queue.begin());
    ++counters_.detection_frames_overflow;
  }
}

std::vector<DetectionFrame> Tracker::takeSynchronized(std::int64_t cloud_time_ns) {
  const std::int64_t eps_ns = nanoseconds(config_.eps_sync_s);
  std::vector<DetectionFrame> matched;
  for (auto& [camera, queue] : pending_) {
    // The frame nearest in time, less than eps_sync away (the paper: the shortest time difference
    // wins; the earlier of two equally near).
    auto best = queue.end();
    std::int64_t best_gap = eps_ns;
    for (auto it = queue.begin(); it != queue.end(); ++it) {
      const std::int64_t gap = std::llabs(it->capture_time_ns - cloud_time_ns);
      if (gap < best_gap) {
        best = it;
        best_gap = gap;
      }
    }
    if (best != queue.end()) {
      matched.push_back(std::move(*best));
      queue.erase(best);
    }
    // Frames older than this LiDAR frame by more than eps_sync cannot match a later one.
    const auto stale_end = std::find_if(queue.begin(), queue.end(),
                                        [&](const DetectionFrame& f) { return f.capture_time_ns >= cloud_time_ns - eps_ns; });
    counters_.detection_frames_stale += static_cast<std::uint64_t>(stale_end - queue.begin());
    queue.erase(queue.begin(), stale_end);
  }
  return matched;
}

StepStats Tracker::addCloud(const CloudFrame& frame) {
  StepStats stats;
  stats.time_ns = frame.time_ns;
  if (last_cloud_ns_ && frame.time_ns < *last_cloud_ns_) {
    ++counters_.cloud_frames_out_of_order;
    return stats;
  }
  const auto detections = takeSynchronized(frame.time_ns);
  stats.detection_frames_used = detections.size();
  const CloudFrame taken = withinBudget(frame, stats);
  if (config_.association == Association::kPaper) {
    stepPaper(taken, detections, stats);
  } else {
    stepKalman(taken, detections, stats);
  }
  prune(frame.time_ns, stats);
  last_cloud_ns_ = frame.time_ns;
  ++counters_.steps;
  counters_.detections_fused += stats.detections_fused;
  counters_.updates_overlay += stats.updates_overlay;
  counters_.updates_cloud_only += stats.updates_cloud_only;
  counters_.tracks_created += stats.tracks_created;
  counters_.tracks_deleted += stats.tracks_deleted;
  counters_.tracks_recovered += stats.tracks_recovered;
  counters_.measurements_shed += stats.measurements_shed;
  return stats;
}

CloudFrame Tracker::withinBudget(const CloudFrame& frame, StepStats& stats) const {
  const std::size_t n = frame.observations.size();
  stats.measurements = n;
  if (budget_ == 0 || n <= budget_) return frame;
  std::vector<bool> keep(n, false);
  std::size_t kept = 0;
  // The tracks in the order they claim observations: camera-confirmed, then confirmed or lost, then
  // tentative; the oldest (lowest id) first within each.
  const auto rank = [&](std::size_t t) {
    if (tracks_[t].state == TrackState::kTentative) return 2;
    return tracks_[t].camera_confirmed ? 0 : 1;
  };
  std::vector<std::size_t> holders(tracks_.size());
  std::iota(holders.begin(), holders.end(), 0);
  std::stable_sort(holders.begin(), holders.end(), [&](std::size_t a, std::size_t b) {
    if (rank(a) != rank(b)) return rank(a) < rank(b);
    return tracks_[a].id < tracks_[b].id;
  });
  // Each keeps its nearest observation within reach, found on a grid of cells one reach wide.
  const double reach = config_.shed_reach_m;
  const auto cellOf = [&](const Eigen::Vector2d& p) {
    return std::pair<std::int64_t, std::int64_t>{static_cast<std::int64_t>(std::floor(p.x() / reach)),
                                                 static_cast<std::int64_t>(std::floor(p.y() / reach))};
  };
  std::map<std::pair<std::int64_t, std::int64_t>, std::vector<std::size_t>> cells;
  for (std::size_t g = 0; g < n; ++g) cells[cellOf(ground(frame.observations[g]))].push_back(g);
  const double dt = last_cloud_ns_ ? std::max(0.0, seconds(frame.time_ns - *last_cloud_ns_)) : 0.0;
  for (const std::size_t t : holders) {
    if (kept == budget_) break;
    const Eigen::Vector2d predicted = tracks_[t].position + tracks_[t].velocity * dt;
    const auto [cx, cy] = cellOf(predicted);
    std::optional<std::size_t> nearest;
    double nearest_distance = reach;
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        const auto cell = cells.find({cx + dx, cy + dy});
        if (cell == cells.end()) continue;
        for (const std::size_t g : cell->second) {
          const double d = (ground(frame.observations[g]) - predicted).norm();
          if (!keep[g] && d <= nearest_distance) {
            nearest_distance = d;
            nearest = g;
          }
        }
      }
    }
    if (nearest) {
      keep[*nearest] = true;
      ++kept;
    }
  }
  // Then the observations with the most points (in frame order among equals).
  std::vector<std::size_t> rest;
  for (std::size_t g = 0; g < n; ++g) {
    if (!keep[g]) rest.push_back(g);
  }
  std::stable_sort(rest.begin(), rest.end(), [&](std::size_t a, std::size_t b) {
    return frame.observations[a].point_count > frame.observations[b].point_count;
  });
  for (std::size_t i = 0; i < rest.size() && kept < budget_; ++i, ++kept) keep[rest[i]] = true;
  CloudFrame taken;
  taken.time_ns = frame.time_ns;
  taken.sensor_position = frame.sensor_position;
  taken.observations.reserve(kept);
  for (std::size_t g = 0; g < n; ++g) {
    if (keep[g]) taken.observations.push_back(frame.observations[g]);
  }
  stats.measurements = kept;
  stats.measurements_shed = n - kept;
  return taken;
}

bool Tracker::ready(const CloudFrame& frame, std::int64_t now_ns) const {
  if (now_ns - frame.time_ns >= nanoseconds(config_.max_detection_wait_s)) return true;
  // Frames of one camera arrive in capture order: once one captured at or after the LiDAR frame
  // is here, no later one can be nearer.
  return std::all_of(cameras_.begin(), cameras_.end(), [&](const camera::PinholeCamera& c) {
    const auto newest = last_capture_ns_.find(c.name);
    return newest != last_capture_ns_.end() && newest->second >= frame.time_ns;
  });
}

std::vector<StepStats> Tracker::offerCloud(const CloudFrame& frame, std::int64_t now_ns) {
  const std::int64_t newest = waiting_.empty() ? (last_cloud_ns_ ? *last_cloud_ns_ : frame.time_ns) : waiting_.back().time_ns;
  if (frame.time_ns < newest) {
    ++counters_.cloud_frames_out_of_order;
    return {};
  }
  waiting_.push_back(frame);
  std::vector<StepStats> out;
  while (waiting_.size() > config_.max_buffered_frames) {
    out.push_back(addCloud(waiting_.front()));
    waiting_.erase(waiting_.begin());
  }
  for (auto& stats : advance(now_ns)) out.push_back(stats);
  return out;
}

std::vector<StepStats> Tracker::advance(std::int64_t now_ns) {
  std::vector<StepStats> out;
  std::size_t fused = 0;
  while (fused < waiting_.size() && ready(waiting_[fused], now_ns)) {
    out.push_back(addCloud(waiting_[fused]));
    ++fused;
  }
  waiting_.erase(waiting_.begin(), waiting_.begin() + static_cast<std::ptrdiff_t>(fused));
  return out;
}

ConstantVelocityFilter Tracker::filterAt(const Eigen::Vector2d& position, const Eigen::Matrix2d& covariance) const {
  return ConstantVelocityFilter(position, covariance, config_.initial_speed_sigma,
                                ConstantVelocityModel{.acceleration_sigma = config_.acceleration_sigma});
}

Track& Tracker::spawn(const Eigen::Vector2d& position, const Eigen::Matrix2d& covariance, std::int64_t now_ns) {
  Track track;
  track.id = next_id_++;
  track.position = position;
  track.covariance = covariance;
  track.created_ns = now_ns;
  track.last_update_ns = now_ns;
  track.consecutive_hits = 1;
  tracks_.push_back(track);
  filters_.push_back(filterAt(position, covariance));
  vehicles_.emplace_back();
  label_votes_.emplace_back();
  last_measured_.push_back(position);
  return tracks_.back();
}

void Tracker::restart(std::size_t t, const Eigen::Vector2d& position, const Eigen::Matrix2d& covariance) {
  filters_[t] = filterAt(position, covariance);
  vehicles_[t].reset();
  tracks_[t].heading_rad.reset();
  last_measured_[t] = position;
}

// Algorithms 2, 4 and 5, as published.
void Tracker::stepPaper(const CloudFrame& frame, const std::vector<DetectionFrame>& detections, StepStats& stats) {
  const std::size_t previous = tracks_.size();  // T_i: the tracks of the previous frame
  std::vector<bool> associated(previous, false);
  std::set<std::size_t> remaining;  // C^XY: observations not overlaid
  for (std::size_t g = 0; g < frame.observations.size(); ++g) remaining.insert(g);
  const auto cameraNamed = [&](const std::string& name) {
    return std::find_if(cameras_.begin(), cameras_.end(), [&](const auto& c) { return c.name == name; });
  };
  struct NewTrack {
    Eigen::Vector2d position;
    std::string label;
  };
  std::vector<NewTrack> created;  // H: added after every detection is handled
  for (const auto& message : detections) {
    const auto cam = cameraNamed(message.camera);
    for (const auto& detection : message.detections) {
      const auto g = overlay(frame.observations, *cam, detection.box, frame.sensor_position);  // Alg. 3
      if (!g) continue;
      ++stats.detections_fused;
      const Eigen::Vector2d c = ground(frame.observations[*g]);
      // Alg. 4: the closest track of T_i; same label and within rho_overlay, or a new track.
      std::optional<std::size_t> closest;
      double closest_distance = std::numeric_limits<double>::infinity();
      for (std::size_t o = 0; o < previous; ++o) {
        const double d = (tracks_[o].position - c).norm();
        if (d < closest_distance) {
          closest_distance = d;
          closest = o;
        }
      }
      if (closest && tracks_[*closest].label == detection.label && closest_distance < config_.rho_overlay_m) {
        auto& track = tracks_[*closest];
        track.position = c;
        track.last_update_ns = frame.time_ns;
        associated[*closest] = true;
        ++stats.updates_overlay;
      } else {
        created.push_back({c, detection.label});
      }
      remaining.erase(*g);
    }
  }
  // Alg. 5: every track not associated takes the nearest remaining centroid within rho_purecloud
  // (as published, a centroid is not removed once taken).
  for (std::size_t o = 0; o < previous; ++o) {
    if (associated[o]) continue;
    auto& track = tracks_[o];
    std::optional<std::size_t> nearest;
    double nearest_distance = std::numeric_limits<double>::infinity();
    for (const std::size_t g : remaining) {
      const double d = (track.position - ground(frame.observations[g])).norm();
      if (d < nearest_distance) {
        nearest_distance = d;
        nearest = g;
      }
    }
    if (nearest && nearest_distance < config_.rho_purecloud_m) {
      track.position = ground(frame.observations[*nearest]);
      track.last_update_ns = frame.time_ns;
      ++stats.updates_cloud_only;
    }
  }
  for (const auto& h : created) {
    Track& track = spawn(h.position, Eigen::Matrix2d::Zero(), frame.time_ns);
    track.label = h.label;
    track.state = TrackState::kConfirmed;  // the paper makes tracks only by fusion
    track.camera_confirmed = true;
    ++stats.tracks_created;
  }
  for (auto& track : tracks_) {
    if (track.state != TrackState::kTentative) {
      track.state = track.last_update_ns == frame.time_ns ? TrackState::kConfirmed : TrackState::kLost;
    }
  }
}

// Predict, associate, update, spawn (pruning follows in addCloud).
void Tracker::stepKalman(const CloudFrame& frame, const std::vector<DetectionFrame>& detections, StepStats& stats) {
  // Predict every track to the frame's time.
  const double dt = last_cloud_ns_ ? seconds(frame.time_ns - *last_cloud_ns_) : 0.0;
  for (auto& filter : filters_) filter.predict(dt);
  for (auto& vehicle : vehicles_) {
    if (vehicle) vehicle->filter.predict(dt);
  }

  // Measurements: every observation, with the labels of the detections that overlay it (several
  // cameras may see one object: their votes add up in one measurement).
  struct Measurement {
    Eigen::Vector2d position;
    Eigen::Matrix2d covariance;
    std::map<std::string, double> votes;  // the cameras'
    const CloudObservation* observation = nullptr;  // its box and LiDAR class
    std::optional<BoxPrior> vehicle_prior{};        // its box's, when it is a vehicle's (vehiclePriorFor)
  };
  std::vector<Measurement> measurements;
  measurements.reserve(frame.observations.size());
  for (const auto& o : frame.observations) {
    measurements.push_back({ground(o), groundCovariance(o, config_.min_measurement_sigma_m), {}, &o,
                            o.box ? vehiclePriorFor(*o.box, o.lidar_class) : std::nullopt});
  }
  // Labels: the cameras' detections vote with their scores, a LiDAR class with its confidence
  // times lidar_class_weight (docs/tracking.md, "Labels").
  const auto voteLidarClass = [&](const Measurement& meas, std::map<std::string, double>& votes) {
    const auto& lidar_class = meas.observation->lidar_class;
    if (lidar_class && config_.lidar_class_weight > 0.0) {
      votes[std::string(objectClassName(lidar_class->object_class))] +=
          config_.lidar_class_weight * std::max(lidar_class->confidence, 1e-6);
    }
  };
  for (const auto& message : detections) {
    const auto cam = std::find_if(cameras_.begin(), cameras_.end(), [&](const auto& c) { return c.name == message.camera; });
    for (const auto& detection : message.detections) {
      const auto g = overlayByBox(frame.observations, *cam, detection.box, frame.sensor_position);
      if (!g) continue;
      ++stats.detections_fused;
      measurements[*g].votes[detection.label] += std::max(detection.score, 1e-6);
    }
  }

  // Associate: the least total squared Mahalanobis distance, inside the gate, never across labels
  // cameras have told apart.
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<std::vector<double>> cost(tracks_.size(), std::vector<double>(measurements.size(), inf));
  std::vector<std::string> measured_label(measurements.size());
  for (std::size_t m = 0; m < measurements.size(); ++m) {
    if (!measurements[m].votes.empty()) measured_label[m] = bestLabel(measurements[m].votes);
  }
  // Never across labels cameras have told apart. (A label only LiDAR classes gave, camera_confirmed
  // false, does not gate: a camera may rename it.)
  const auto labelsAllow = [&](std::size_t t, std::size_t m) {
    return measured_label[m].empty() || !tracks_[t].camera_confirmed || tracks_[t].label == kUnknownLabel ||
           measured_label[m] == tracks_[t].label;
  };
  // A pair is gated only if |d|^2 <= gate tr(S) (d' S^-1 d >= |d|^2 / tr(S) for the 2 x 2 S = P + R),
  // a cheap test that leaves the exact one to the few pairs that may pass it.
  std::vector<double> measurement_spread(measurements.size());
  for (std::size_t m = 0; m < measurements.size(); ++m) measurement_spread[m] = measurements[m].covariance.trace();
  // A vehicle seen by a moving track is measured where its box, grown along the track's motion,
  // puts it (grownCentre): for each such pair within reach, its own measured point.
  std::map<std::pair<std::size_t, std::size_t>, Eigen::Vector2d> along_motion;
  const auto measuredFor = [&](std::size_t t, std::size_t m) -> const Eigen::Vector2d& {
    const auto it = along_motion.find({t, m});
    return it == along_motion.end() ? measurements[m].position : it->second;
  };
  for (std::size_t t = 0; t < tracks_.size(); ++t) {
    const auto& vehicle = vehicles_[t];
    const Eigen::Vector2d predicted = positionOf(t);
    const double track_spread = positionCovarianceOf(t).trace();
    const Eigen::Vector2d velocity = velocityOf(t);
    for (std::size_t m = 0; m < measurements.size(); ++m) {
      const auto& meas = measurements[m];
      if (meas.vehicle_prior && (meas.position - predicted).norm() <= kHeadingReachM) {
        const OrientedBox& box = *meas.observation->box;
        if (vehicle) {
          along_motion[{t, m}] = grownCentre(box, vehicle->size, vehicle->filter.heading());
        } else if (velocity.norm() >= kHeadingMinSpeedMps) {
          along_motion[{t, m}] = grownCentre(box, *meas.vehicle_prior, std::atan2(velocity.y(), velocity.x()));
        }
      }
      const Eigen::Vector2d& position = measuredFor(t, m);
      if ((position - predicted).squaredNorm() > config_.gate_chi2 * (track_spread + measurement_spread[m])) continue;
      if (!labelsAllow(t, m)) continue;
      const double d2 = vehicle ? vehicle->filter.mahalanobis2(position, meas.covariance)
                                : filters_[t].mahalanobis2(position, meas.covariance);
      if (d2 <= config_.gate_chi2) cost[t][m] = d2;
    }
  }
  const auto assignment = assignMinCost(cost);

  // What an update by `meas` adds to track t's labels: the cameras' votes (which confirm it as
  // camera-seen) and its LiDAR class.
  const auto takeLabels = [&](std::size_t t, const Measurement& meas) {
    if (meas.votes.empty()) {
      ++stats.updates_cloud_only;
    } else {
      ++stats.updates_overlay;
      tracks_[t].camera_confirmed = true;
      for (const auto& [label, score] : meas.votes) label_votes_[t][label] += score;
    }
    voteLidarClass(meas, label_votes_[t]);
  };

  // Update the matched tracks; the others miss a hit.
  std::vector<bool> used(measurements.size(), false);
  for (std::size_t t = 0; t < tracks_.size(); ++t) {
    auto& track = tracks_[t];
    if (!assignment[t]) {
      track.consecutive_hits = 0;
      if (track.state == TrackState::kConfirmed) track.state = TrackState::kLost;
      continue;
    }
    const auto& meas = measurements[*assignment[t]];
    used[*assignment[t]] = true;
    const Eigen::Vector2d& point = measuredFor(t, *assignment[t]);
    filters_[t].update(point, meas.covariance);
    last_measured_[t] = point;
    if (vehicles_[t]) vehicles_[t]->filter.updatePosition(point, meas.covariance);
    track.heading_rad = vehicleHeading(*meas.observation, velocityOf(t), track.heading_rad);
    updateVehicle(t, *meas.observation, meas.vehicle_prior, meas.covariance);
    track.last_update_ns = frame.time_ns;
    ++track.consecutive_hits;
    takeLabels(t, meas);
    if (track.camera_confirmed || track.consecutive_hits >= config_.confirm_hits) track.state = TrackState::kConfirmed;
  }

  // Recovery: a confirmed or lost track no measurement gated takes the nearest one no track took
  // within reach of where it was last measured (kRecoveryMarginM), and starts again there.
  // The pairs within reach first: the assignment then runs over the few tracks and measurements
  // they hold, not over every stranded track and free measurement (clutter makes many of both).
  struct Reach {
    std::size_t track, measurement;
    double d2;
  };
  std::vector<Reach> within;
  for (std::size_t t = 0; t < tracks_.size(); ++t) {
    const double unobserved_s = seconds(frame.time_ns - tracks_[t].last_update_ns);
    if (assignment[t] || tracks_[t].state == TrackState::kTentative || !(unobserved_s > 0.0) || unobserved_s > kRecoveryWindowS) {
      continue;
    }
    const double reach = velocityOf(t).norm() * unobserved_s + kRecoveryMarginM;
    for (std::size_t m = 0; m < measurements.size(); ++m) {
      // A vehicle's track takes no person.
      if (used[m] || (vehicles_[t] && !measurements[m].vehicle_prior) || !labelsAllow(t, m)) continue;
      const double d2 = (measurements[m].position - last_measured_[t]).squaredNorm();
      if (d2 <= reach * reach) within.push_back({t, m, d2});
    }
  }
  if (!within.empty()) {
    std::vector<std::size_t> stranded, free_measurements;
    for (const auto& r : within) {
      if (std::find(stranded.begin(), stranded.end(), r.track) == stranded.end()) stranded.push_back(r.track);
      if (std::find(free_measurements.begin(), free_measurements.end(), r.measurement) == free_measurements.end()) {
        free_measurements.push_back(r.measurement);
      }
    }
    std::vector<std::vector<double>> reach_cost(stranded.size(), std::vector<double>(free_measurements.size(), inf));
    for (const auto& r : within) {
      const auto a = static_cast<std::size_t>(std::find(stranded.begin(), stranded.end(), r.track) - stranded.begin());
      const auto b = static_cast<std::size_t>(std::find(free_measurements.begin(), free_measurements.end(), r.measurement) -
                                              free_measurements.begin());
      reach_cost[a][b] = r.d2;
    }
    const auto recovered = assignMinCost(reach_cost);
    for (std::size_t a = 0; a < stranded.size(); ++a) {
      if (!recovered[a]) continue;
      const std::size_t t = stranded[a];
      const std::size_t m = free_measurements[*recovered[a]];
      const auto& meas = measurements[m];
      used[m] = true;
      restart(t, meas.position, meas.covariance);
      auto& track = tracks_[t];
      track.last_update_ns = frame.time_ns;
      track.consecutive_hits = 1;
      ++stats.tracks_recovered;
      takeLabels(t, meas);
      // It was confirmed before: it is again.
      track.state = TrackState::kConfirmed;
    }
  }

  // Spawn: every measurement no track took starts a track; a camera-confirmed one is confirmed at
  // once (as the paper makes tracks by fusion), a LiDAR-only one after confirm_hits hits.
  for (std::size_t m = 0; m < measurements.size(); ++m) {
    if (used[m]) continue;
    const auto& meas = measurements[m];
    Track& track = spawn(meas.position, meas.covariance, frame.time_ns);
    ++stats.tracks_created;
    if (!meas.votes.empty()) {
      track.camera_confirmed = true;
      label_votes_.back() = meas.votes;
    }
    voteLidarClass(meas, label_votes_.back());
    if (track.camera_confirmed || config_.confirm_hits <= 1) track.state = TrackState::kConfirmed;
  }

  // The published view of every track: the filter's estimate and the label the votes give.
  for (std::size_t t = 0; t < tracks_.size(); ++t) {
    tracks_[t].position = positionOf(t);
    tracks_[t].velocity = velocityOf(t);
    tracks_[t].covariance = positionCovarianceOf(t);
    tracks_[t].label = bestLabel(label_votes_[t]);
  }
}

Eigen::Vector2d Tracker::positionOf(std::size_t t) const {
  return vehicles_[t] ? vehicles_[t]->filter.position() : filters_[t].position();
}
Eigen::Vector2d Tracker::velocityOf(std::size_t t) const {
  return vehicles_[t] ? vehicles_[t]->filter.velocity() : filters_[t].velocity();
}
Eigen::Matrix2d Tracker::positionCovarianceOf(std::size_t t) const {
  return vehicles_[t] ? vehicles_[t]->filter.positionCovariance() : Eigen::Matrix2d(filters_[t].covariance().topLeftCorner<2, 2>());
}

void Tracker::updateVehicle(std::size_t t, const CloudObservation& o, const std::optional<BoxPrior>& prior,
                            const Eigen::Matrix2d& measurement_covariance) {
  auto& vehicle = vehicles_[t];
  const auto& heading = tracks_[t].heading_rad;
  if (!heading) {  // the observation's box is no vehicle's (or none was ever seen moving)
    vehicle.reset();
    return;
  }
  if (!vehicle) {
    if (!prior) return;  // a heading carried over an observation without a box: start at the next box
    // At the box grown along the heading now known (the constant-velocity track followed the
    // centres guessed without one), moving at the constant-velocity track's speed.
    const Eigen::Vector2d start = grownCentre(*o.box, *prior, *heading);
    const double speed_sigma = std::sqrt(0.5 * filters_[t].covariance().bottomRightCorner<2, 2>().trace());
    vehicle.emplace(VehicleMotion{CtrvFilter(start, measurement_covariance, *heading, kVehicleInitialHeadingSigmaRad,
                                             filters_[t].velocity().norm(), speed_sigma, kVehicleInitialYawRateSigma,
                                             CtrvModel{}),
                                  *prior, *prior});
    tracks_[t].heading_rad = vehicle->filter.heading();
    return;
  }
  if (prior) {
    if (axisAngleBetween(o.box->yaw, vehicle->filter.heading()) <= kHeadingAxisTrustRad) {
      vehicle->filter.updateAxis(o.box->yaw, kVehicleAxisSigmaRad);
    }
    const OrientedBox grown = grownFromAnchor(*o.box, vehicle->size, vehicle->filter.heading());
    const auto& p = vehicle->prior;
    auto& size = vehicle->size;
    size.length_m = std::clamp(size.length_m + kVehicleSizeGain * (grown.length - size.length_m),
                               kVehicleMinSizeRatio * p.length_m, kVehicleMaxLengthRatio * p.length_m);
    size.width_m = std::clamp(size.width_m + kVehicleSizeGain * (grown.width - size.width_m),
                              kVehicleMinSizeRatio * p.width_m, p.max_width_m);
  }
  tracks_[t].heading_rad = vehicle->filter.heading();
}

std::vector<Track> Tracker::publishedTracks() const {
  std::vector<Track> out;
  out.reserve(tracks_.size());
  const std::int64_t window_ns = nanoseconds(config_.publish_lost_s);
  for (const auto& track : tracks_) {
    if (track.state == TrackState::kLost && last_cloud_ns_ && *last_cloud_ns_ - track.last_update_ns > window_ns) continue;
    out.push_back(track);
  }
  return out;
}

void Tracker::prune(std::int64_t now_ns, StepStats& stats) {
  const std::int64_t tentative_ns = nanoseconds(config_.tentative_timeout_s);
  const std::int64_t timeout_ns = nanoseconds(config_.track_timeout_s);
  std::size_t kept = 0;
  for (std::size_t t = 0; t < tracks_.size(); ++t) {
    const auto& track = tracks_[t];
    const std::int64_t unobserved = now_ns - track.last_update_ns;
    const bool expired = track.state == TrackState::kTentative ? unobserved > tentative_ns : unobserved > timeout_ns;
    if (expired) {
      ++stats.tracks_deleted;
      continue;
    }
    if (kept != t) {
      tracks_[kept] = std::move(tracks_[t]);
      filters_[kept] = std::move(filters_[t]);
      vehicles_[kept] = std::move(vehicles_[t]);
      label_votes_[kept] = std::move(label_votes_[t]);
      last_measured_[kept] = last_measured_[t];
    }
    ++kept;
  }
  tracks_.resize(kept);
  filters_.erase(filters_.begin() + static_cast<std::ptrdiff_t>(kept), filters_.end());
  vehicles_.erase(vehicles_.begin() + static_cast<std::ptrdiff_t>(kept), vehicles_.end());
  label_votes_.resize(kept);
  last_measured_.resize(kept);
}

}  // namespace fogmap::tracking
