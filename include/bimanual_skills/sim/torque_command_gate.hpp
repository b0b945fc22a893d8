/// \file
/// What a robot (simulated or real) does with torque commands that arrive over a network: it checks them, uses
/// them while they are fresh and, when they stop, brakes instead of replaying the last one: τ = −D q̇ (zero torque
/// plus braking damping). A command may carry a joint impedance that the robot closes itself at every step between
/// commands, as the drivers of torque-controlled arms do (KUKA's FRI, Franka's joint impedance): the torque is then
/// τ + K (q_d + q̇_d (t − t_c) − q) + D_c (q̇_d − q̇), its setpoint moving on at its velocity from the command's time
/// t_c, so that a controller whose commands arrive late or in bursts does not leave the arm open-loop.
#pragma once

#include "bimanual_skills/sim/robot_interface.hpp"

#include <limits>

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
  /// The same with a joint impedance: setpoint `position` and `velocity`, `stiffness` [N m/rad] and `damping`
  /// [N m s/rad] per joint (finite, the gains ≥ 0); InvalidCommand otherwise. The setpoint is the one of time
  /// `setpoint_time` (the stamp of the state the command answers) and moves on at its velocity from there; NaN, a time
  /// after `now` or one more than the timeout before it: from `now`.
  RobotStatus accept(double now, const Eigen::Ref<const Eigen::VectorXd>& torque,
                     const Eigen::Ref<const Eigen::VectorXd>& position,
                     const Eigen::Ref<const Eigen::VectorXd>& velocity,
                     const Eigen::Ref<const Eigen::VectorXd>& stiffness,
                     const Eigen::Ref<const Eigen::VectorXd>& damping,
                     double setpoint_time = std::numeric_limits<double>::quiet_NaN()) noexcept;

  /// The torque to apply at `now` given the measured state: the last command (with its impedance) while fresh,
  /// else −D q̇. Returns true when braking.
  bool torque(double now, const Eigen::Ref<const Eigen::VectorXd>& position,
              const Eigen::Ref<const Eigen::VectorXd>& velocity, Eigen::Ref<Eigen::VectorXd> out) noexcept;

  /// Forgets the command (brakes until the next one).
  void clear() noexcept { received_ = false; }
  bool hasCommand() const noexcept { return received_; }
  /// Time of the last accepted command.
  double lastCommandTime() const noexcept { return last_time_; }

 private:
  Eigen::VectorXd command_, damping_;
  Eigen::VectorXd setpoint_, setpoint_velocity_, stiffness_, impedance_damping_;  ///< The command's impedance.
  double timeout_;
  double last_time_ = 0.0;
  double setpoint_time_ = 0.0;  ///< When the impedance's setpoint held.
  bool received_ = false, impedance_ = false;
};

}  // namespace bimanual_skills::sim
