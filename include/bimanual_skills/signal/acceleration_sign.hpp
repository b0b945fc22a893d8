/// \file
/// The sign of a joint acceleration estimated from measured velocities, for the hysteresis term of the friction
/// models (thesis Sec. 2.3.2, 4.2.2): a finite difference, two first-order low-pass stages and a Schmitt trigger.
#pragma once

#include "bimanual_skills/signal/signal_status.hpp"

#include <Eigen/Core>

namespace bimanual_skills::signal {

/// The sign of q̈ from measured joint velocities: q̈ is the finite difference of q̇ at the sample period, low-passed
/// by two cascaded first-order stages (a critically damped second-order filter, cut-off `cutoff_hz` each), and the
/// sign only flips when the filtered q̈ crosses ±`dead_band` (a Schmitt trigger), so sensor noise around q̈ = 0 does
/// not make the friction chatter. Defaults sized by simulation: a 0.5 Hz, 0.5 rad/s oscillation sampled at 500 Hz
/// with 2–5 mrad/s velocity noise gives exactly its 4 sign changes in 4 s (one first-order stage at 20 Hz: 61–253).
/// With a desired trajectory available (computed-torque control), sign(q̈_d) can be used directly instead: see
/// signWithDeadBand().
class AccelerationSign {
 public:
  /// \throws std::invalid_argument for n < 1, period ≤ 0, cut-off ≤ 0 or dead band < 0.
  AccelerationSign(int n, double period, double cutoff_hz = 10.0, double dead_band = 0.2);

  /// Feeds one velocity sample and updates sign() (−1, 0 before the first decision, +1). Real-time safe: no
  /// allocation, no exceptions. A wrongly sized or non-finite sample is rejected (WrongSize, NotFinite) and
  /// changes nothing.
  [[nodiscard]] SignalStatus update(const Eigen::Ref<const Eigen::VectorXd>& qd) noexcept;
  const Eigen::VectorXd& sign() const noexcept { return sign_; }
  const Eigen::VectorXd& filteredAcceleration() const noexcept { return filtered_; }
  void reset() noexcept;

 private:
  double period_, alpha_, dead_band_;
  bool primed_ = false;
  Eigen::VectorXd previous_, stage_, filtered_, sign_;
};

/// sign(x): 1, −1, or 0 for x = 0 (and NaN).
inline double sign(double x) noexcept {
  return x > 0.0 ? 1.0 : x < 0.0 ? -1.0 : 0.0;
}

/// sign[i] = sign(values[i]), 0 where |values[i]| ≤ dead_band (e.g. sign(q̈_d) of a desired trajectory for the
/// friction models). Real-time safe: no allocation, no exceptions; `sign` must have the size of `values`.
void signWithDeadBand(const Eigen::Ref<const Eigen::VectorXd>& values, double dead_band,
                      Eigen::Ref<Eigen::VectorXd> sign) noexcept;

}  // namespace bimanual_skills::signal
