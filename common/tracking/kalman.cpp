#include "common/tracking/kalman.hpp"

#include <algorithm>

#include <Eigen/Cholesky>

namespace fogmap::tracking {

ConstantVelocityFilter::ConstantVelocityFilter(const Eigen::Vector2d& position, const Eigen::Matrix2d& position_covariance,
                                               double speed_sigma, ConstantVelocityModel model)
    : model_(model) {
  state_ << position, 0.0, 0.0;
  covariance_.setZero();
  covariance_.topLeftCorner<2, 2>() = position_covariance;
  covariance_.bottomRightCorner<2, 2>() = Eigen::Matrix2d::Identity() * speed_sigma * speed_sigma;
}

void ConstantVelocityFilter::predict(double dt) {
  dt = std::max(dt, 0.0);
  Eigen::Matrix4d f = Eigen::Matrix4d::Identity();
  f(0, 2) = dt;
  f(1, 3) = dt;
  // White acceleration noise a ~ N(0, sigma^2) per axis over dt: G = (dt^2 / 2, dt), Q = G G^T sigma^2.
  const double q = model_.acceleration_sigma * model_.acceleration_sigma;
  const double dt2 = dt * dt;
  Eigen::Matrix4d noise = Eigen::Matrix4d::Zero();
  for (int axis = 0; axis < 2; ++axis) {
    noise(axis, axis) = dt2 * dt2 / 4.0 * q;
    noise(axis, axis + 2) = noise(axis + 2, axis) = dt2 * dt / 2.0 * q;
    noise(axis + 2, axis + 2) = dt2 * q;
  }
  state_ = f * state_;
  covariance_ = f * covariance_ * f.transpose() + noise;
}

Eigen::Matrix2d ConstantVelocityFilter::innovationCovariance(const Eigen::Matrix2d& measurement_covariance) const {
  return covariance_.topLeftCorner<2, 2>() + measurement_covariance;
}

double ConstantVelocityFilter::mahalanobis2(const Eigen::Vector2d& measurement,
                                            const Eigen::Matrix2d& measurement_covariance) const {
  const Eigen::Vector2d innovation = measurement - position();
  return innovation.dot(innovationCovariance(measurement_covariance).ldlt().solve(innovation));
}

void ConstantVelocityFilter::update(const Eigen::Vector2d& measurement, const Eigen::Matrix2d& measurement_covariance) {
  Eigen::Matrix<double, 2, 4> h = Eigen::Matrix<double, 2, 4>::Zero();
  h(0, 0) = 1.0;
  h(1, 1) = 1.0;
  const Eigen::Matrix2d s = innovationCovariance(measurement_covariance);
  // K = P H^T S^-1, by solving S K^T = H P (S and P symmetric).
  const Eigen::Matrix<double, 4, 2> gain = s.ldlt().solve(h * covariance_).transpose();
  state_ += gain * (measurement - position());
  const Eigen::Matrix4d i_kh = Eigen::Matrix4d::Identity() - gain * h;
  covariance_ = i_kh * covariance_ * i_kh.transpose() + gain * measurement_covariance * gain.transpose();
}

}  // namespace fogmap::tracking
