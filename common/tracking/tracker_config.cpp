#include "common/tracking/tracker_config.hpp"

#include <cmath>

namespace fogmap::tracking {

const char* associationName(Association association) {
  switch (association) {
    case Association::kPaper:
      return "paper";
    case Association::kKalman:
      return "kalman";
  }
  return "?";
}

Expected<Association> parseAssociation(const std::string& name) {
  if (name == "paper") return Association::kPaper;
  if (name == "kalman") return Association::kKalman;
  return invalidArgument("association must be 'paper' or 'kalman', not '" + name + "'");
}

Status validate(const TrackerConfig& c) {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(c.eps_sync_s)) return invalidArgument("tracker: eps_sync_s must be a positive number of seconds");
  if (!positive(c.rho_overlay_m)) return invalidArgument("tracker: rho_overlay_m must be positive");
  if (!positive(c.rho_purecloud_m)) return invalidArgument("tracker: rho_purecloud_m must be positive");
  if (!positive(c.gate_chi2)) return invalidArgument("tracker: gate_chi2 must be positive");
  if (!positive(c.acceleration_sigma)) return invalidArgument("tracker: acceleration_sigma must be positive");
  if (!positive(c.initial_speed_sigma)) return invalidArgument("tracker: initial_speed_sigma must be positive");
  if (!positive(c.min_measurement_sigma_m)) return invalidArgument("tracker: min_measurement_sigma_m must be positive");
  if (c.confirm_hits < 1) return invalidArgument("tracker: confirm_hits must be at least 1");
  if (!positive(c.tentative_timeout_s)) return invalidArgument("tracker: tentative_timeout_s must be positive");
  if (!positive(c.track_timeout_s)) return invalidArgument("tracker: track_timeout_s must be positive");
  if (!(std::isfinite(c.publish_lost_s) && c.publish_lost_s >= 0.0 && c.publish_lost_s <= c.track_timeout_s)) {
    return invalidArgument("tracker: publish_lost_s must be in [0, track_timeout_s] seconds");
  }
  if (c.max_buffered_frames < 1) return invalidArgument("tracker: max_buffered_frames must be at least 1");
  if (!(std::isfinite(c.max_detection_wait_s) && c.max_detection_wait_s >= 0.0 && c.max_detection_wait_s <= 10.0)) {
    return invalidArgument("tracker: max_detection_wait_s must be in [0, 10] seconds");
  }
  if (!positive(c.shed_reach_m)) return invalidArgument("tracker: shed_reach_m must be positive");
  if (!(std::isfinite(c.lidar_class_weight) && c.lidar_class_weight >= 0.0 && c.lidar_class_weight <= 10.0)) {
    return invalidArgument("tracker: lidar_class_weight must be in [0, 10]");
  }
  return {};
}

}  // namespace fogmap::tracking
