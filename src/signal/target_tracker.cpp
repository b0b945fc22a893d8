#include "bimanual_skills/signal/target_tracker.hpp"

#include <Eigen/Cholesky>

#include <cmath>
#include <stdexcept>

namespace bimanual_skills::signal {

namespace {

using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

bool positiveFinite(double v) noexcept {
  return v > 0.0 && std::isfinite(v);
}

}  // namespace

bool TargetTrackerConfig::valid() const noexcept {
  return positiveFinite(acceleration_noise) && positiveFinite(initial_speed) && positiveFinite(gate) &&
         positiveFinite(lost_after) && reject_limit >= 1;
}

TargetTracker::TargetTracker(const TargetTrackerConfig& config) : config_(config) {
  if (!config.valid()) {
    throw std::invalid_argument(
        "target tracker: acceleration_noise, initial_speed, gate and lost_after must be finite and > 0, "
        "reject_limit >= 1");
  }
}

void TargetTracker::reset() noexcept {
  started_ = false;
  rejected_ = 0;
  t_ = last_seen_ = last_nis_ = 0.0;
  x_.setZero();
  p_.setZero();
}

bool TargetTracker::tracking(double t) const noexcept {
  return started_ && rejected_ < config_.reject_limit && t - t_ <= config_.lost_after;
}

void TargetTracker::propagate(double dt, Vector6& x, Matrix6& p) const noexcept {
  // x = F x; P = F P Fᵀ + Q with F = [I dt I; 0 I] (positions first, then velocities).
  x.head<3>() += dt * x.tail<3>();
  Matrix6 f = Matrix6::Identity();
  f.topRightCorner<3, 3>().diagonal().setConstant(dt);
  p = f * p * f.transpose();
  const double q = config_.acceleration_noise;
  const double q11 = q * dt * dt * dt / 3.0, q12 = q * dt * dt / 2.0, q22 = q * dt;
  p.topLeftCorner<3, 3>().diagonal().array() += q11;
  p.topRightCorner<3, 3>().diagonal().array() += q12;
  p.bottomLeftCorner<3, 3>().diagonal().array() += q12;
  p.bottomRightCorner<3, 3>().diagonal().array() += q22;
}

TargetTracker::Update TargetTracker::update(double t, const Eigen::Vector3d& z, const Eigen::Matrix3d& r) noexcept {
  if (!std::isfinite(t) || !z.allFinite() || !r.allFinite() || (started_ && t <= last_seen_)) return Update::Invalid;
  const Eigen::LLT<Eigen::Matrix3d> r_llt(r);
  if (r_llt.info() != Eigen::Success || !(r - r.transpose()).isZero(1e-12 * (1.0 + r.norm()))) {
    return Update::Invalid;
  }
  last_seen_ = t;
  if (!tracking(t)) {
    // A new track: at the measurement, at rest within initial_speed.
    started_ = true;
    rejected_ = 0;
    t_ = t;
    last_nis_ = 0.0;
    x_.head<3>() = z;
    x_.tail<3>().setZero();
    p_.setZero();
    p_.topLeftCorner<3, 3>() = r;
    p_.bottomRightCorner<3, 3>().diagonal().setConstant(config_.initial_speed * config_.initial_speed);
    return Update::Started;
  }
  Vector6 x = x_;
  Matrix6 p = p_;
  propagate(t - t_, x, p);
  // Innovation ν = z − H x, S = H P Hᵀ + R with H = [I 0].
  const Eigen::Vector3d nu = z - x.head<3>();
  const Eigen::Matrix3d s = p.topLeftCorner<3, 3>() + r;
  const Eigen::LLT<Eigen::Matrix3d> s_llt(s);
  if (s_llt.info() != Eigen::Success) return Update::Invalid;
  last_nis_ = nu.dot(s_llt.solve(nu));
  if (!(last_nis_ <= config_.gate)) {
    ++rejected_;
    return Update::Rejected;
  }
  // K = P Hᵀ S⁻¹; x += K ν; P = (I − K H) P (I − K H)ᵀ + K R Kᵀ (Joseph form: stays symmetric positive definite).
  const Eigen::Matrix<double, 6, 3> k = s_llt.solve(p.leftCols<3>().transpose()).transpose();
  x += k * nu;
  Matrix6 i_kh = Matrix6::Identity();
  i_kh.leftCols<3>() -= k;
  p = i_kh * p * i_kh.transpose() + k * r * k.transpose();
  x_ = x;
  p_ = p;
  t_ = t;
  rejected_ = 0;
  return Update::Accepted;
}

bool TargetTracker::predict(double t, Eigen::Vector3d& position, Eigen::Vector3d& velocity,
                            Eigen::Matrix3d& covariance) const noexcept {
  if (!tracking(t)) return false;
  Vector6 x = x_;
  Matrix6 p = p_;
  if (t > t_) propagate(t - t_, x, p);
  position = x.head<3>();
  velocity = x.tail<3>();
  covariance = p.topLeftCorner<3, 3>();
  return true;
}

}  // namespace bimanual_skills::signal
