/// \file
/// What a robot (simulated or real) does with torque commands that arrive over a network: it checks them, uses
/// them while they are fresh and, when they stop, brakes instead of replaying the last one: τ = −D q̇ (zero torque
/// plus braking damping).
#pragma once

#include "bimanual_skills/sim/robot_interface.hpp"

#include <Eigen/Core>

namespace bimanual_skills::sim {

/// One arm's command gate. Construction allocates; the other calls are real-time safe (no allocation, no
/// exceptions).
class TorqueCommandGate {
 public:
  /// For `joints` joints; commands older than `timeout` [s] are stale; braking damping `damping` [N m s/rad] per
  /// joint. \throws std::invalid_argument for a non-positive timeout or negative or wrongly sized damping.
  TorqueCommandGate(int joints, double timeout, const Eigen::VectorXd& damping);

  /// A command received at time `now`: InvalidCommand (and the previous command stays) for a wrong size or NaN/Inf.
  RobotStatus accept(double now, const Eigen::Ref<const Eigen::VectorXd>& torque) noexcept;

  /// The torque to apply at `now` given the measured velocity: the last command while fresh, else −D q̇.
  /// Returns true when braking.
  bool torque(double now, const Eigen::Ref<const Eigen::VectorXd>& velocity, Eigen::Ref<Eigen::VectorXd> out) noexcept;

  /// Forgets the command (brakes until the next one).
  void clear() noexcept { received_ = false; }
  bool hasCommand() const noexcept { return received_; }
  /// Time of the last accepted command.
  double lastCommandTime() const noexcept { return last_time_; }

 private:
  Eigen::VectorXd command_, damping_;
  double timeout_;
  double last_time_ = 0.0;
  bool received_ = false;
};

}  // namespace bimanual_skills::sim
