/// \file
/// Sensorless external-force estimation with the disturbance observer of thesis Sec. 4.1 (eqs. 4.5–4.15).
#pragma once

#include "bimanual_skills/control/learned_dynamics.hpp"
#include "bimanual_skills/dynamics/friction_model.hpp"
#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/signal/fir_filter.hpp"

#include <Eigen/Cholesky>

namespace bimanual_skills::control {

/// Outcome of an observer update. On WrongSize, NotFinite and InvalidTimeStep the estimates are unchanged.
enum class ObserverStatus {
  Success,
  WrongSize,
  NotFinite,
  InvalidTimeStep,  ///< Δt not finite or not > 0.
  Restarted,        ///< Δt longer than the observer can integrate (a gap): the estimate restarted at this state.
};
const char* toString(ObserverStatus status) noexcept;

struct ObserverGains {
  Eigen::MatrixXd K11, K12, K21, K22, Sigma;  ///< n × n each.
  double rate_hz = 500.0;                     ///< Nominal update rate (the FIR's sample rate; Δt may differ).
  int fir_taps = 15;                          ///< Velocity FIR length (odd).
  double fir_cutoff_hz = 40.0;                ///< Velocity FIR cut-off.
  double wrench_damping = 1e-3;               ///< λ of F = (J Jᵀ + λ² I)⁻¹ J τ (near singularities).

  /// Diagonal gains k11, k12, k21, k22, σ on every joint.
  static ObserverGains diagonal(int n, double k11, double k12, double k21, double k22, double sigma);
};

/// State observer with disturbance estimate, discretised at rate_hz. With P = K11 + (I − K12)(Σ + K22)⁻¹ K21 and
/// G = (Σ + K22)⁻¹ K21 (4.14):  x̂1 ← x̂1 + T (P (q − x̂1) + v),  x̂2 = G (q − x̂1) + v,  v the FIR-filtered measured
/// velocity; then (4.15) d̂ = M(x̂1) (ẋ̂2 + Σ (v − x̂2)) + n̂(x̂1, x̂2) − u_c, with ẋ̂2 the backward difference of x̂2 and
/// n̂ = C + G + F_f. With the robot obeying M q̈ + n = u_c + τ_ext, d̂ estimates τ_ext, the joint torque the environment
/// applies on the robot (the thesis' d = −u_e, u_e being the robot's action on the environment); the tool wrench
/// solves Jᵀ F = τ̂_ext in the least-squares sense (damped): the wrench the environment exerts on the tool.
class DisturbanceObserver {
 public:
  /// \throws std::invalid_argument if gain sizes are wrong, Σ + K22 is singular, the symmetric part of P is not
  /// positive definite (no convergence, 4.14), T times P's largest eigenvalue reaches 1 (the discretisation would
  /// not converge at this rate), or the friction model does not fit the chain. Messages name the failing check.
  DisturbanceObserver(const kinematics::ChainModel& model, const dynamics::FrictionModel& friction,
                      const ObserverGains& gains);

  /// Starts the estimate at a measured state.
  void reset(const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& qd) noexcept;

  /// One observer step at the nominal period 1/rate_hz with the measured q, q̇, the torque u_c applied over the
  /// last period and sign(q̈) for the friction term. WrongSize or NotFinite (estimates unchanged) on bad input.
  /// Real-time safe: no allocation, no exceptions.
  [[nodiscard]] ObserverStatus update(const Eigen::Ref<const Eigen::VectorXd>& q,
                                      const Eigen::Ref<const Eigen::VectorXd>& qd,
                                      const Eigen::Ref<const Eigen::VectorXd>& u,
                                      const Eigen::Ref<const Eigen::VectorXd>& accel_sign) noexcept;
  /// One observer step `dt` [s] after the previous one, as measured (a robot at another rate, a dropped or late
  /// sample): x̂1 is integrated and ẋ̂2 differentiated over dt, and the velocity FIR, designed for the nominal
  /// rate, is fed the measured velocity held over dt (zero-order hold resampled to the nominal rate: one sample per
  /// nominal period that elapsed, rounded). A step whose dt differs from the nominal period by more than 20 % is
  /// counted (irregularSteps()); a dt beyond what the discretisation integrates stably (or 20 periods) restarts
  /// the estimate at this state (Restarted, counted in restarts()); dt ≤ 0 or not finite is InvalidTimeStep.
  /// Real-time safe: no allocation, no exceptions.
  [[nodiscard]] ObserverStatus update(const Eigen::Ref<const Eigen::VectorXd>& q,
                                      const Eigen::Ref<const Eigen::VectorXd>& qd,
                                      const Eigen::Ref<const Eigen::VectorXd>& u,
                                      const Eigen::Ref<const Eigen::VectorXd>& accel_sign, double dt) noexcept;
  /// Nominal period 1/rate_hz [s].
  double period() const noexcept { return period_; }
  /// Steps whose Δt differed from the nominal period by more than 20 %, and restarts after gaps.
  long irregularSteps() const noexcept { return irregular_steps_; }
  long restarts() const noexcept { return restarts_; }

  void setPayload(const dynamics::Payload& payload) noexcept { payload_ = payload; }
  /// Learned n̂(q, q̇) = C q̇ + G + F_f (inputs [q; q̇]) in place of the analytic terms of (4.15), as in the
  /// controller; where it has no prediction the analytic model is used. Not owned. Real-time safe.
  void setLearnedModel(LearnedDynamics model) noexcept { learned_ = model; }
  const Eigen::VectorXd& externalTorque() const noexcept { return external_torque_; }
  /// Estimated wrench [f; m] the environment exerts on the tip, in the base frame, at the tip's origin.
  const Eigen::Matrix<double, 6, 1>& wrench() const noexcept { return wrench_; }
  const Eigen::VectorXd& positionEstimate() const noexcept { return x1_; }
  const Eigen::VectorXd& velocityEstimate() const noexcept { return x2_; }
  const Eigen::MatrixXd& convergenceMatrix() const noexcept { return P_; }

 private:
  kinematics::ChainModel model_;
  kinematics::ChainModel inertial_model_;  ///< model_ without gravity: RNEA(q, 0, a) = M(q) a
  dynamics::FrictionModel friction_;
  LearnedDynamics learned_;
  double period_, wrench_damping_;
  double max_step_;              ///< Longest Δt integrated; a longer one restarts the estimate.
  double velocity_clock_ = 0.0;  ///< Time not yet fed to the FIR (resampling to the nominal rate).
  long irregular_steps_ = 0, restarts_ = 0;
  Eigen::MatrixXd P_, G_, Sigma_;
  signal::FirFilter velocity_filter_;
  dynamics::DynamicsData dynamics_;
  dynamics::FrictionState friction_state_;
  kinematics::ChainData kinematics_;
  dynamics::Payload payload_;
  Eigen::VectorXd x1_, x2_, x2_previous_, e1_, e1_dt_, accel_, velocity_error_, tau_model_, friction_torque_,
      external_torque_;
  Eigen::VectorXd state_, learned_n_, zeros_;
  Eigen::Matrix<double, 6, 6> gram_;
  Eigen::LLT<Eigen::Matrix<double, 6, 6>> gram_llt_;
  Eigen::Matrix<double, 6, 1> wrench_;
  bool started_ = false;
};

}  // namespace bimanual_skills::control
