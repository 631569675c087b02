#pragma once
// A constant turn rate and velocity (CTRV) model for vehicles (Schubert, Richter and Wanielik 2008,
// "Comparison and evaluation of advanced motion models for vehicle tracking"): state (x, y,
// heading, speed, yaw rate) on the ground plane in an extended Kalman filter. A car moves along
// its heading and turns at its yaw rate; unlike a constant-velocity filter, its heading is state,
// carried through gaps and turns, and measured from its box as well as from its motion. Pure; the
// tracker's vehicle tracks (common/tracking/tracker.cpp).
//
// Prediction over dt with heading t, speed v and yaw rate w (the specification):
//   x' = x + v / w (sin(t + w dt) - sin t),  y' = y + v / w (cos t - cos(t + w dt)),  t' = t + w dt,
// v' = v, w' = w; for |w| below kStraightYawRate the second-order expansion in w of the same arc
// (x' = x + v dt cos t - v w dt^2 sin t / 2, y' = y + v dt sin t + v w dt^2 cos t / 2), which is
// off the arc by about v w^2 dt^3 / 6: below 1e-5 m there for speeds up to 40 m/s and dt up to 1 s.
// Process noise: white longitudinal acceleration (acceleration_sigma) and yaw acceleration
// (yaw_acceleration_sigma) over dt, Q = G diag(sa^2, sy^2) G^T with G's columns (dt^2/2 cos t,
// dt^2/2 sin t, 0, dt, 0) and (0, 0, dt^2/2, 0, dt).
// The speed is never negative: an update that would make it so turns the heading round (t + pi, -v:
// the same motion), so the heading is always the direction the vehicle moves in.
#include <Eigen/Core>

namespace fogmap::tracking {

struct CtrvModel {
  double acceleration_sigma = 2.0;      // m/s^2: braking and speeding up
  double yaw_acceleration_sigma = 1.0;  // rad/s^2: how fast a turn starts or ends
};

using CtrvState = Eigen::Matrix<double, 5, 1>;       // x, y, heading, speed, yaw rate
using CtrvCovariance = Eigen::Matrix<double, 5, 5>;

// Below this yaw rate (rad/s) the prediction takes the expansion for small w.
inline constexpr double kStraightYawRate = 1e-3;

// The arc of the model: `state` moved dt seconds ahead, and the Jacobian of that map.
CtrvState ctrvPredict(const CtrvState& state, double dt);
Eigen::Matrix<double, 5, 5> ctrvJacobian(const CtrvState& state, double dt);

class CtrvFilter {
 public:
  // Starts at a measured position with its covariance, moving along `heading` (radians) at
  // `speed` (m/s; a negative one turns the heading round), with those sigmas, not turning (yaw rate
  // 0 with sigma yaw_rate_sigma).
  CtrvFilter(const Eigen::Vector2d& position, const Eigen::Matrix2d& position_covariance, double heading,
             double heading_sigma, double speed, double speed_sigma, double yaw_rate_sigma, CtrvModel model = {});

  // Moves the state dt seconds ahead (dt >= 0; negative is treated as 0).
  void predict(double dt);
  // The squared Mahalanobis distance of a position measurement from the predicted position.
  double mahalanobis2(const Eigen::Vector2d& measurement, const Eigen::Matrix2d& measurement_covariance) const;
  // Corrects the state with a position measurement (Joseph form).
  void updatePosition(const Eigen::Vector2d& measurement, const Eigen::Matrix2d& measurement_covariance);
  // Corrects the state with a measured heading (radians, any turn; the innovation is taken in
  // (-pi, pi]) of standard deviation `sigma` (radians).
  void updateHeading(double heading, double sigma);
  // The same for a measured axis, which does not tell front from back (a box's yaw): of the two
  // directions along it, the one nearer the state's heading is the measurement.
  void updateAxis(double axis, double sigma);

  Eigen::Vector2d position() const { return state_.head<2>(); }
  double heading() const { return state_(2); }  // in (-pi, pi]
  double speed() const { return state_(3); }
  double yawRate() const { return state_(4); }
  Eigen::Vector2d velocity() const;
  Eigen::Matrix2d positionCovariance() const { return covariance_.topLeftCorner<2, 2>(); }
  const CtrvState& state() const { return state_; }
  const CtrvCovariance& covariance() const { return covariance_; }

 private:
  // A linear measurement of the state (rows of H), Joseph form, then the heading wrapped and the
  // speed kept non-negative.
  template <int M>
  void correct(const Eigen::Matrix<double, M, 5>& h, const Eigen::Matrix<double, M, 1>& innovation,
               const Eigen::Matrix<double, M, M>& measurement_covariance);
  void normalise();

  CtrvState state_;
  CtrvCovariance covariance_;
  CtrvModel model_;
};

}  // namespace fogmap::tracking
