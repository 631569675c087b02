#pragma once
// A constant-velocity Kalman filter on the ground plane: state (x, y, vx, vy), position
// measurements with their own covariance (from a centroid's or ellipsoid's spread), white
// acceleration noise. Pure; the tracker's predict and update steps, and the Mahalanobis distance
// its gate uses.
#include <Eigen/Core>

namespace fogmap::tracking {

struct ConstantVelocityModel {
  double acceleration_sigma = 1.0;  // m/s^2: how hard targets may speed up, slow down or turn
};

class ConstantVelocityFilter {
 public:
  // Starts at a measured position with its covariance, at rest with velocity sigma `speed_sigma`.
  ConstantVelocityFilter(const Eigen::Vector2d& position, const Eigen::Matrix2d& position_covariance,
                         double speed_sigma, ConstantVelocityModel model = {});

  // Moves the state dt seconds ahead (dt >= 0; negative is treated as 0).
  void predict(double dt);
  // The predicted measurement's innovation covariance S = H P H^T + R and the squared Mahalanobis
  // distance of `measurement` from the predicted position.
  Eigen::Matrix2d innovationCovariance(const Eigen::Matrix2d& measurement_covariance) const;
  double mahalanobis2(const Eigen::Vector2d& measurement, const Eigen::Matrix2d& measurement_covariance) const;
  // Corrects the state with a position measurement (Joseph form: the covariance stays symmetric
  // and positive semi-definite).
  void update(const Eigen::Vector2d& measurement, const Eigen::Matrix2d& measurement_covariance);

  Eigen::Vector2d position() const { return state_.head<2>(); }
  Eigen::Vector2d velocity() const { return state_.tail<2>(); }
  const Eigen::Vector4d& state() const { return state_; }
  const Eigen::Matrix4d& covariance() const { return covariance_; }

 private:
  Eigen::Vector4d state_;
  Eigen::Matrix4d covariance_;
  ConstantVelocityModel model_;
};

}  // namespace fogmap::tracking
