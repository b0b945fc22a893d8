#include "bimanual_skills/sim/torque_command_gate.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace bimanual_skills::sim {

TorqueCommandGate::TorqueCommandGate(int joints, double timeout, const Eigen::VectorXd& damping)
    : command_(Eigen::VectorXd::Zero(joints)),
      damping_(damping),
      setpoint_(Eigen::VectorXd::Zero(joints)),
      setpoint_velocity_(Eigen::VectorXd::Zero(joints)),
      stiffness_(Eigen::VectorXd::Zero(joints)),
      impedance_damping_(Eigen::VectorXd::Zero(joints)),
      timeout_(timeout) {
  if (joints <= 0 || !(timeout > 0.0)) throw std::invalid_argument("TorqueCommandGate: joints and timeout must be > 0");
  if (damping.size() != joints || !damping.allFinite() || (damping.array() < 0.0).any()) {
    throw std::invalid_argument("TorqueCommandGate: braking damping needs " + std::to_string(joints) +
                                " finite non-negative entries");
  }
}

RobotStatus TorqueCommandGate::accept(double now, const Eigen::Ref<const Eigen::VectorXd>& torque) noexcept {
  if (torque.size() != command_.size() || !torque.allFinite() || !std::isfinite(now)) {
    return RobotStatus::InvalidCommand;
  }
  command_ = torque;
  last_time_ = now;
  received_ = true;
  impedance_ = false;
  return RobotStatus::Ok;
}

RobotStatus TorqueCommandGate::accept(double now, const Eigen::Ref<const Eigen::VectorXd>& torque,
                                      const Eigen::Ref<const Eigen::VectorXd>& position,
                                      const Eigen::Ref<const Eigen::VectorXd>& velocity,
                                      const Eigen::Ref<const Eigen::VectorXd>& stiffness,
                                      const Eigen::Ref<const Eigen::VectorXd>& damping, double setpoint_time) noexcept {
  const Eigen::Index n = command_.size();
  for (const auto* v : {&position, &velocity, &stiffness, &damping}) {
    if (v->size() != n || !v->allFinite()) return RobotStatus::InvalidCommand;
  }
  if ((stiffness.array() < 0.0).any() || (damping.array() < 0.0).any()) return RobotStatus::InvalidCommand;
  if (const RobotStatus status = accept(now, torque); status != RobotStatus::Ok) return status;
  setpoint_ = position;
  setpoint_velocity_ = velocity;
  stiffness_ = stiffness;
  impedance_damping_ = damping;
  impedance_ = true;
  setpoint_time_ =
      std::isfinite(setpoint_time) && setpoint_time <= now && now - setpoint_time <= timeout_ ? setpoint_time : now;
  return RobotStatus::Ok;
}

bool TorqueCommandGate::torque(double now, const Eigen::Ref<const Eigen::VectorXd>& position,
                               const Eigen::Ref<const Eigen::VectorXd>& velocity,
                               Eigen::Ref<Eigen::VectorXd> out) noexcept {
  if (received_ && now - last_time_ <= timeout_) {
    out = command_;
    if (impedance_) {
      const double ahead = std::max(0.0, now - setpoint_time_);
      out.array() += stiffness_.array() * (setpoint_.array() + setpoint_velocity_.array() * ahead - position.array()) +
                     impedance_damping_.array() * (setpoint_velocity_.array() - velocity.array());
    }
    return false;
  }
  out = -damping_.cwiseProduct(velocity);
  return true;
}

}  // namespace bimanual_skills::sim
