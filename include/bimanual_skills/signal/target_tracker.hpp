/// \file
/// A tracked point target (an object a camera sees, thesis Sec. 4.3.2): a constant-velocity Kalman filter of its
/// position and velocity in 3-D, fed measured positions at irregular times (camera frames arrive late, are dropped,
/// or stop), with the gating and the lost state a tracking controller needs. Model (Bar-Shalom, Li & Kirubarajan,
/// "Estimation with Applications to Tracking and Navigation", 2001, Sec. 6.3.2, the continuous white-noise
/// acceleration model), per axis with state x = (p, v) over a step Δt:
///   F = [1 Δt; 0 1],  Q = q [Δt³/3 Δt²/2; Δt²/2 Δt],  z = p + w, w ~ N(0, R),
/// q the acceleration noise's power spectral density [m²/s³]. A measurement whose normalised innovation squared
/// νᵀ S⁻¹ ν exceeds the gate (χ² with 3 DoF) is rejected: a jump is not followed. The target is lost once no
/// measurement was accepted for `lost_after` seconds (or `reject_limit` were rejected in a row: it moved elsewhere),
/// and the next measurement starts the track anew. update() and predict() are real-time safe: fixed-size matrices, no
/// allocation, no exception, no lock. Target bimanual_skills_signal.
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::signal {

struct TargetTrackerConfig {
  double acceleration_noise = 1.0;  ///< q, the acceleration noise's power spectral density [m²/s³].
  double initial_speed = 0.5;       ///< Standard deviation of the velocity when a track starts [m/s].
  double gate = 16.27;              ///< χ² gate on the normalised innovation squared (3 DoF; 16.27: p = 0.001).
  double lost_after = 0.5;          ///< [s] without an accepted measurement: the target is lost.
  int reject_limit = 5;             ///< Rejected measurements in a row that lose the target.

  /// Whether every value is finite and in range (q, speed, gate, lost_after > 0, reject_limit ≥ 1).
  bool valid() const noexcept;
};

class TargetTracker {
 public:
  enum class Update {
    Started,   ///< The measurement started a new track (the first one, or one after the target was lost).
    Accepted,  ///< Within the gate: filtered in.
    Rejected,  ///< Outside the gate: ignored (a jump, an outlier).
    /// Non-finite values, a covariance that is not symmetric positive definite, or a time not after the last
    /// measurement's (a duplicate or reordered frame).
    Invalid,
  };

  /// \throws std::invalid_argument when `config` is not valid.
  explicit TargetTracker(const TargetTrackerConfig& config);

  /// Filters in the position `z` measured at time `t` [s] with covariance `r` (symmetric positive definite).
  Update update(double t, const Eigen::Vector3d& z, const Eigen::Matrix3d& r) noexcept;
  /// Position and velocity predicted to time `t` (≥ the last measurement's; earlier times give the filtered state),
  /// and the position's covariance there; false when no track runs (never started, or lost at `t`).
  bool predict(double t, Eigen::Vector3d& position, Eigen::Vector3d& velocity,
               Eigen::Matrix3d& covariance) const noexcept;
  /// Whether a track runs at time `t`: started, and neither lost_after without an accepted measurement nor
  /// reject_limit rejections in a row.
  bool tracking(double t) const noexcept;
  /// The normalised innovation squared of the last accepted or rejected measurement (consistency: about 3 on
  /// average for a filter that fits the target).
  double lastInnovation() const noexcept { return last_nis_; }
  /// The time of the last accepted measurement [s].
  double lastAccepted() const noexcept { return t_; }
  void reset() noexcept;

 private:
  /// The state and covariance propagated by Δt ≥ 0 (per axis, the model above).
  void propagate(double dt, Eigen::Matrix<double, 6, 1>& x, Eigen::Matrix<double, 6, 6>& p) const noexcept;

  TargetTrackerConfig config_;
  bool started_ = false;
  int rejected_ = 0;
  double t_ = 0.0, last_seen_ = 0.0, last_nis_ = 0.0;
  Eigen::Matrix<double, 6, 1> x_ = Eigen::Matrix<double, 6, 1>::Zero();  ///< (p, v) at t_.
  Eigen::Matrix<double, 6, 6> p_ = Eigen::Matrix<double, 6, 6>::Zero();
};

}  // namespace bimanual_skills::signal
