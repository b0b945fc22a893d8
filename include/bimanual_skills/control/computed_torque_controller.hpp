/// \file
/// Computed-torque controller with low PD gains (thesis eq. 4.17): u = M(q) q̈_d + C(q, q̇) q̇ + G(q) + F_f + Kp e + Kv ė.
#pragma once

#include "bimanual_skills/control/learned_dynamics.hpp"
#include "bimanual_skills/dynamics/friction_model.hpp"
#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"

namespace bimanual_skills::control {

struct ComputedTorqueGains {
  Eigen::VectorXd kp;            ///< Position gains [N m/rad], ≥ 0.
  Eigen::VectorXd kv;            ///< Velocity gains [N m s/rad], ≥ 0.
  Eigen::VectorXd torque_limit;  ///< Saturation per joint [N m], > 0 (default: the model's effort limits).
};

enum class ControlStatus { Success, Saturated, InvalidInput };
const char* toString(ControlStatus status) noexcept;

/// Owns its model, friction model and scratch: construction allocates and validates, update() does neither.
class ComputedTorqueController {
 public:
  /// \throws std::invalid_argument for gains or friction of the wrong size, negative gains, non-positive limits.
  ComputedTorqueController(const kinematics::ChainModel& model, const dynamics::FrictionModel& friction,
                           ComputedTorqueGains gains);

  /// u = RNEA(q, q̇, q̈_d) + F_f(q, q̇_d, sign q̈_d) + Kp (q_d − q) + Kv (q̇_d − q̇), clamped to ±torque_limit.
  /// Friction is evaluated on the desired velocity and acceleration sign (noise-free; the measured ones feed the
  /// PD terms). Returns Saturated when any joint was clamped, InvalidInput (u untouched) for NaN/Inf or sizes.
  /// Real-time safe: no allocation, no exceptions.
  ControlStatus update(const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& qd,
                       const Eigen::Ref<const Eigen::VectorXd>& q_desired,
                       const Eigen::Ref<const Eigen::VectorXd>& qd_desired,
                       const Eigen::Ref<const Eigen::VectorXd>& qdd_desired, Eigen::Ref<Eigen::VectorXd> u) noexcept;

  /// Real-time safe switches.
  void setFrictionCompensation(bool enabled) noexcept { friction_enabled_ = enabled; }
  void setPayload(const dynamics::Payload& payload) noexcept { payload_ = payload; }
  /// Learned alternative (thesis Sec. 2.3.1): with a model of n(q, q̇) = C q̇ + G + F_f (inputs [q; q̇], n outputs),
  /// the feed-forward becomes M(q) q̈_d + n̂(q, q̇), only M coming from the rigid-body model; where the learned model
  /// has no prediction the analytic feed-forward is used. An empty handle returns to the analytic model. The model
  /// is not owned and must outlive its use. Real-time safe.
  void setLearnedModel(LearnedDynamics model) noexcept { learned_ = model; }

  const kinematics::ChainModel& model() const noexcept { return model_; }
  const dynamics::FrictionModel& friction() const noexcept { return friction_; }
  const ComputedTorqueGains& gains() const noexcept { return gains_; }
  /// The last feed-forward (model) part of u, before the PD terms and saturation.
  const Eigen::VectorXd& feedforward() const noexcept { return feedforward_; }

 private:
  kinematics::ChainModel model_;
  kinematics::ChainModel inertial_model_;  ///< model_ without gravity: RNEA(q, 0, q̈) = M(q) q̈
  dynamics::FrictionModel friction_;
  ComputedTorqueGains gains_;
  dynamics::DynamicsData dynamics_;
  dynamics::FrictionState friction_state_;
  dynamics::Payload payload_;
  bool friction_enabled_ = true;
  LearnedDynamics learned_;
  Eigen::VectorXd feedforward_, friction_torque_, sign_, state_, learned_n_, zeros_;
};

}  // namespace bimanual_skills::control
