/// \file
/// The real-time part of a joint-space arm controller (what the `ctc_controller` node runs per joint-state
/// message): modes gravity compensation, hold and track, the computed-torque law (thesis eq. 4.17) with the
/// identified friction model, the disturbance observer (Sec. 4.1) for the external wrench at the tool, and the
/// safety rules: torque saturation, a velocity limit, a watchdog on the age of the joint states, rejection of
/// non-finite states and of bad trajectories. No ROS: the node is a shell that moves messages in and out.
#pragma once

#include "bimanual_skills/control/computed_torque_controller.hpp"
#include "bimanual_skills/control/disturbance_observer.hpp"
#include "bimanual_skills/control/joint_trajectory.hpp"
#include "bimanual_skills/dynamics/friction_model.hpp"
#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"

#include <string>

namespace bimanual_skills::control {

enum class ControllerMode { GravityCompensation, Hold, Track };

/// Name of a mode ("gravity_compensation", "hold", "track").
const char* toString(ControllerMode mode) noexcept;
/// The mode called `name`; false if there is none.
bool modeFromString(const char* name, ControllerMode& mode) noexcept;

/// Outcome of one update; anything but Ok/Saturated is also a reason the controller switched to hold.
enum class ControllerStatus {
  Ok,
  Saturated,      ///< Torque clamped at the limit on some joint (the torque is still sent).
  InvalidState,   ///< Wrong size or NaN/Inf in the measurement: no torque computed (caller sends none).
  StaleState,     ///< The state is older than the timeout: no torque computed; the controller holds on recovery.
  VelocityLimit,  ///< A joint moved faster than its limit: switched to hold at the current position.
};

const char* toString(ControllerStatus status) noexcept;
/// What a VelocityLimit stop saw: "joint k moved at v rad/s, over its velocity limit l rad/s" for the joint nearest
/// its limit in the measured `qd`; "" for sizes that differ or none (for logs outside the real-time path).
std::string velocityLimitText(const Eigen::VectorXd& qd, const Eigen::VectorXd& velocity_limit);

struct ArmControllerConfig {
  ComputedTorqueGains gains;       ///< Kp, Kv and torque limits of the computed-torque law.
  ObserverGains observer;          ///< Its rate_hz must be the control rate.
  Eigen::VectorXd velocity_limit;  ///< [rad/s] per joint; empty: the model's velocity limits.
  double state_timeout = 0.05;     ///< States older than this [s] are stale.
  int trajectory_capacity = 2000;  ///< Maximum waypoints of one trajectory.
  bool friction_compensation = true;
  /// A hold requested while the arm moves (a cancel, a path tolerance violated, set_mode hold) stops it smoothly
  /// from its desired state: a quintic to rest over T = max(min_stop_time, 2 max_j |q̇_d,j| / stop_deceleration).
  double stop_deceleration = 5.0;  ///< [rad/s²] > 0
  double min_stop_time = 0.05;     ///< [s] > 0
};

/// Construction allocates and validates (std::invalid_argument); every other call is real-time safe: no
/// allocation, no locks, no exceptions, no logging.
class ArmController {
 public:
  ArmController(const kinematics::ChainModel& model, const dynamics::FrictionModel& friction,
                ArmControllerConfig config);

  /// One control step with the state measured at `stamp`, computed at `now` (same clock): `now` only decides
  /// whether the state is stale; the trajectory runs on the stamps, so a run driven by the same states gives the
  /// same torques whenever they are computed. Writes `torque` unless the status is InvalidState or StaleState. The
  /// first valid state starts the controller in hold at that state, and so does a stamp earlier than the last one
  /// when `now` went back too (a simulation was reset); an earlier stamp alone is a delayed, stale state.
  /// The observer integrates over the measured Δt between stamps and is given the torque this controller
  /// commanded for the last period.
  ControllerStatus update(double now, double stamp, const Eigen::Ref<const Eigen::VectorXd>& q,
                          const Eigen::Ref<const Eigen::VectorXd>& qd, Eigen::Ref<Eigen::VectorXd> torque) noexcept;
  /// As above, for a robot that reports the torque `applied` over the last period (after its own saturation or
  /// braking): the observer is given that instead of the command (a wrong size or NaN/Inf there: the command).
  ControllerStatus update(double now, double stamp, const Eigen::Ref<const Eigen::VectorXd>& q,
                          const Eigen::Ref<const Eigen::VectorXd>& qd, const Eigen::Ref<const Eigen::VectorXd>& applied,
                          Eigen::Ref<Eigen::VectorXd> torque) noexcept;

  /// True (and the controller will hold at the next fresh state) if no state newer than now − timeout arrived.
  bool stale(double now) noexcept;
  /// What to send while the states cannot be used (stale, invalid, unread): the gravity torque at the last valid
  /// measured posture (within the torque limits), so that an arm without brakes does not fall. Returns false, with
  /// zero torque, before the first valid state (false and untouched for a wrongly sized `torque`). Real-time safe.
  bool holdingTorque(Eigen::Ref<Eigen::VectorXd> torque) noexcept;

  /// Switches mode at the next update (hold: a smooth stop from the desired state, or from the measured one after
  /// gravity compensation, ArmControllerConfig::stop_deceleration; track: the loaded trajectory, if any, else
  /// hold).
  void setMode(ControllerMode mode) noexcept;
  /// Validates waypoints (times relative to the stamp of the next update) and tracks them from the next update on,
  /// starting from the current desired state (no jump when replacing a running trajectory). Anything but Ok changes
  /// nothing.
  TrajectoryStatus setTrajectory(const Waypoints& waypoints) noexcept;
  /// The same with times that count from `offset` seconds after the next update's stamp (JointTrajectory::load).
  TrajectoryStatus setTrajectory(const Waypoints& waypoints, double offset) noexcept;
  /// The same, from the desired state (q, q̇, q̈) at the next update's stamp instead of the current one: for a
  /// reference generator that owns the desired state (TargetFollower), so that a late or missing state does not let
  /// the controller's own extrapolation drift from it and the segment's spline close the gap with an acceleration
  /// spike. WrongSize or NotFinite for a bad state; anything but Ok changes nothing.
  TrajectoryStatus setTrajectoryFrom(const Waypoints& waypoints, const Eigen::Ref<const Eigen::VectorXd>& q,
                                     const Eigen::Ref<const Eigen::VectorXd>& qd,
                                     const Eigen::Ref<const Eigen::VectorXd>& qdd) noexcept;

  ControllerMode mode() const noexcept { return mode_; }
  bool started() const noexcept { return started_; }
  /// Desired state and tracking error q_d − q of the last update.
  const Eigen::VectorXd& desiredPosition() const noexcept { return q_d_; }
  const Eigen::VectorXd& desiredVelocity() const noexcept { return qd_d_; }
  const Eigen::VectorXd& desiredAcceleration() const noexcept { return qdd_d_; }
  const Eigen::VectorXd& trackingError() const noexcept { return error_; }
  /// Estimated wrench [f; m] the environment exerts on the tool (base frame, at the tool origin).
  const Eigen::Matrix<double, 6, 1>& estimatedWrench() const noexcept { return observer_.wrench(); }
  const Eigen::VectorXd& estimatedExternalTorque() const noexcept { return observer_.externalTorque(); }
  /// Whether the running trajectory has ended (or there is none).
  bool trajectoryFinished(double now) const noexcept {
    return mode_ != ControllerMode::Track || trajectory_.finished(now);
  }
  /// Time of the running trajectory's last waypoint (stamp clock).
  double trajectoryEndTime() const noexcept { return trajectory_.endTime(); }
  /// Stamp of the last accepted state and the Δt before it (0 at a start) [s].
  double lastStamp() const noexcept { return last_stamp_; }
  double lastPeriod() const noexcept { return last_period_; }
  /// The disturbance observer (its counters of irregular steps and restarts).
  const DisturbanceObserver& observer() const noexcept { return observer_; }
  const kinematics::ChainModel& model() const noexcept { return ctc_.model(); }
  const ComputedTorqueGains& gains() const noexcept { return ctc_.gains(); }

 private:
  void holdAt(double t, const Eigen::Ref<const Eigen::VectorXd>& q) noexcept;
  /// Hold mode through a smooth stop from the desired state (q_d_, qd_d_, qdd_d_) at t.
  void stopAt(double t) noexcept;

  ComputedTorqueController ctc_;
  DisturbanceObserver observer_;
  JointTrajectory trajectory_;
  dynamics::DynamicsData dynamics_;
  Eigen::VectorXd velocity_limit_, torque_limit_;
  double timeout_, stop_deceleration_, min_stop_time_;
  ControllerMode mode_ = ControllerMode::Hold;
  ControllerMode requested_mode_ = ControllerMode::Hold;
  bool mode_request_ = false, trajectory_request_ = false, start_given_ = false;
  bool started_ = false, was_stale_ = false;
  double last_stamp_ = 0.0, last_period_ = 0.0;
  Eigen::VectorXd q_d_, qd_d_, qdd_d_, error_, applied_, accel_sign_, q_valid_, start_q_, start_qd_, start_qdd_;
};

}  // namespace bimanual_skills::control
