#pragma once
// The tracker's settings (common/tracking/tracker.hpp): the association (the fusion paper's or
// Kalman with global assignment), synchronisation, thresholds and track life cycle, as a plain
// struct with units in the names and its check. Read from a tracker node's `tracker:` section.
#include <cstddef>
#include <string>

#include "common/base/status.hpp"

namespace fogmap::tracking {

enum class Association { kPaper, kKalman };
const char* associationName(Association association);
Expected<Association> parseAssociation(const std::string& name);

struct TrackerConfig {
  Association association = Association::kKalman;
  double eps_sync_s = 0.1;  // a detection frame fuses with the LiDAR frame nearest in time, less than this away
  // The paper's thresholds (Algorithms 4 and 5): 0.5 m and 0.3 m indoors, 5 m on KITTI.
  double rho_overlay_m = 0.5;
  double rho_purecloud_m = 0.3;
  // Kalman association.
  double gate_chi2 = 9.21;              // squared Mahalanobis gate: chi-square, 2 dof, 99 %
  double acceleration_sigma = 2.0;      // m/s^2, the constant-velocity model's process noise
  double initial_speed_sigma = 3.0;     // m/s, a new track's velocity uncertainty
  double min_measurement_sigma_m = 0.05;  // floor of a measurement's standard deviation
  int confirm_hits = 3;                 // consecutive LiDAR hits that confirm a track without a camera
  double tentative_timeout_s = 0.3;     // a tentative track unobserved this long is dropped
  double track_timeout_s = 2.0;         // a track unobserved this long is deleted (both associations)
  // A lost track is published this long after its last update (Tracker::publishedTracks), as long
  // as recovery can still take it back; it stays live (gated, recovered) until track_timeout_s.
  // In [0, track_timeout_s].
  double publish_lost_s = 0.5;
  std::size_t max_buffered_frames = 64;  // detection frames kept per camera while waiting for LiDAR
  // Asynchronous fusion (Tracker::offerCloud): a LiDAR frame waits until every camera has sent a
  // frame captured at or after it (its nearest detection frame is then known), or this long.
  double max_detection_wait_s = 0.25;
  // Load shedding (Tracker::setMeasurementBudget): when a LiDAR frame brings more observations than
  // the step's budget, every track first keeps the observation nearest its predicted position within
  // this ground distance (m), then the others go by their points.
  double shed_reach_m = 2.0;
  // A track's label is the best of its votes: each fused camera detection votes with its score,
  // each LiDAR class (global maps of edges that classify) with its confidence times this weight, in
  // [0, 10] (0: LiDAR classes do not label tracks). Below 1, a camera outvotes one LiDAR frame.
  double lidar_class_weight = 0.5;
};

Status validate(const TrackerConfig& config);

}  // namespace fogmap::tracking
