#include "bimanual_skills/signal/acceleration_sign.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace bimanual_skills::signal {

AccelerationSign::AccelerationSign(int n, double period, double cutoff_hz, double dead_band)
    : period_(period),
      alpha_(0.0),
      dead_band_(dead_band),
      previous_(Eigen::VectorXd::Zero(std::max(n, 1))),
      stage_(Eigen::VectorXd::Zero(std::max(n, 1))),
      filtered_(Eigen::VectorXd::Zero(std::max(n, 1))),
      sign_(Eigen::VectorXd::Zero(std::max(n, 1))) {
  if (n < 1 || !(period > 0.0) || !(cutoff_hz > 0.0) || !(dead_band >= 0.0) || !std::isfinite(period) ||
      !std::isfinite(cutoff_hz) || !std::isfinite(dead_band)) {
    throw std::invalid_argument("AccelerationSign: need n >= 1, period > 0, cutoff_hz > 0, dead_band >= 0");
  }
  // Each stage a discretised first-order low-pass: y += α (x − y), α = 1 − exp(−2π f_c T).
  alpha_ = 1.0 - std::exp(-2.0 * M_PI * cutoff_hz * period);
}

SignalStatus AccelerationSign::update(const Eigen::Ref<const Eigen::VectorXd>& qd) noexcept {
  if (qd.size() != previous_.size()) return SignalStatus::WrongSize;
  if (!qd.allFinite()) return SignalStatus::NotFinite;
  if (!primed_) {
    previous_ = qd;
    primed_ = true;
    return SignalStatus::Success;
  }
  for (Eigen::Index i = 0; i < qd.size(); ++i) {
    const double raw = (qd[i] - previous_[i]) / period_;
    stage_[i] += alpha_ * (raw - stage_[i]);
    filtered_[i] += alpha_ * (stage_[i] - filtered_[i]);
    if (filtered_[i] > dead_band_) {
      sign_[i] = 1.0;
    } else if (filtered_[i] < -dead_band_) {
      sign_[i] = -1.0;
    }
  }
  previous_ = qd;
  return SignalStatus::Success;
}

void AccelerationSign::reset() noexcept {
  primed_ = false;
  previous_.setZero();
  stage_.setZero();
  filtered_.setZero();
  sign_.setZero();
}

void signWithDeadBand(const Eigen::Ref<const Eigen::VectorXd>& values, double dead_band,
                      Eigen::Ref<Eigen::VectorXd> sign) noexcept {
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    sign[i] = values[i] > dead_band ? 1.0 : values[i] < -dead_band ? -1.0 : 0.0;
  }
}

}  // namespace bimanual_skills::signal
