#include "bimanual_skills/control/realtime_arm_controller.hpp"
#include "bimanual_skills/realtime/clock.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <utility>

namespace bimanual_skills::control {

const char* toString(GoalState state) noexcept {
  switch (state) {
    case GoalState::None:
      return "none";
    case GoalState::Active:
      return "active";
    case GoalState::Succeeded:
      return "succeeded";
    case GoalState::Rejected:
      return "rejected";
    case GoalState::PathToleranceViolated:
      return "path tolerance violated";
    case GoalState::GoalToleranceViolated:
      return "goal tolerance violated";
    case GoalState::Aborted:
      return "aborted";
    case GoalState::Preempted:
      return "preempted";
  }
  return "unknown";
}

TrajectoryTolerances TrajectoryTolerances::none(int n) {
  TrajectoryTolerances t;
  t.path_position = t.path_velocity = t.goal_position = t.goal_velocity = Eigen::VectorXd::Zero(n);
  return t;
}

ArmControllerState::ArmControllerState(int n)
    : position(Eigen::VectorXd::Zero(n)),
      velocity(Eigen::VectorXd::Zero(n)),
      torque(Eigen::VectorXd::Zero(n)),
      desired_position(Eigen::VectorXd::Zero(n)),
      desired_velocity(Eigen::VectorXd::Zero(n)),
      desired_acceleration(Eigen::VectorXd::Zero(n)),
      position_error(Eigen::VectorXd::Zero(n)),
      velocity_error(Eigen::VectorXd::Zero(n)),
      external_torque(Eigen::VectorXd::Zero(n)) {}

namespace {

ControllerCommand initialCommand(int n) {
  ControllerCommand c;
  c.tolerances = TrajectoryTolerances::none(n);
  return c;
}

/// The first joint whose |error| exceeds a positive tolerance, −1 if none.
int violation(const Eigen::VectorXd& error, const Eigen::VectorXd& tolerance) noexcept {
  for (Eigen::Index i = 0; i < error.size(); ++i) {
    if (tolerance[i] > 0.0 && std::abs(error[i]) > tolerance[i]) return static_cast<int>(i);
  }
  return -1;
}

}  // namespace

RealtimeArmController::RealtimeArmController(const kinematics::ChainModel& model,
                                             const dynamics::FrictionModel& friction, ArmControllerConfig config)
    : controller_(model, friction, config),
      checker_(model.nq(), config.trajectory_capacity, model.lowerLimits(), model.upperLimits()),
      capacity_(config.trajectory_capacity),
      commands_(initialCommand(model.nq())),
      states_(ArmControllerState(model.nq())),
      tolerances_(TrajectoryTolerances::none(model.nq())),
      state_timeout_(config.state_timeout) {}

void RealtimeArmController::enableFollowing(const TargetFollowerConfig& config) {
  follower_ = std::make_unique<TargetFollower>(controller_.model(), config);
}

void RealtimeArmController::setTarget(const FollowTarget& target) noexcept {
  targets_.writeSlot() = target;
  targets_.publish();
}

void RealtimeArmController::command(ControllerCommand command) {
  const std::lock_guard<std::mutex> lock(command_mutex_);
  command.sent = realtime::monotonicSeconds();
  commands_.writeSlot() = std::move(command);
  commands_.publish();
}

TrajectoryStatus RealtimeArmController::validate(const Waypoints& waypoints) const noexcept {
  const std::lock_guard<std::mutex> lock(command_mutex_);
  return checker_.load(waypoints);
}

TrajectoryStatus RealtimeArmController::validate(const Waypoints& waypoints, double offset) const noexcept {
  const std::lock_guard<std::mutex> lock(command_mutex_);
  return checker_.load(waypoints, offset);
}

void RealtimeArmController::receive() noexcept {
  last_cycle_.store(realtime::monotonicSeconds(), std::memory_order_release);
  const ControllerCommand* command = commands_.readNew();
  if (!command) return;
  pending_ = command;  // a newer command replaces one still waiting for its start
  if (command->kind == ControllerCommand::Kind::Trajectory) {
    received_goal_.store(command->goal_id, std::memory_order_release);
  }
}

void RealtimeArmController::idle() noexcept {
  receive();
}

void RealtimeArmController::take(const ControllerCommand& command, double stamp) noexcept {
  ++commands_taken_;
  command_taken_at_ = realtime::monotonicSeconds();
  command_latency_ = command_taken_at_ - command.sent;
  if (goal_ == GoalState::Active && command.kind != ControllerCommand::Kind::Trajectory) goal_ = GoalState::Preempted;
  // Following ends with any command; a Follow command (re)starts it from the controller's desired state.
  following_ = command.kind == ControllerCommand::Kind::Follow && follower_ != nullptr;
  if (follower_) follower_->stop();
  if (following_) {
    follow_grasp_ = command.grasp;
    next_follow_ = -std::numeric_limits<double>::infinity();
    follow_interrupted_ = false;
    follow_stopped_ = ControllerStatus::Ok;
    grasp_answer_.store(-1, std::memory_order_relaxed);
  }
  if (command.kind == ControllerCommand::Kind::Follow) return;
  if (command.kind == ControllerCommand::Kind::Mode) {
    controller_.setMode(command.mode);
    return;
  }
  goal_id_ = command.goal_id;
  goal_joint_ = -1;
  goal_error_ = 0.0;
  abort_reason_ = ControllerStatus::Ok;
  abort_gap_ = 0.0;
  trajectory_start_ = stamp;
  rejection_ = std::isfinite(command.start) ? controller_.setTrajectory(command.waypoints, command.start - stamp)
                                            : controller_.setTrajectory(command.waypoints);
  const int n = joints();
  const TrajectoryTolerances& t = command.tolerances;
  const bool sized = t.path_position.size() == n && t.path_velocity.size() == n && t.goal_position.size() == n &&
                     t.goal_velocity.size() == n;
  if (rejection_ == TrajectoryStatus::Ok && !sized) rejection_ = TrajectoryStatus::WrongSize;
  if (rejection_ != TrajectoryStatus::Ok) {
    goal_ = GoalState::Rejected;
    return;
  }
  tolerances_.path_position = t.path_position;
  tolerances_.path_velocity = t.path_velocity;
  tolerances_.goal_position = t.goal_position;
  tolerances_.goal_velocity = t.goal_velocity;
  tolerances_.goal_time = t.goal_time;
  goal_ = GoalState::Active;
}

void RealtimeArmController::monitorGoal(double stamp, ControllerStatus status) noexcept {
  if (goal_ != GoalState::Active) return;
  if (controller_.mode() != ControllerMode::Track) {
    // Restarted, stale, velocity limit or a trajectory dropped at a restart: the controller holds on its own.
    goal_ = GoalState::Aborted;
    abort_reason_ = status;
    abort_gap_ = status == ControllerStatus::VelocityLimit && stamp - gap_end_ <= kGapWindow ? gap_ : 0.0;
    return;
  }
  const ArmControllerState& s = states_.writeSlot();
  const bool running = !controller_.trajectoryFinished(stamp);
  const Eigen::VectorXd& velocity = running ? s.velocity_error : s.velocity;
  int joint = violation(s.position_error, running ? tolerances_.path_position : tolerances_.goal_position);
  goal_error_is_velocity_ = joint < 0;
  if (joint < 0) joint = violation(velocity, running ? tolerances_.path_velocity : tolerances_.goal_velocity);
  if (running && joint >= 0) {
    goal_ = GoalState::PathToleranceViolated;
    controller_.setMode(ControllerMode::Hold);
  } else if (!running && joint < 0) {
    goal_ = GoalState::Succeeded;
  } else if (!running && stamp > controller_.trajectoryEndTime() + tolerances_.goal_time) {
    goal_ = GoalState::GoalToleranceViolated;
  } else {
    return;
  }
  goal_joint_ = joint;
  if (joint >= 0) goal_error_ = goal_error_is_velocity_ ? velocity[joint] : s.position_error[joint];
}

void RealtimeArmController::follow(double stamp, const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  if (const FollowTarget* newest = targets_.readNew()) target_ = *newest;
  if (!controller_.started()) return;  // the first state starts the controller; the follower starts from it
  if (follower_->phase() == FollowPhase::Idle) {
    follower_->start(stamp, controller_.desiredPosition(), controller_.desiredVelocity(), follow_grasp_);
  }
  const int answer = grasp_answer_.exchange(-1, std::memory_order_acq_rel);
  if (answer >= 0) follower_->graspDone(answer == 1);
  const double period = follower_->config().period;
  if (stamp < next_follow_ - 1e-9 && stamp > next_follow_ - 2.0 * period) return;  // not due (a clock back: due)
  next_follow_ = stamp + period;
  if (!follower_->update(stamp, target_, q)) return;
  // From the follower's reference itself (its acceleration-limited state), not from the controller's desired state:
  // after a late or missing state the two differ, and a segment joining them within five periods asked tens of
  // rad/s² (a velocity-limit trip on hardware:=true).
  (void)controller_.setTrajectoryFrom(follower_->waypoints(), follower_->reference(), follower_->segmentVelocity(),
                                      follower_->segmentAcceleration());
  const double used = follower_->targetStamp();
  if (std::isfinite(used) && !(used == used_target_stamp_)) {
    used_target_stamp_ = used;
    follow_latency_ = stamp - used;  // this cycle's torque is the first computed from that estimate
  }
}

void RealtimeArmController::publishState(double stamp, ControllerStatus status,
                                         const Eigen::Ref<const Eigen::VectorXd>& q,
                                         const Eigen::Ref<const Eigen::VectorXd>& qd,
                                         const Eigen::Ref<const Eigen::VectorXd>& torque) noexcept {
  ArmControllerState& s = states_.writeSlot();
  s.sequence = ++sequence_;
  s.stamp = stamp;
  s.period = controller_.lastPeriod();
  s.mode = controller_.mode();
  s.status = status;
  s.position = q;
  s.velocity = qd;
  s.torque = torque;
  s.desired_position = controller_.desiredPosition();
  s.desired_velocity = controller_.desiredVelocity();
  s.desired_acceleration = controller_.desiredAcceleration();
  s.position_error = controller_.trackingError();
  s.velocity_error = s.desired_velocity - qd;
  s.wrench = controller_.estimatedWrench();
  s.external_torque = controller_.estimatedExternalTorque();
  monitorGoal(stamp, status);
  s.mode = controller_.mode();
  s.goal_id = goal_id_;
  s.goal = goal_;
  s.trajectory_start = trajectory_start_;
  s.goal_joint = goal_joint_;
  s.goal_error = goal_error_;
  s.goal_error_is_velocity = goal_error_is_velocity_;
  s.rejection = rejection_;
  s.abort_reason = abort_reason_;
  s.abort_gap = abort_gap_;
  for (int k = 0; k < 5; ++k) s.status_counts[k] = counts_[k];
  s.observer_irregular_steps = controller_.observer().irregularSteps();
  s.observer_restarts = controller_.observer().restarts();
  s.commands_taken = commands_taken_;
  s.command_latency = command_latency_;
  s.following = following_;
  s.follow_interrupted = follow_interrupted_;
  s.follow_stopped = follow_stopped_;
  if (follower_) {
    s.follow_phase = follower_->phase();
    s.follow_reason = follower_->holdReason();
    s.follow_goal = follower_->toolGoal();
    s.follow_tool = follower_->toolPosition();
    s.follow_error = follower_->toolError();
    s.follow_offset = follower_->offset();
    s.follow_target_stamp = used_target_stamp_;
    s.follow_latency = follow_latency_;
    s.grasp_requested = following_ && follower_->graspRequested();
  }
  states_.publish();
}

ControllerStatus RealtimeArmController::update(double now, double stamp, const Eigen::Ref<const Eigen::VectorXd>& q,
                                               const Eigen::Ref<const Eigen::VectorXd>& qd,
                                               const Eigen::Ref<const Eigen::VectorXd>& applied,
                                               Eigen::Ref<Eigen::VectorXd> torque) noexcept {
  receive();
  // A clock that went back (a simulation reset) drops a command waiting for a start on the old clock.
  if (pending_ && stamp < last_update_stamp_ && pending_->kind == ControllerCommand::Kind::Trajectory &&
      pending_->start > stamp) {
    goal_id_ = pending_->goal_id;  // its goal ends: the controller restarts
    goal_ = GoalState::Aborted;
    abort_reason_ = ControllerStatus::StaleState;
    trajectory_start_ = std::numeric_limits<double>::quiet_NaN();
    pending_ = nullptr;
  }
  if (stamp - last_update_stamp_ > state_timeout_ && stamp > last_update_stamp_ && std::isfinite(last_update_stamp_)) {
    gap_ = stamp - last_update_stamp_;
    gap_end_ = stamp;
  }
  last_update_stamp_ = stamp;
  if (pending_ && !(pending_->kind == ControllerCommand::Kind::Trajectory && pending_->start > stamp)) {
    take(*pending_, stamp);
    pending_ = nullptr;
  }
  if (following_) follow(stamp, q);
  const ControllerStatus status = controller_.update(now, stamp, q, qd, applied, torque);
  ++counts_[static_cast<int>(status)];
  if (following_ && follower_->phase() != FollowPhase::Idle && controller_.mode() != ControllerMode::Track) {
    // The controller left tracking on its own (velocity limit, stale or restarted states): following ends.
    following_ = false;
    follower_->stop();
    follow_interrupted_ = true;
    // A restart after stale states (the loop or the link stopped a while) is said as such, not as a clock gone back.
    follow_stopped_ = (status == ControllerStatus::Ok || status == ControllerStatus::Saturated) &&
                              previous_status_ == ControllerStatus::StaleState
                          ? ControllerStatus::StaleState
                          : status;
  }
  previous_status_ = status;
  if (status == ControllerStatus::StaleState) {  // a state older than the timeout: a gap of that age at least
    const double age = std::isfinite(now - stamp) ? now - stamp : 0.0;
    gap_ = stamp - gap_end_ <= kGapWindow ? std::max(gap_, age) : age;
    gap_end_ = stamp;
  }
  if (status == ControllerStatus::InvalidState || status == ControllerStatus::StaleState) {
    if (goal_ == GoalState::Active && status == ControllerStatus::StaleState) {
      goal_ = GoalState::Aborted;
      abort_reason_ = status;
    }
    return status;
  }
  publishState(stamp, status, q, qd, torque);
  return status;
}

}  // namespace bimanual_skills::control
