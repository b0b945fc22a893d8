#include "bimanual_skills/sim/torque_command_gate.hpp"

#include <cmath>
#include <stdexcept>

namespace bimanual_skills::sim {

TorqueCommandGate::TorqueCommandGate(int joints, double timeout, const Eigen::VectorXd& damping)
    : command_(Eigen::VectorXd::Zero(joints)), damping_(damping), timeout_(timeout) {
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
  return RobotStatus::Ok;
}

bool TorqueCommandGate::torque(double now, const Eigen::Ref<const Eigen::VectorXd>& velocity,
                               Eigen::Ref<Eigen::VectorXd> out) noexcept {
  if (received_ && now - last_time_ <= timeout_) {
    out = command_;
    return false;
  }
  out = -damping_.cwiseProduct(velocity);
  return true;
}

}  // namespace bimanual_skills::sim
