#pragma once
// The fusion tracker (DESIGN.md 2.5): LiDAR observations (displacement centroids, or the global
// map's objects) fused with 2D camera detections that arrive asynchronously, kept as labelled
// tracks on the ground plane. Pure: the tracker service feeds it and publishes what it returns.
//
// Two associations, chosen in the config:
//  - paper: Algorithms 2 to 5 of the camera-LiDAR fusion paper as published: each detection's
//    overlaid centroid nearest the sensor updates the nearest track of the same label within
//    rho_overlay or creates a track; tracks left alone take the nearest remaining centroid within
//    rho_purecloud. Tracks are made only by fusion; positions are the last measurement.
//  - kalman (default): a constant-velocity Kalman filter per track; one step is predict,
//    associate (Hungarian over squared Mahalanobis distances, gated), update, spawn, prune.
//    Tracks are tentative until confirmed (a camera detection, or N consecutive LiDAR hits), lost
//    while unobserved, deleted after a timeout; the label is the vote of the fused detections.
#include <cstdint>
#include <map>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/base/status.hpp"
#include "common/camera/pinhole.hpp"
#include "common/perception/box_fitting.hpp"
#include "common/tracking/ctrv.hpp"
#include "common/tracking/kalman.hpp"
#include "common/tracking/track.hpp"
#include "common/tracking/tracker_config.hpp"

namespace fogmap::tracking {

// A vehicle's track moving at least this fast updates on its box grown along its direction of
// motion (common/tracking/tracker.cpp, grownCentre).
inline constexpr double kHeadingMinSpeedMps = 1.0;
// ... when its box, grown as the extents say, lies within this ground distance of the prediction
// (a wrong guess of which side is the length moves a car's centre by at most about 2.2 m).
inline constexpr double kHeadingReachM = 4.0;

// A vehicle track's heading after an update by observation `o` (Track::heading_rad): the axis of
// its box (a vehicle's: vehiclePriorFor), turned to the track's direction of motion when it moves at
// least kHeadingMinSpeedMps, else to its `previous` heading; none for a vehicle never seen moving (a
// box's axis does not tell its front from its back). An axis more than
// kHeadingAxisTrustRad off the motion (a car seen end-on, whose rear reads as its length) gives
// way to the motion's direction. An observation without a box (objects off, a fragment) leaves the
// previous heading; one whose box is no vehicle's (a person's, two people side by side for a while)
// clears it.
inline constexpr double kHeadingAxisTrustRad = std::numbers::pi / 4.0;
std::optional<double> vehicleHeading(const CloudObservation& o, const Eigen::Vector2d& velocity, std::optional<double> previous);

// Vehicles (docs/tracking.md, "Vehicles"): once vehicleHeading gives a track a heading, the track
// also runs a CTRV filter (common/tracking/ctrv.hpp), started at the observation's box grown along
// that heading (with the measurement's covariance) at the constant-velocity track's speed, and
// keeps its box's size as state: the class's prior at first, then each update's box grown to it
// (seen faces kept), smoothed by kVehicleSizeGain and held within [kVehicleMinSizeRatio x prior,
// kVehicleMaxLengthRatio x prior length] and [kVehicleMinSizeRatio x prior width, prior max width].
// Its position, velocity and heading are the CTRV filter's from then on; each update measures the
// box's centre grown from its anchor along the filter's heading with the track's size, and the box's
// axis as a heading (sigma kVehicleAxisSigmaRad) when it lies within kHeadingAxisTrustRad of it.
// An observation whose box is no vehicle's ends the CTRV filter: the track is a person's or other
// object's again (constant velocity).
inline constexpr double kVehicleSizeGain = 0.2;
inline constexpr double kVehicleMinSizeRatio = 0.8;
inline constexpr double kVehicleMaxLengthRatio = 1.5;
inline constexpr double kVehicleAxisSigmaRad = 0.15;
inline constexpr double kVehicleInitialHeadingSigmaRad = 0.3;
inline constexpr double kVehicleInitialYawRateSigma = 0.3;  // rad/s

// Overlay by boxes (overlayByBox): the least IoU of an observation's projected box with a detection.
inline constexpr double kMinOverlayIou = 0.3;
// Recovery (docs/tracking.md, "Detections by their boxes, and recovery"): a confirmed or lost track
// that no measurement gated, lost 0.5 s ago at most, takes the nearest measurement no track took
// within its speed x the time since its last update plus this of where it was last measured (an
// object that stopped short, or turned round, where the prediction ran on), instead of that
// measurement starting a new track. Its filter starts again there, at rest.
inline constexpr double kRecoveryMarginM = 0.5;

struct VehicleMotion {
  CtrvFilter filter;
  BoxPrior prior;  // the class's
  BoxPrior size;   // the track's estimate (length_m, width_m), max_width_m as the prior's
};

struct StepStats {
  std::int64_t time_ns = 0;               // the fused LiDAR frame's sensor time
  std::size_t detections_fused = 0;       // detections whose overlay found an observation
  std::size_t updates_overlay = 0;        // track updates by a fused (camera + LiDAR) measurement
  std::size_t updates_cloud_only = 0;     // track updates by a LiDAR observation alone
  std::size_t tracks_created = 0;
  std::size_t tracks_deleted = 0;
  std::size_t tracks_recovered = 0;       // tracks that took a measurement by recovery, not by the gate
  std::size_t detection_frames_used = 0;  // detection frames matched to this LiDAR frame
  std::size_t measurements = 0;           // observations the step took
  std::size_t measurements_shed = 0;      // observations left out: beyond the step's budget
};

struct TrackerCounters {
  std::uint64_t steps = 0;
  std::uint64_t detections_fused = 0;
  std::uint64_t updates_overlay = 0;
  std::uint64_t updates_cloud_only = 0;
  std::uint64_t tracks_created = 0;
  std::uint64_t tracks_deleted = 0;
  std::uint64_t tracks_recovered = 0;
  std::uint64_t detection_frames_stale = 0;    // older than every LiDAR frame they could match: dropped
  std::uint64_t detection_frames_overflow = 0;  // beyond max_buffered_frames: the oldest dropped
  std::uint64_t detection_frames_unknown_camera = 0;
  std::uint64_t cloud_frames_out_of_order = 0;  // older than the last fused LiDAR frame: dropped
  std::uint64_t measurements_shed = 0;          // observations left out of steps: beyond the budget
};

class Tracker {
 public:
  // `cameras`: the calibrated cameras whose detections may arrive (names must be unique).
  static Expected<Tracker> create(TrackerConfig config, std::vector<camera::PinholeCamera> cameras);

  // Buffers a camera's detections until the LiDAR frame nearest in time arrives. A frame of an
  // unknown camera, or one older than the last fused LiDAR frame by more than eps_sync, is
  // dropped and counted.
  void addDetections(DetectionFrame frame);

  // Fuses a LiDAR frame now with the buffered detection frames nearest in time (one per camera,
  // within eps_sync) and steps the tracks to its time: the caller has given every detection frame
  // that could match it. Detection frames that can no longer match any later LiDAR frame are
  // dropped as stale. A LiDAR frame older than the last is dropped.
  StepStats addCloud(const CloudFrame& frame);

  // Asynchronous fusion, for detections that arrive after the LiDAR frame they belong to: the
  // frame waits until every camera has sent a frame captured at or after it, or until
  // max_detection_wait_s has passed since its sensor time (`now_ns`, the same clock); then it is
  // fused as addCloud does. Returns what each frame fused now did (in time order). At most
  // max_buffered_frames LiDAR frames wait; beyond, the oldest is fused at once.
  std::vector<StepStats> offerCloud(const CloudFrame& frame, std::int64_t now_ns);
  // Fuses the waiting LiDAR frames that are ready at `now_ns` (after detections arrived, or as
  // time passes).
  std::vector<StepStats> advance(std::int64_t now_ns);
  std::size_t waitingClouds() const { return waiting_.size(); }

  // Load shedding: a step takes at most `budget` observations of its LiDAR frame (0: all). Over
  // budget, it keeps first, for each track (camera-confirmed ones, then confirmed or lost ones, then
  // tentative ones; the oldest first in each), the observation nearest its predicted position
  // within shed_reach_m, then the others with the most points; the rest are shed and counted. So
  // objects already tracked keep their tracks whatever else a frame brings, and a step's cost is
  // bounded by the budget.
  void setMeasurementBudget(std::size_t budget) { budget_ = budget; }
  std::size_t measurementBudget() const { return budget_; }

  // The live tracks (tentative ones too; callers usually publish confirmed and lost ones).
  const std::vector<Track>& tracks() const { return tracks_; }
  // The tracks to publish after the last LiDAR frame fused: the live ones, except lost ones whose
  // last update is more than publish_lost_s before that frame. A lost track coasts on its last
  // velocity; past the time recovery could take it back it is a guess, kept to be gated again,
  // not shown (a car turned round on the spot left one coasting ahead for its 2 s of timeout).
  std::vector<Track> publishedTracks() const;
  const TrackerCounters& counters() const { return counters_; }
  const TrackerConfig& config() const { return config_; }
  // When each camera's newest detection frame was captured (absent until one arrived).
  const std::map<std::string, std::int64_t>& lastCapture() const { return last_capture_ns_; }
  // The cameras whose detections this tracker fuses.
  const std::vector<camera::PinholeCamera>& cameras() const { return cameras_; }

 private:
  Tracker(TrackerConfig config, std::vector<camera::PinholeCamera> cameras);

  std::vector<DetectionFrame> takeSynchronized(std::int64_t cloud_time_ns);
  // The observations of `frame` a step takes under the budget (all of them within it).
  CloudFrame withinBudget(const CloudFrame& frame, StepStats& stats) const;
  bool ready(const CloudFrame& frame, std::int64_t now_ns) const;
  void stepPaper(const CloudFrame& frame, const std::vector<DetectionFrame>& detections, StepStats& stats);
  void stepKalman(const CloudFrame& frame, const std::vector<DetectionFrame>& detections, StepStats& stats);
  void prune(std::int64_t now_ns, StepStats& stats);
  Track& spawn(const Eigen::Vector2d& position, const Eigen::Matrix2d& covariance, std::int64_t now_ns);
  // A new constant-velocity filter at `position`, at rest (spawn, restart).
  ConstantVelocityFilter filterAt(const Eigen::Vector2d& position, const Eigen::Matrix2d& covariance) const;
  // Track t's filter started again at `position`, at rest, without a vehicle motion (recovery).
  void restart(std::size_t t, const Eigen::Vector2d& position, const Eigen::Matrix2d& covariance);
  // Track t's estimate: its vehicle filter's where it has one, else its constant-velocity filter's.
  Eigen::Vector2d positionOf(std::size_t t) const;
  Eigen::Vector2d velocityOf(std::size_t t) const;
  Eigen::Matrix2d positionCovarianceOf(std::size_t t) const;
  // After track t's update by `o` (its heading_rad already set by vehicleHeading): starts, updates
  // or ends its vehicle motion (see VehicleMotion).
  // `prior`: o's box's vehicle prior (vehiclePriorFor), none when it is no vehicle's.
  void updateVehicle(std::size_t t, const CloudObservation& o, const std::optional<BoxPrior>& prior,
                     const Eigen::Matrix2d& measurement_covariance);

  TrackerConfig config_;
  std::vector<camera::PinholeCamera> cameras_;
  std::map<std::string, std::vector<DetectionFrame>> pending_;  // per camera, by capture time
  std::map<std::string, std::int64_t> last_capture_ns_;
  std::optional<std::int64_t> last_cloud_ns_;
  std::vector<CloudFrame> waiting_;  // offered LiDAR frames not fused yet, by time
  std::vector<Track> tracks_;
  std::vector<ConstantVelocityFilter> filters_;                // kalman: one per track, same order
  std::vector<std::optional<VehicleMotion>> vehicles_;          // kalman: a vehicle's CTRV and size
  std::vector<std::map<std::string, double>> label_votes_;     // kalman: summed scores per label
  std::vector<Eigen::Vector2d> last_measured_;                 // kalman: where each track was last measured
  std::uint64_t next_id_ = 1;
  std::size_t budget_ = 0;
  TrackerCounters counters_;
};

// Algorithm 3 (Overlay): of the observations in front of `camera` whose pixel lies inside `box`,
// the ground projection of the one nearest to `sensor_position` (on the ground plane); nothing
// when none is overlaid. Returns the index of that observation.
std::optional<std::size_t> overlay(const std::vector<CloudObservation>& observations, const camera::PinholeCamera& camera,
                                   const camera::Box2d& box, const Eigen::Vector3d& sensor_position);

// The kalman association's overlay: of the observations whose pixel lies inside `box` (as in
// overlay), those with an oriented box compete by the IoU of their box's image (its 8 corners
// projected) with `box`, and the best of at least kMinOverlayIou wins. When none of them fits that
// well, the detection overlays the observation nearest the sensor of those without a box (as
// overlay), or nothing. So the detection of a car whose image box holds a person in front of it
// labels the car, not the person, and a detection whose object the map lacks labels nothing.
std::optional<std::size_t> overlayByBox(const std::vector<CloudObservation>& observations, const camera::PinholeCamera& camera,
                                        const camera::Box2d& box, const Eigen::Vector3d& sensor_position);

}  // namespace fogmap::tracking
