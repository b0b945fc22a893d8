/// \file
/// An ArmController driven by a real-time loop and commanded from other threads (ros_control's split without
/// ros_control): commands (a trajectory with its goal's tolerances, or a mode) come in through a lock-free
/// latest-wins mailbox, and after every update the loop hands out a snapshot of the controller's state through
/// another. The loop thread never waits for a command, a publisher or a lock; the other threads never touch the
/// controller. The goal of the running trajectory is monitored in the loop as control_msgs' FollowJointTrajectory
/// defines it: path tolerances while it runs, goal tolerances at its end, within a goal time tolerance. A trajectory
/// starts at its own time (control_msgs' header.stamp): one whose start lies ahead waits in the loop, the running
/// motion going on, until the first update at or after it (two arms given the same start begin in the same cycle);
/// one whose start lies behind is sampled from where it has got to by then.
#pragma once

#include "bimanual_skills/control/arm_controller.hpp"
#include "bimanual_skills/control/target_follower.hpp"
#include "bimanual_skills/realtime/triple_buffer.hpp"

#include <atomic>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>

namespace bimanual_skills::control {

/// Tolerances of one trajectory goal [rad, rad/s] per joint; a value ≤ 0 is not checked.
struct TrajectoryTolerances {
  Eigen::VectorXd path_position, path_velocity;  ///< |q_d − q|, |q̇_d − q̇| while the trajectory runs.
  Eigen::VectorXd goal_position, goal_velocity;  ///< The same at its end (goal_velocity: how still the arm must be).
  double goal_time = 0.0;  ///< [s] after the last waypoint's time in which the goal tolerances must be met.

  /// Every tolerance unchecked, for n joints.
  static TrajectoryTolerances none(int n);
};

/// Where the goal of the last trajectory stands.
enum class GoalState {
  None,                   ///< No goal yet.
  Active,                 ///< Running, or past its end and waiting for the goal tolerances.
  Succeeded,              ///< Ended within the goal tolerances.
  Rejected,               ///< The controller refused the waypoints (see ArmControllerState::rejection).
  PathToleranceViolated,  ///< A joint left its path tolerance: the arm holds where it is.
  GoalToleranceViolated,  ///< Not within the goal tolerances goal_time after the end: the arm holds the end point.
  Aborted,                ///< The controller left tracking on its own (velocity limit, stale or restarted states).
  Preempted,              ///< A mode command replaced it.
};
const char* toString(GoalState state) noexcept;

/// A command handed to the loop.
struct ControllerCommand {
  /// Follow: the tool follows the tracked target (RealtimeArmController::enableFollowing) until another command.
  enum class Kind { Mode, Trajectory, Follow };
  Kind kind = Kind::Mode;
  ControllerMode mode = ControllerMode::Hold;  ///< Kind::Mode.
  Waypoints waypoints;                         ///< Kind::Trajectory: times relative to `start` (>= 0, increasing).
  /// Kind::Trajectory: the stamp its waypoints' times count from [s, the states' clock]; the loop holds the command
  /// until its first update at or after it. NaN: the stamp of the update that takes it (times then > 0).
  double start = std::numeric_limits<double>::quiet_NaN();
  TrajectoryTolerances tolerances;  ///< Kind::Trajectory.
  std::uint64_t goal_id = 0;        ///< Kind::Trajectory: reported back in ArmControllerState.
  bool grasp = false;               ///< Kind::Follow: approach and grasp when the follower can (else follow only).
  double sent = 0.0;                ///< Monotonic wall clock [s] when it was handed over (set by command()).
};

/// The controller after one update, as the loop hands it out.
struct ArmControllerState {
  explicit ArmControllerState(int n = 0);

  std::uint64_t sequence = 0;  ///< Updates that produced a torque so far.
  double stamp = 0.0;          ///< Of the state it was computed from [s].
  double period = 0.0;         ///< Δt to the previous state's stamp [s] (0 at a start).
  ControllerMode mode = ControllerMode::Hold;
  ControllerStatus status = ControllerStatus::Ok;
  Eigen::VectorXd position, velocity, torque;  ///< Measured q, q̇; commanded torque [N m].
  Eigen::VectorXd desired_position, desired_velocity, desired_acceleration;
  Eigen::VectorXd position_error, velocity_error;                            ///< q_d − q, q̇_d − q̇.
  Eigen::Matrix<double, 6, 1> wrench = Eigen::Matrix<double, 6, 1>::Zero();  ///< Estimated tool wrench, base frame.
  Eigen::VectorXd external_torque;  ///< The observer's estimated external joint torques τ̂_ext [N m].
  std::uint64_t goal_id = 0;
  GoalState goal = GoalState::None;
  /// Stamp of the update that started goal_id's trajectory [s] (NaN before it started).
  double trajectory_start = std::numeric_limits<double>::quiet_NaN();
  int goal_joint = -1;      ///< The joint that violated a tolerance.
  double goal_error = 0.0;  ///< Its error then [rad, or rad/s when goal_error_is_velocity].
  bool goal_error_is_velocity = false;
  TrajectoryStatus rejection = TrajectoryStatus::Ok;     ///< Why a trajectory was Rejected.
  ControllerStatus abort_reason = ControllerStatus::Ok;  ///< Why a goal was Aborted.
  /// A goal Aborted at the velocity limit within kGapWindow of a gap in the states longer than the state timeout
  /// (the robot ran without this controller's torques meanwhile): that gap [s]; 0 for none.
  double abort_gap = 0.0;
  long status_counts[5] = {0, 0, 0, 0, 0};  ///< Updates per ControllerStatus value.
  long observer_irregular_steps = 0, observer_restarts = 0;
  std::uint64_t commands_taken = 0;  ///< Commands the loop took so far.
  double command_latency = 0.0;      ///< Wall time [s] from the last command's hand-over to its first torque.
  // Following a tracked target (ControllerCommand::Kind::Follow).
  bool following = false;
  FollowPhase follow_phase = FollowPhase::Idle;
  HoldReason follow_reason = HoldReason::None;
  Eigen::Vector3d follow_goal = Eigen::Vector3d::Zero();  ///< The tool's goal (world) [m].
  Eigen::Vector3d follow_tool = Eigen::Vector3d::Zero();  ///< The measured tool (world) [m].
  double follow_error = 0.0;                              ///< Their distance [m].
  double follow_offset = 1.0;  ///< The share of the pre-grasp offset in the goal (1 following, 0 at the grasp).
  /// The stamp of the target's estimate in use, and its age at the first torque computed from it [s] (NaN: none).
  double follow_target_stamp = std::numeric_limits<double>::quiet_NaN();
  double follow_latency = std::numeric_limits<double>::quiet_NaN();
  bool grasp_requested = false;  ///< The follower asks for the gripper to close (answer: graspDone()).
  /// Following ended without a command: the controller left tracking on its own, with the status of that update
  /// (VelocityLimit; StaleState, also when it restarted after stale states; Ok or Saturated: it restarted, the clock
  /// went back).
  bool follow_interrupted = false;
  ControllerStatus follow_stopped = ControllerStatus::Ok;
};

/// One arm's controller between a real-time loop and the threads that command and watch it. Construction
/// allocates and throws like ArmController's. update() is real-time safe (no allocation, locks, exceptions or
/// logging) and must be called from one thread; command() may be called from any other threads; latestState()
/// from one reader thread.
class RealtimeArmController {
 public:
  /// How long after a gap in the states a velocity-limit stop is put down to it [s]: the robot's own hold or brake
  /// over the gap, then the law catching up.
  static constexpr double kGapWindow = 0.5;

  RealtimeArmController(const kinematics::ChainModel& model, const dynamics::FrictionModel& friction,
                        ArmControllerConfig config);

  // ---- Non-real-time side ----
  /// Hands a command to the loop, replacing one it has not taken yet (latest wins); stamps its `sent` time. Its
  /// waypoints are validated
  /// by the loop; validate them with validate() first to answer a caller at once. Thread-safe among writers.
  void command(ControllerCommand command);
  /// Checks waypoints as the loop's controller will (sizes, capacity, NaN/Inf, times, joint limits), without
  /// touching it. Thread-safe.
  TrajectoryStatus validate(const Waypoints& waypoints) const noexcept;
  /// The same for waypoints with a start `offset` seconds from now (JointTrajectory::load's offset).
  TrajectoryStatus validate(const Waypoints& waypoints, double offset) const noexcept;
  /// The goal_id of the last trajectory the loop received (taken, or waiting for its start): a command handed over.
  /// Thread-safe.
  std::uint64_t receivedGoal() const noexcept { return received_goal_.load(std::memory_order_acquire); }
  /// Monotonic wall clock [s] of the loop's last update() or idle() (0 before any): whether the loop still runs.
  /// Thread-safe.
  double lastCycle() const noexcept { return last_cycle_.load(std::memory_order_acquire); }
  /// The newest state if the loop produced one since the last call, else nullptr; valid until the next call.
  /// One reader thread.
  const ArmControllerState* latestState() noexcept { return states_.readNew(); }
  /// The loop thread's view of the controller: the last update's desired state, its gains and mode (what a robot
  /// that closes the joint impedance itself needs: ctc_controller ~local_impedance).
  const ArmController& controller() const noexcept { return controller_; }
  /// Makes the arm able to follow a tracked target (ControllerCommand::Kind::Follow): a TargetFollower run in the
  /// loop every config.period of the states' clock, its segments given to the controller in the same cycle. Call
  /// before the loop runs (allocates). \throws std::invalid_argument for an invalid config.
  void enableFollowing(const TargetFollowerConfig& config);
  bool canFollow() const noexcept { return follower_ != nullptr; }
  /// The newest estimate of the target (one writer thread).
  void setTarget(const FollowTarget& target) noexcept;
  /// The gripper's answer to ArmControllerState::grasp_requested (any thread).
  void graspDone(bool held) noexcept { grasp_answer_.store(held ? 1 : 0, std::memory_order_release); }

  // ---- Real-time side ----
  /// One control step (ArmController::update with the robot's applied torque) after taking the newest command,
  /// then the goal's tolerances are checked and the state is handed out. Real-time safe.
  ControllerStatus update(double now, double stamp, const Eigen::Ref<const Eigen::VectorXd>& q,
                          const Eigen::Ref<const Eigen::VectorXd>& qd, const Eigen::Ref<const Eigen::VectorXd>& applied,
                          Eigen::Ref<Eigen::VectorXd> torque) noexcept;
  /// For a loop that stands still on purpose (a paused simulation): receives the newest command without acting on
  /// it (update() does, at its time) and tells the other threads the loop is alive. Real-time safe.
  void idle() noexcept;
  /// Loop side: commands taken so far, and when the last one was (monotonic wall clock [s], just before its first
  /// torque), for the loop's own statistics.
  std::uint64_t commandsTaken() const noexcept { return commands_taken_; }
  double lastCommandTaken() const noexcept { return command_taken_at_; }
  /// Whether the states stopped (ArmController::stale); call from the loop thread.
  bool stale(double now) noexcept { return controller_.stale(now); }
  /// ArmController::holdingTorque: the gravity torque at the last valid posture, for a loop whose states cannot be
  /// used (loop thread).
  bool holdingTorque(Eigen::Ref<Eigen::VectorXd> torque) noexcept { return controller_.holdingTorque(torque); }

  const kinematics::ChainModel& model() const noexcept { return controller_.model(); }
  int joints() const noexcept { return controller_.model().nq(); }
  int trajectoryCapacity() const noexcept { return capacity_; }

 private:
  void receive() noexcept;
  void take(const ControllerCommand& command, double stamp) noexcept;
  void monitorGoal(double stamp, ControllerStatus status) noexcept;
  /// Following: the follower's update when due, its segment to the controller.
  void follow(double stamp, const Eigen::Ref<const Eigen::VectorXd>& q) noexcept;
  void publishState(double stamp, ControllerStatus status, const Eigen::Ref<const Eigen::VectorXd>& q,
                    const Eigen::Ref<const Eigen::VectorXd>& qd,
                    const Eigen::Ref<const Eigen::VectorXd>& torque) noexcept;

  ArmController controller_;
  mutable JointTrajectory checker_;  ///< Validates waypoints off the loop (guarded by command_mutex_).
  int capacity_;
  mutable std::mutex command_mutex_;  ///< Serialises the writers and the checker; never taken by the loop.
  realtime::TripleBuffer<ControllerCommand> commands_;
  realtime::TripleBuffer<ArmControllerState> states_;
  // Loop-side goal bookkeeping.
  TrajectoryTolerances tolerances_;
  std::uint64_t goal_id_ = 0, sequence_ = 0;
  GoalState goal_ = GoalState::None;
  int goal_joint_ = -1;
  double goal_error_ = 0.0;
  bool goal_error_is_velocity_ = false;
  TrajectoryStatus rejection_ = TrajectoryStatus::Ok;
  ControllerStatus abort_reason_ = ControllerStatus::Ok;
  double abort_gap_ = 0.0;
  /// The states' last gap longer than the state timeout (or a stale state), and the stamp that ended it.
  double state_timeout_, gap_ = 0.0, gap_end_ = -std::numeric_limits<double>::infinity();
  long counts_[5] = {0, 0, 0, 0, 0};
  std::uint64_t commands_taken_ = 0;
  double command_latency_ = 0.0, command_taken_at_ = 0.0;
  /// The command received and not yet taken (the reader's slot of commands_, valid until the next readNew()).
  const ControllerCommand* pending_ = nullptr;
  double last_update_stamp_ = -std::numeric_limits<double>::infinity();
  double trajectory_start_ = std::numeric_limits<double>::quiet_NaN();
  std::atomic<std::uint64_t> received_goal_{0};
  std::atomic<double> last_cycle_{0.0};
  // Following (loop side, but for the target's and the gripper's handoffs).
  std::unique_ptr<TargetFollower> follower_;
  realtime::TripleBuffer<FollowTarget> targets_{FollowTarget{}};
  FollowTarget target_;
  bool following_ = false;
  double next_follow_ = -std::numeric_limits<double>::infinity();
  bool follow_grasp_ = false;
  double used_target_stamp_ = std::numeric_limits<double>::quiet_NaN();
  double follow_latency_ = std::numeric_limits<double>::quiet_NaN();
  bool follow_interrupted_ = false;
  ControllerStatus follow_stopped_ = ControllerStatus::Ok;
  ControllerStatus previous_status_ = ControllerStatus::Ok;  ///< The last update's.
  std::atomic<int> grasp_answer_{-1};                        ///< −1 none, 0 not held, 1 held.
};

}  // namespace bimanual_skills::control
