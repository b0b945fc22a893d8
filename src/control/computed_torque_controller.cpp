#include "bimanual_skills/control/computed_torque_controller.hpp"

#include "bimanual_skills/signal/acceleration_sign.hpp"

#include <stdexcept>
#include <string>

namespace bimanual_skills::control {

const char* toString(ControlStatus status) noexcept {
  switch (status) {
    case ControlStatus::Success:
      return "success";
    case ControlStatus::Saturated:
      return "torque saturated";
    case ControlStatus::InvalidInput:
      return "invalid input (NaN/Inf or wrong size)";
  }
  return "unknown status";
}

ComputedTorqueController::ComputedTorqueController(const kinematics::ChainModel& model,
                                                   const dynamics::FrictionModel& friction, ComputedTorqueGains gains)
    : model_(model),
      inertial_model_(model.withGravity(Eigen::Vector3d::Zero())),
      friction_(friction),
      gains_(std::move(gains)),
      dynamics_(model),
      friction_state_(friction),
      feedforward_(Eigen::VectorXd::Zero(model.nq())),
      friction_torque_(Eigen::VectorXd::Zero(model.nq())),
      sign_(Eigen::VectorXd::Zero(model.nq())),
      state_(Eigen::VectorXd::Zero(2 * model.nq())),
      learned_n_(Eigen::VectorXd::Zero(model.nq())),
      zeros_(Eigen::VectorXd::Zero(model.nq())) {
  const int n = model.nq();
  if (gains_.torque_limit.size() == 0) gains_.torque_limit = model.effortLimits();
  if (gains_.kp.size() != n || gains_.kv.size() != n || gains_.torque_limit.size() != n) {
    throw std::invalid_argument("ComputedTorqueController: kp, kv and torque_limit need " + std::to_string(n) +
                                " entries");
  }
  if (!gains_.kp.allFinite() || !gains_.kv.allFinite() || (gains_.kp.array() < 0).any() ||
      (gains_.kv.array() < 0).any() || !(gains_.torque_limit.array() > 0).all()) {
    throw std::invalid_argument("ComputedTorqueController: gains must be finite and >= 0, torque limits > 0");
  }
  if (friction_.size() != n) {
    throw std::invalid_argument("ComputedTorqueController: the friction model has " + std::to_string(friction_.size()) +
                                " joints, the chain " + std::to_string(n));
  }
  friction_.validate();
}

ControlStatus ComputedTorqueController::update(const Eigen::Ref<const Eigen::VectorXd>& q,
                                               const Eigen::Ref<const Eigen::VectorXd>& qd,
                                               const Eigen::Ref<const Eigen::VectorXd>& q_desired,
                                               const Eigen::Ref<const Eigen::VectorXd>& qd_desired,
                                               const Eigen::Ref<const Eigen::VectorXd>& qdd_desired,
                                               Eigen::Ref<Eigen::VectorXd> u) noexcept {
  const int n = model_.nq();
  if (u.size() != n) return ControlStatus::InvalidInput;
  for (const auto* v : {&q, &qd, &q_desired, &qd_desired, &qdd_desired}) {
    if (v->size() != n || !v->allFinite()) return ControlStatus::InvalidInput;
  }
  bool learned = false;
  if (learned_.fits(n)) {
    // M(q) q̈_d from the rigid-body model, n(q, q̇) from the learned one.
    state_.head(n) = q;
    state_.tail(n) = qd;
    learned = learned_.predict(state_, learned_n_) &&
              dynamics::inverseDynamics(inertial_model_, dynamics_, q, zeros_, qdd_desired, feedforward_, payload_) ==
                  dynamics::DynamicsStatus::Success;
    if (learned) feedforward_ += learned_n_;
  }
  // Analytic: M(q) q̈_d + C(q, q̇) q̇ + G(q) in one Newton–Euler pass, then the friction model.
  if (!learned && dynamics::inverseDynamics(model_, dynamics_, q, qd, qdd_desired, feedforward_, payload_) !=
                      dynamics::DynamicsStatus::Success) {
    return ControlStatus::InvalidInput;
  }
  if (friction_enabled_ && !learned) {
    signal::signWithDeadBand(qdd_desired, 0.0, sign_);
    if (dynamics::frictionTorques(friction_, friction_state_, q, qd_desired, sign_, friction_torque_) ==
        dynamics::DynamicsStatus::Success) {
      feedforward_ += friction_torque_;
    }
  }
  bool saturated = false;
  for (int i = 0; i < n; ++i) {
    const double command =
        feedforward_[i] + gains_.kp[i] * (q_desired[i] - q[i]) + gains_.kv[i] * (qd_desired[i] - qd[i]);
    const double limit = gains_.torque_limit[i];
    u[i] = command > limit ? limit : command < -limit ? -limit : command;
    saturated = saturated || u[i] != command;
  }
  return saturated ? ControlStatus::Saturated : ControlStatus::Success;
}

}  // namespace bimanual_skills::control
