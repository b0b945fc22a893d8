/// \file
/// The robot interface a controller talks to (house style item 15): read each arm's joint state, write its joint
/// torques. The Bullet simulation implements it; a hardware driver would implement the same calls, so a controller
/// written against RobotInterface cannot tell the two apart. Only Eigen: no Bullet, no ROS.
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::sim {

/// Outcome of a robot-interface call.
enum class RobotStatus {
  Ok,
  InvalidCommand,  ///< Torque vector of the wrong size or with NaN/Inf: rejected, the previous command holds.
  WrongSize,       ///< The caller's JointState buffers are not sized for the arm (use JointState(n)).
  UnknownArm,      ///< Arm index out of range.
  Fault,           ///< The backend cannot deliver (simulation diverged, hardware fault): state not updated.
};

/// Name of a status ("Ok", "InvalidCommand", ...), for logs outside the real-time path.
const char* toString(RobotStatus status) noexcept;

/// What the joint sensors of one arm report.
struct JointState {
  JointState() = default;
  /// Buffers sized for an arm of n joints, zero-filled.
  explicit JointState(int n)
      : position(Eigen::VectorXd::Zero(n)), velocity(Eigen::VectorXd::Zero(n)), effort(Eigen::VectorXd::Zero(n)) {}

  Eigen::VectorXd position;  ///< Measured joint positions [rad or m] (encoder resolution applies).
  Eigen::VectorXd velocity;  ///< Measured joint velocities [rad/s or m/s] (sensor noise applies).
  Eigen::VectorXd effort;    ///< Torque the motors currently apply [N m or N] (the command after saturation).
  double time = 0.0;         ///< Time of the measurement [s] (simulated time for a simulation).
};

/// A robot of one or more torque-controlled arms.
class RobotInterface {
 public:
  virtual ~RobotInterface() = default;

  virtual int armCount() const noexcept = 0;
  /// Joints of arm `arm` (0 for an unknown arm).
  virtual int jointCount(int arm) const noexcept = 0;
  /// Latest measurement of arm `arm` into `state` (buffers must already have jointCount(arm) entries).
  /// Real-time safe: no allocation, no exceptions.
  virtual RobotStatus readJointState(int arm, JointState& state) noexcept = 0;
  /// Torque command of arm `arm` [N m], held until the next write. Real-time safe: no allocation, no exceptions.
  virtual RobotStatus writeJointTorques(int arm, const Eigen::Ref<const Eigen::VectorXd>& torque) noexcept = 0;

 protected:
  RobotInterface() = default;
  RobotInterface(const RobotInterface&) = default;
  RobotInterface& operator=(const RobotInterface&) = default;
};

}  // namespace bimanual_skills::sim
