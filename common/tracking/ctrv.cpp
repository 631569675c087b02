#include "common/tracking/ctrv.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "common/base/angles.hpp"

namespace fogmap::tracking {

CtrvState ctrvPredict(const CtrvState& s, double dt) {
  const double t = s(2), v = s(3), w = s(4);
  CtrvState out = s;
  if (std::abs(w) >= kStraightYawRate) {
    out(0) += v / w * (std::sin(t + w * dt) - std::sin(t));
    out(1) += v / w * (std::cos(t) - std::cos(t + w * dt));
  } else {
    out(0) += v * dt * std::cos(t) - 0.5 * v * w * dt * dt * std::sin(t);
    out(1) += v * dt * std::sin(t) + 0.5 * v * w * dt * dt * std::cos(t);
  }
  out(2) = wrapToPi(t + w * dt);
  return out;
}

Eigen::Matrix<double, 5, 5> ctrvJacobian(const CtrvState& s, double dt) {
  const double t = s(2), v = s(3), w = s(4);
  const double s0 = std::sin(t), c0 = std::cos(t);
  Eigen::Matrix<double, 5, 5> f = Eigen::Matrix<double, 5, 5>::Identity();
  if (std::abs(w) >= kStraightYawRate) {
    const double s1 = std::sin(t + w * dt), c1 = std::cos(t + w * dt);
    f(0, 2) = v / w * (c1 - c0);
    f(0, 3) = (s1 - s0) / w;
    f(0, 4) = -v / (w * w) * (s1 - s0) + v / w * dt * c1;
    f(1, 2) = v / w * (s1 - s0);
    f(1, 3) = (c0 - c1) / w;
    f(1, 4) = -v / (w * w) * (c0 - c1) + v / w * dt * s1;
  } else {
    f(0, 2) = -v * dt * s0 - 0.5 * v * w * dt * dt * c0;
    f(0, 3) = dt * c0 - 0.5 * w * dt * dt * s0;
    f(0, 4) = -0.5 * v * dt * dt * s0;
    f(1, 2) = v * dt * c0 - 0.5 * v * w * dt * dt * s0;
    f(1, 3) = dt * s0 + 0.5 * w * dt * dt * c0;
    f(1, 4) = 0.5 * v * dt * dt * c0;
  }
  f(2, 4) = dt;
  return f;
}

CtrvFilter::CtrvFilter(const Eigen::Vector2d& position, const Eigen::Matrix2d& position_covariance, double heading,
                       double heading_sigma, double speed, double speed_sigma, double yaw_rate_sigma, CtrvModel model)
    : model_(model) {
  state_ << position, heading, speed, 0.0;
  covariance_.setZero();
  covariance_.topLeftCorner<2, 2>() = 0.5 * (position_covariance + position_covariance.transpose());
  covariance_(2, 2) = heading_sigma * heading_sigma;
  covariance_(3, 3) = speed_sigma * speed_sigma;
  covariance_(4, 4) = yaw_rate_sigma * yaw_rate_sigma;
  normalise();
}

void CtrvFilter::predict(double dt) {
  dt = std::max(dt, 0.0);
  const Eigen::Matrix<double, 5, 5> f = ctrvJacobian(state_, dt);
  const double t = state_(2);
  Eigen::Matrix<double, 5, 2> g = Eigen::Matrix<double, 5, 2>::Zero();
  g(0, 0) = 0.5 * dt * dt * std::cos(t);
  g(1, 0) = 0.5 * dt * dt * std::sin(t);
  g(3, 0) = dt;
  g(2, 1) = 0.5 * dt * dt;
  g(4, 1) = dt;
  const Eigen::Vector2d noise(model_.acceleration_sigma * model_.acceleration_sigma,
                              model_.yaw_acceleration_sigma * model_.yaw_acceleration_sigma);
  state_ = ctrvPredict(state_, dt);
  covariance_ = f * covariance_ * f.transpose() + g * noise.asDiagonal() * g.transpose();
  covariance_ = 0.5 * (covariance_ + covariance_.transpose());
}

double CtrvFilter::mahalanobis2(const Eigen::Vector2d& measurement, const Eigen::Matrix2d& measurement_covariance) const {
  const Eigen::Matrix2d s = positionCovariance() + measurement_covariance;
  const Eigen::Vector2d d = measurement - position();
  return d.dot(s.ldlt().solve(d));
}

template <int M>
void CtrvFilter::correct(const Eigen::Matrix<double, M, 5>& h, const Eigen::Matrix<double, M, 1>& innovation,
                         const Eigen::Matrix<double, M, M>& measurement_covariance) {
  const Eigen::Matrix<double, M, M> s = h * covariance_ * h.transpose() + measurement_covariance;
  const Eigen::Matrix<double, 5, M> k = covariance_ * h.transpose() * s.inverse();
  state_ += k * innovation;
  const Eigen::Matrix<double, 5, 5> a = Eigen::Matrix<double, 5, 5>::Identity() - k * h;
  covariance_ = a * covariance_ * a.transpose() + k * measurement_covariance * k.transpose();
  covariance_ = 0.5 * (covariance_ + covariance_.transpose());
  normalise();
}

void CtrvFilter::updatePosition(const Eigen::Vector2d& measurement, const Eigen::Matrix2d& measurement_covariance) {
  Eigen::Matrix<double, 2, 5> h = Eigen::Matrix<double, 2, 5>::Zero();
  h(0, 0) = 1.0;
  h(1, 1) = 1.0;
  correct<2>(h, measurement - position(), 0.5 * (measurement_covariance + measurement_covariance.transpose()));
}

void CtrvFilter::updateHeading(double heading, double sigma) {
  Eigen::Matrix<double, 1, 5> h = Eigen::Matrix<double, 1, 5>::Zero();
  h(0, 2) = 1.0;
  const Eigen::Matrix<double, 1, 1> innovation(wrapToPi(heading - state_(2)));
  const Eigen::Matrix<double, 1, 1> r(sigma * sigma);
  correct<1>(h, innovation, r);
}

void CtrvFilter::updateAxis(double axis, double sigma) {
  const double along = wrapToPi(axis - state_(2));
  const double nearer = std::abs(along) <= 0.5 * std::numbers::pi ? axis : axis + std::numbers::pi;
  updateHeading(nearer, sigma);
}

Eigen::Vector2d CtrvFilter::velocity() const { return state_(3) * Eigen::Vector2d(std::cos(state_(2)), std::sin(state_(2))); }

void CtrvFilter::normalise() {
  if (state_(3) < 0.0) {
    // (t, -v) and (t + pi, v) are the same motion; the yaw rate keeps its sign (the arc is the same).
    state_(3) = -state_(3);
    state_(2) += std::numbers::pi;
    covariance_.row(3) *= -1.0;
    covariance_.col(3) *= -1.0;
  }
  state_(2) = wrapToPi(state_(2));
}

}  // namespace fogmap::tracking
