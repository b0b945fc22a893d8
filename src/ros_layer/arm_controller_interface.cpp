#include "bimanual_skills/ros_layer/arm_controller_interface.hpp"

#include "bimanual_skills/ClothGrasp.h"
#include "bimanual_skills/FollowerState.h"
#include "bimanual_skills/JointTrajectoryControllerState.h"
#include "bimanual_skills/dynamics/friction_yaml.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/ros_layer/bounded_call.hpp"
#include "bimanual_skills/ros_layer/trajectory_messages.hpp"

#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/WrenchStamped.h>
#include <sensor_msgs/JointState.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <limits>
#include <sstream>
#include <thread>

namespace bimanual_skills::ros_layer {

namespace bc = bimanual_skills::control;
using Result = bimanual_skills::FollowJointTrajectoryResult;

const char* const kControllerParameterHelp =
    "  base_link, tip_link   the arm's chain in robot_description (default: the robot file's)\n"
    "  kp, kv                PD gains per joint [N m/rad, N m s/rad] (default: the robot file's, else 50, 5)\n"
    "  torque_limit, velocity_limit  per joint (default: the URDF's limits)\n"
    "  friction_file         friction model YAML (fit_friction's output; default: the robot file's); empty: no\n"
    "                        friction compensation\n"
    "  observer/{k11,k12,k21,k22,sigma}  disturbance observer gains (diagonal; thesis eq. 4.14)\n"
    "  observer/{rate,fir_taps,fir_cutoff}  its nominal rate [Hz] and velocity FIR (the robot's rate may differ:\n"
    "                        the observer integrates the measured dt; a mismatch is warned about)\n"
    "  state_timeout         joint states older than this [s] are stale: no torque, hold on recovery (0.05)\n"
    "  initial_mode          gravity_compensation | hold | follow | grasp (default hold; follow, grasp: as set_mode)\n"
    "  publish_rate          state, estimated_wrench, estimated_external_torque and action feedback rate [Hz]\n"
    "                        (default 100)\n"
    "  trajectory_capacity   most points of one trajectory (default 2000)\n"
    "  stop_deceleration, min_stop_time  a cancel, a path violation or a hold stops the arm over\n"
    "                        max(min_stop_time, 2 max|qd| / stop_deceleration) [rad/s^2, s] (5, 0.05)\n"
    "  path_tolerance, goal_tolerance  default position tolerances per joint [rad] (0: unchecked; 0, 0.05)\n"
    "  stopped_velocity_tolerance  default goal velocity tolerance [rad/s] (0.05)\n"
    "  goal_time_tolerance   default time after a trajectory's end to meet the goal tolerances [s] (1.0)\n"
    "  loop_timeout          an active goal is aborted when the loop has computed no torque for this long of the\n"
    "                        robot's clock [s] (0.5; a paused simulation's clock stands still: no abort)\n"
    "  follow/target_topic   bimanual_skills/TrackedObject to follow on set_mode follow (default\n"
    "                        /object_tracker/object; empty: no following), in the robot description's root frame\n"
    "  follow/gripper_service  bimanual_skills/ClothGrasp that closes the gripper (default /bullet_sim/grasp)\n"
    "  follow/pregrasp, follow/grasp_offset  grasp point -> where the tool follows, object centre -> grasp point,\n"
    "                        world axes [m] ([0, 0, 0.1], [0, 0, 0])\n"
    "  follow/tool_rpy       the tool's orientation while following, roll pitch yaw in the world [rad] ([pi, 0, 0]:\n"
    "                        pointing down)\n"
    "  follow/keep_yaw       true: the tool keeps the yaw it has when following starts, tilted as tool_rpy says (a\n"
    "                        round object's yaw is free); false: tool_rpy's yaw (true)\n"
    "  follow/rate           follower updates per second of the robot's clock (125)\n"
    "  follow/time_constant, follow/velocity_limit, follow/acceleration_limit  the reference's pull [s] (0.1) and\n"
    "                        limits per joint [rad/s, rad/s^2] (half the URDF's velocity limits, 4)\n"
    "  follow/max_age, follow/jump, follow/settle  hold on an estimate older than max_age [s] (0.25), or one jump\n"
    "                        [m] (0.05) from where the last predicted it, for settle [s] (0.5)\n"
    "  follow/track_time, follow/grasp_speed, follow/follow_tolerance  approach once followed this long [s] (2),\n"
    "                        the object slower than grasp_speed [m/s] (0.03), the tool this near [m] (0.02)\n"
    "  follow/speed_time_constant, follow/position_time_constant  low-pass filters [s] (0.3, 0.1) on the measured\n"
    "                        estimates: the approach's speed, and its grasp point (held where last measured)\n"
    "  follow/approach_speed, follow/grasp_tolerance  [m/s] (0.1); close within this of the grasp point [m] (0.01)\n"
    "  follow/clik_iterations  CLIK steps per update (3)\n";

namespace {

Eigen::VectorXd vector(const std::vector<double>& v) {
  return Eigen::Map<const Eigen::VectorXd>(v.data(), static_cast<Eigen::Index>(v.size()));
}

std::vector<double> stdVector(const Eigen::VectorXd& v) {
  return std::vector<double>(v.data(), v.data() + v.size());
}

void assign(std::vector<double>& out, const Eigen::VectorXd& v) {
  out.assign(v.data(), v.data() + v.size());
}

/// Where a trajectory's start lies from now [s] (0 for a zero stamp: it starts when the loop takes it).
double offsetOf(const ros::Time& start, const ros::Time& now) {
  return start.isZero() ? 0.0 : (start - now).toSec();
}

}  // namespace

ControllerSettings readControllerSettings(ParameterReader& p, const std::string& arm,
                                          const std::string& robot_description, const ControllerDefaults& defaults) {
  ControllerSettings s;
  const auto link = [&](const char* key, const std::string& robot) {
    const std::string value = p.text(key, robot);
    if (value.empty()) {
      throw std::invalid_argument("parameter " + p.name(key) + " is not set and no robot file gives " + arm + "'s " +
                                  key);
    }
    return value;
  };
  s.base_link = link("base_link", defaults.base_link);
  s.tip_link = link("tip_link", defaults.tip_link);
  try {
    s.model = std::make_shared<const kinematics::ChainModel>(
        kinematics::ChainModel::fromUrdfString(robot_description, s.base_link, s.tip_link));
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("the chain " + s.base_link + " -> " + s.tip_link + " (parameters " +
                                p.name("base_link") + ", " + p.name("tip_link") + "): " + e.what());
  }
  const kinematics::ChainModel& model = *s.model;
  const auto n = static_cast<std::size_t>(model.nq());
  bc::ArmControllerConfig& c = s.config;
  const auto gains = [n](const Eigen::VectorXd& robot, double otherwise) {
    return static_cast<std::size_t>(robot.size()) == n ? stdVector(robot) : std::vector<double>(n, otherwise);
  };
  c.gains.kp = vector(p.numbers("kp", gains(defaults.kp, 50.0), n, 0.0, 1e5));
  c.gains.kv = vector(p.numbers("kv", gains(defaults.kv, 5.0), n, 0.0, 1e4));
  c.gains.torque_limit = vector(p.numbers("torque_limit", stdVector(model.effortLimits()), n, 1e-6, 1e4));
  c.velocity_limit = vector(p.numbers("velocity_limit", stdVector(model.velocityLimits()), n, 1e-6, 100.0));
  c.state_timeout = p.number("state_timeout", 0.05, 1e-3, 10.0);
  c.trajectory_capacity = p.integer("trajectory_capacity", 2000, 2, 100000);
  c.stop_deceleration = p.number("stop_deceleration", 5.0, 1e-3, 1e4);
  c.min_stop_time = p.number("min_stop_time", 0.05, 1e-3, 10.0);
  s.friction_file = p.text("friction_file", defaults.friction_file);
  if (s.friction_file.empty()) {
    s.friction.joints.assign(n, dynamics::JointFriction{});
    c.friction_compensation = false;
  } else {
    try {
      s.friction = dynamics::loadFrictionModel(s.friction_file);
    } catch (const std::exception& e) {
      throw std::invalid_argument("parameter " + p.name("friction_file") + ": " + e.what());
    }
  }
  c.observer =
      bc::ObserverGains::diagonal(static_cast<int>(n), p.number("observer/k11", 10.0, 0.0, 1e4),
                                  p.number("observer/k12", 0.0, -1e4, 1e4), p.number("observer/k21", 100.0, 0.0, 1e6),
                                  p.number("observer/k22", 0.0, -1e4, 1e4), p.number("observer/sigma", 10.0, 0.0, 1e4));
  c.observer.rate_hz = p.number("observer/rate", 1000.0, 1.0, 1e5);
  c.observer.fir_taps = p.integer("observer/fir_taps", 15, 3, 1001);
  c.observer.fir_cutoff_hz = p.number("observer/fir_cutoff", 40.0, 1e-3, 0.5 * c.observer.rate_hz - 1e-9);
  if (c.observer.fir_taps % 2 == 0) {
    throw std::invalid_argument("parameter " + p.name("observer/fir_taps") + " must be odd");
  }
  const std::string mode = p.text("initial_mode", "hold", {"gravity_compensation", "hold", "follow", "grasp"});
  s.start_following = mode == "follow" || mode == "grasp";
  s.start_grasping = mode == "grasp";
  if (!s.start_following) bc::modeFromString(mode.c_str(), s.initial_mode);
  s.publish_rate = p.number("publish_rate", 100.0, 0.1, 1000.0);
  bc::TrajectoryTolerances& t = s.default_tolerances;
  t = bc::TrajectoryTolerances::none(static_cast<int>(n));
  t.path_position = vector(p.numbers("path_tolerance", std::vector<double>(n, 0.0), n, 0.0, 10.0));
  t.goal_position = vector(p.numbers("goal_tolerance", std::vector<double>(n, 0.05), n, 0.0, 10.0));
  t.goal_velocity =
      Eigen::VectorXd::Constant(static_cast<Eigen::Index>(n), p.number("stopped_velocity_tolerance", 0.05, 0.0, 100.0));
  t.goal_time = p.number("goal_time_tolerance", 1.0, 0.0, 3600.0);
  s.loop_timeout = p.number("loop_timeout", 0.5, 1e-3, 3600.0);
  const bool topic_given = p.has("follow/target_topic");
  s.target_topic = p.text("follow/target_topic", "/object_tracker/object");
  s.gripper_service = p.text("follow/gripper_service", "/bullet_sim/grasp");
  if (!s.target_topic.empty()) {
    try {
      const kinematics::FixedLinkPose base = kinematics::fixedLinkPose(robot_description, s.base_link);
      s.follow.base = base.pose;
      s.world_frame = base.root;
    } catch (const std::invalid_argument& e) {
      const std::string why = "following (parameter " + p.name("follow/target_topic") + "): " + e.what();
      if (topic_given || s.start_following) throw std::invalid_argument(why + "; set it empty to follow nothing");
      ROS_WARN("%s; this arm cannot follow a tracked object", why.c_str());
      s.target_topic.clear();
    }
  }
  if (s.start_following && s.target_topic.empty()) {
    throw std::invalid_argument("parameter " + p.name("initial_mode") + " is " + mode + ", and " +
                                p.name("follow/target_topic") + " is empty: there is nothing to follow");
  }
  if (!s.target_topic.empty()) {
    bc::TargetFollowerConfig& f = s.follow;
    const auto point = [&](const char* key, const Eigen::Vector3d& fallback) {
      return Eigen::Vector3d(vector(p.numbers(key, stdVector(fallback), 3, -1.0, 1.0)));
    };
    f.pregrasp = point("follow/pregrasp", f.pregrasp);
    f.grasp_offset = point("follow/grasp_offset", f.grasp_offset);
    const std::vector<double> rpy = p.numbers("follow/tool_rpy", {M_PI, 0.0, 0.0}, 3, -10.0, 10.0);
    f.tool_orientation =
        (Eigen::AngleAxisd(rpy[2], Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(rpy[1], Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(rpy[0], Eigen::Vector3d::UnitX()))
            .toRotationMatrix();
    f.keep_yaw = p.boolean("follow/keep_yaw", true);
    f.period = 1.0 / p.number("follow/rate", 125.0, 1.0, 1000.0);
    f.time_constant = p.number("follow/time_constant", f.time_constant, 1e-3, 10.0);
    f.velocity_limit =
        vector(p.numbers("follow/velocity_limit", stdVector(0.5 * model.velocityLimits()), n, 1e-3, 100.0));
    f.acceleration_limit = vector(p.numbers("follow/acceleration_limit", std::vector<double>(n, 4.0), n, 1e-3, 1e4));
    f.max_age = p.number("follow/max_age", f.max_age, 1e-3, 60.0);
    f.jump = p.number("follow/jump", f.jump, 1e-3, 10.0);
    f.settle = p.number("follow/settle", f.settle, 0.0, 60.0);
    f.track_time = p.number("follow/track_time", f.track_time, 0.0, 3600.0);
    f.grasp_speed = p.number("follow/grasp_speed", f.grasp_speed, 1e-4, 10.0);
    f.speed_time_constant = p.number("follow/speed_time_constant", f.speed_time_constant, 1e-3, 10.0);
    f.position_time_constant = p.number("follow/position_time_constant", f.position_time_constant, 1e-3, 10.0);
    f.follow_tolerance = p.number("follow/follow_tolerance", f.follow_tolerance, 1e-4, 1.0);
    f.approach_speed = p.number("follow/approach_speed", f.approach_speed, 1e-4, 10.0);
    f.grasp_tolerance = p.number("follow/grasp_tolerance", f.grasp_tolerance, 1e-4, 1.0);
    f.clik_iterations = p.integer("follow/clik_iterations", f.clik_iterations, 1, 100);
    try {
      f.validate(model.nq());
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string("parameters ") + p.name("follow/...") + ": " + e.what());
    }
  }
  return s;
}

ArmControllerInterface::ArmControllerInterface(ros::NodeHandle node, ParameterReader& parameters,
                                               const std::string& arm, const std::string& robot_description,
                                               const std::string& owner, const ControllerDefaults& defaults)
    : arm_(arm), owner_(owner), node_(node), gripper_(node) {
  settings_ = readControllerSettings(parameters, arm, robot_description, defaults);
  controller_ = std::make_unique<bc::RealtimeArmController>(*settings_.model, settings_.friction, settings_.config);
  if (!settings_.target_topic.empty()) controller_->enableFollowing(settings_.follow);
  joint_names_ = settings_.model->jointNames();
  kinematics_ = std::make_unique<kinematics::ChainData>(*settings_.model);
  if (settings_.start_following) {
    bc::ControllerCommand follow;
    follow.kind = bc::ControllerCommand::Kind::Follow;
    follow.grasp = settings_.start_grasping;
    controller_->command(std::move(follow));
  } else {
    sendMode(settings_.initial_mode);
  }

  state_publisher_ = node_.advertise<bimanual_skills::JointTrajectoryControllerState>("state", 10);
  wrench_publisher_ = node_.advertise<geometry_msgs::WrenchStamped>("estimated_wrench", 10);
  // The observer's joint torques (sensor_msgs/JointState, effort only): what a learning's cost reads of it (the
  // scarf's c_torque), as franka_ros' tau_ext_hat_filtered.
  torque_publisher_ = node_.advertise<sensor_msgs::JointState>("estimated_external_torque", 10);
  path_publisher_ = node_.advertise<visualization_msgs::MarkerArray>("tool_paths", 1);
  diagnostics_publisher_ = node_.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
  command_subscriber_ = node_.subscribe("command", 10, &ArmControllerInterface::onCommand, this);
  if (!settings_.target_topic.empty()) {
    target_subscriber_ = node_.subscribe(settings_.target_topic, 10, &ArmControllerInterface::onTarget, this);
    follow_publisher_ = node_.advertise<bimanual_skills::FollowerState>("follow_state", 10);
  }
  mode_service_ = node_.advertiseService("set_mode", &ArmControllerInterface::onSetMode, this);
  server_ = std::make_unique<Server>(
      node_, "follow_joint_trajectory", [this](GoalHandle goal) { onGoal(goal); },
      [this](GoalHandle goal) { onCancel(goal); }, false);
  server_->start();
  // Polled at 1 kHz of wall time; published at publish_rate of the states' time (simulated time for a simulation
  // that runs faster or slower than real time).
  publish_timer_ = node_.createSteadyTimer(ros::WallDuration(0.001), &ArmControllerInterface::onPublish, this);
  diagnostics_timer_ = node_.createSteadyTimer(ros::WallDuration(1.0), &ArmControllerInterface::onDiagnostics, this);
}

ArmControllerInterface::~ArmControllerInterface() {
  publish_timer_.stop();
  diagnostics_timer_.stop();
  // A gripper call on its thread uses this object: wait for it (it is bounded).
  const double until = realtime::monotonicSeconds() + 10.0;
  while (grasp_in_flight_ && realtime::monotonicSeconds() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const std::lock_guard<std::mutex> lock(mutex_);
  cancelActive("the controller shut down");
}

void ArmControllerInterface::setDriverDiagnostics(std::vector<std::pair<std::string, std::string>> values) {
  const std::lock_guard<std::mutex> lock(mutex_);
  driver_diagnostics_ = std::move(values);
}

void ArmControllerInterface::loopStopped(const std::string& why) {
  const std::lock_guard<std::mutex> lock(mutex_);
  loop_stopped_ = "the control loop stopped: " + why;
  abortActive(loop_stopped_);
}

std::string ArmControllerInterface::loopProblem() const {
  if (!loop_stopped_.empty()) return loop_stopped_;
  // A controller without a state yet (a process just started) would drop a goal when its first state starts it.
  if (!last_ && controller_->lastCycle() == 0.0) return "the control loop has not run yet (no joint state)";
  const double idle = loopIdle();
  if (idle <= settings_.loop_timeout) return "";
  std::ostringstream why;
  why << "the control loop stopped: no control cycle for " << idle << " s of the robot's clock (loop_timeout "
      << settings_.loop_timeout << " s)";
  return why.str();
}

double ArmControllerInterface::loopIdle() const {
  // Both times from this process's clock: it may lag the loop's stamps, and a reset takes it back. A paused
  // simulation's clock stands still: its loop is never idle.
  return last_ ? ros::Time::now().toSec() - clock_at_state_ : 0.0;
}

void ArmControllerInterface::abortActive(const std::string& why) {
  if (!active_) return;
  Result result;
  result.error_code = Result::PATH_TOLERANCE_VIOLATED;
  result.error_string = why;
  active_->setAborted(result, why);
  ROS_WARN("%s: goal aborted: %s", owner_.c_str(), why.c_str());
  active_.reset();
  active_id_ = 0;
}

void ArmControllerInterface::sendTrajectory(bc::Waypoints&& waypoints, const bc::TrajectoryTolerances& tolerances,
                                            std::uint64_t goal_id, const ros::Time& start) {
  bc::ControllerCommand command;
  command.kind = bc::ControllerCommand::Kind::Trajectory;
  // A zero stamp is "now": the cycle that takes it (the clock here lags a simulation many times faster than the wall).
  command.start = start.isZero() ? std::numeric_limits<double>::quiet_NaN() : start.toSec();
  command.waypoints = std::move(waypoints);
  command.tolerances = tolerances;
  command.goal_id = goal_id;
  controller_->command(command);
  ++trajectories_;
}

void ArmControllerInterface::sendMode(bc::ControllerMode mode) {
  bc::ControllerCommand command;
  command.kind = bc::ControllerCommand::Kind::Mode;
  command.mode = mode;
  command.tolerances = bc::TrajectoryTolerances::none(static_cast<int>(joint_names_.size()));
  controller_->command(command);
}

void ArmControllerInterface::cancelActive(const std::string& why) {
  if (!active_) return;
  Result result;
  result.error_code = Result::SUCCESSFUL;
  result.error_string = why;
  active_->setCanceled(result, why);  // a goal not yet accepted is recalled
  active_.reset();
  active_id_ = 0;
}

ros::Time ArmControllerInterface::loopNow() {
  // The loop's own clock, read from its last state: this process's clock lags a simulator's many times faster
  // than real time (a trajectory past for the loop would look ahead here).
  const std::lock_guard<std::mutex> lock(mutex_);
  const double now = ros::Time::now().toSec();
  return ros::Time(last_ && last_->stamp > now ? last_->stamp : now);
}

void ArmControllerInterface::onCommand(const trajectory_msgs::JointTrajectory::ConstPtr& message) {
  if (message->points.empty()) {
    // joint_trajectory_controller's "stop here", whatever joints it names: the arm stops and holds, a goal ends.
    const std::lock_guard<std::mutex> lock(mutex_);
    cancelActive("preempted by an empty trajectory on the command topic");
    sendMode(bc::ControllerMode::Hold);
    ROS_INFO("%s: empty trajectory: holding", owner_.c_str());
    return;
  }
  bc::Waypoints waypoints;
  const ros::Time now = loopNow();
  ros::Time start;
  const TrajectoryError error =
      toWaypoints(*message, joint_names_, now, controller_->trajectoryCapacity(), waypoints, start);
  const std::lock_guard<std::mutex> lock(mutex_);
  const auto status = [&] { return controller_->validate(waypoints, offsetOf(start, now)); };
  if (!error && waypoints.times.size() > 0 && status() != bc::TrajectoryStatus::Ok) {
    ++rejected_;
    last_rejection_ =
        std::string(bc::toString(status())) + " (a point outside the joint limits, or times that do not increase)";
    ROS_WARN("%s: trajectory rejected: %s; the current motion goes on", owner_.c_str(), last_rejection_.c_str());
    return;
  }
  if (error) {
    ++rejected_;
    last_rejection_ = error.message;
    ROS_WARN("%s: trajectory rejected: %s; the current motion goes on", owner_.c_str(), error.message.c_str());
    return;
  }
  cancelActive("preempted by a trajectory on the command topic");
  const double duration = waypoints.times[waypoints.times.size() - 1];
  const auto points = waypoints.times.size();
  sendTrajectory(std::move(waypoints), settings_.default_tolerances, 0, start);
  // DEBUG: a teleoperation streams many (joint_trajectory_controller logs none either).
  ROS_DEBUG("%s: tracking %ld points over %.2f s", owner_.c_str(), static_cast<long>(points), duration);
}

void ArmControllerInterface::onGoal(GoalHandle goal) {
  const auto request = goal.getGoal();
  Result result;
  bc::Waypoints waypoints;
  bc::TrajectoryTolerances tolerances;
  const ros::Time now = loopNow();
  ros::Time start;
  TrajectoryError error =
      toWaypoints(request->trajectory, joint_names_, now, controller_->trajectoryCapacity(), waypoints, start);
  if (!error) {
    error = resolveTolerances(request->path_tolerance, request->goal_tolerance, request->goal_time_tolerance,
                              joint_names_, settings_.default_tolerances, tolerances);
  }
  if (!error && waypoints.times.size() > 0) {
    const bc::TrajectoryStatus status = controller_->validate(waypoints, offsetOf(start, now));
    if (status != bc::TrajectoryStatus::Ok) {
      error = {Result::INVALID_GOAL,
               std::string("the controller refuses the waypoints: ") + bc::toString(status) +
                   (status == bc::TrajectoryStatus::OutOfLimits ? " (a point lies outside the joint limits)" : "")};
    }
  }
  const std::lock_guard<std::mutex> lock(mutex_);
  if (!error) {
    // joint_trajectory_controller rejects a goal while it is not running: a loop that stopped would never end it.
    const std::string problem = loopProblem();
    if (!problem.empty()) error = {Result::INVALID_GOAL, problem};
  }
  if (error) {
    ++rejected_;
    last_rejection_ = error.message;
    result.error_code = error.code;
    result.error_string = error.message;
    goal.setRejected(result, error.message);
    ROS_WARN("%s: goal rejected: %s", owner_.c_str(), error.message.c_str());
    return;
  }
  cancelActive("preempted by a new goal");
  if (waypoints.times.size() == 0) {
    goal.setAccepted();
    sendMode(bc::ControllerMode::Hold);
    result.error_code = Result::SUCCESSFUL;
    result.error_string = "empty trajectory: holding";
    goal.setSucceeded(result, result.error_string);
    return;
  }
  // Accepted at once, as joint_trajectory_controller accepts a goal it has handed to its loop: a loop that stands
  // still on purpose (a paused simulator, a controller waiting for its next state) answers its client all the same.
  goal.setAccepted("the control loop has the trajectory in its mailbox");
  active_ = goal;
  active_goal_time_ = tolerances.goal_time;
  active_id_ = ++next_goal_id_;
  sendTrajectory(std::move(waypoints), tolerances, active_id_, start);
}

void ArmControllerInterface::onCancel(GoalHandle goal) {
  const std::lock_guard<std::mutex> lock(mutex_);
  if (active_ && *active_ == goal) {
    sendMode(bc::ControllerMode::Hold);
    cancelActive("canceled: the arm stops smoothly and holds");
  }
}

bool ArmControllerInterface::onSetMode(bimanual_skills::SetControlMode::Request& request,
                                       bimanual_skills::SetControlMode::Response& response) {
  if (request.mode == "follow" || request.mode == "grasp") {
    if (!controller_->canFollow()) {
      response.message = "refused: following is off (parameter follow/target_topic is empty)";
      return true;
    }
    const std::lock_guard<std::mutex> lock(mutex_);
    cancelActive("preempted by set_mode " + request.mode);
    bc::ControllerCommand command;
    command.kind = bc::ControllerCommand::Kind::Follow;
    const bool grasp = request.mode == "grasp";
    command.grasp = grasp;
    controller_->command(std::move(command));
    response.success = true;
    response.message = "following " + settings_.target_topic + (grasp ? " and grasping it when it can" : "") +
                       " from the next control step";
    ROS_INFO("%s: %s", owner_.c_str(), response.message.c_str());
    return true;
  }
  bc::ControllerMode mode;
  if (!bc::modeFromString(request.mode.c_str(), mode)) {
    response.message = "unknown mode '" + request.mode + "' (gravity_compensation, hold, track, follow, grasp)";
    return true;
  }
  const std::lock_guard<std::mutex> lock(mutex_);
  cancelActive("preempted by set_mode " + request.mode);
  sendMode(mode);
  response.success = true;
  response.message = "mode " + request.mode + " from the next control step";
  ROS_INFO("%s: %s", owner_.c_str(), response.message.c_str());
  return true;
}

void ArmControllerInterface::onTarget(const bimanual_skills::TrackedObject::ConstPtr& message) {
  bc::FollowTarget target;
  target.stamp = message->header.stamp.toSec();
  target.tracking = message->tracking;
  const auto& p = message->pose.pose.position;
  target.position = Eigen::Vector3d(p.x, p.y, p.z);
  target.velocity = Eigen::Vector3d(message->velocity.x, message->velocity.y, message->velocity.z);
  if (!message->last_accepted.isZero()) target.measured = message->last_accepted.toSec();
  std::string problem;
  if (message->header.frame_id != settings_.world_frame) {
    problem = "the target is in frame '" + message->header.frame_id + "', the robot's root is '" +
              settings_.world_frame + "'";
    target.tracking = false;  // not a place this arm can go to: it holds
  } else if (message->tracking && !(target.position.allFinite() && target.velocity.allFinite())) {
    problem = "the target's position or velocity is not finite";
  } else if (!message->tracking) {
    problem = "the tracker: " + message->state;
  }
  controller_->setTarget(target);
  const std::lock_guard<std::mutex> lock(mutex_);
  target_problem_ = problem;
}

void ArmControllerInterface::follow(const bc::ArmControllerState& s, const ros::Time& stamp, bool due) {
  if (!s.grasp_requested) grasp_answered_ = false;  // the loop has the answer: a later request is a new one
  if (s.grasp_requested && !grasp_answered_ && !grasp_in_flight_.exchange(true)) {
    // The follower asks for the gripper: a bounded call on a thread of its own, its answer to the loop.
    std::thread([this] {
      bimanual_skills::ClothGrasp grasp;
      grasp.request.arm = arm_;
      grasp.request.grasp = true;
      const CallOutcome outcome = settings_.gripper_service.empty()
                                      ? CallOutcome::NoServer
                                      : gripper_.call(settings_.gripper_service, grasp, 5.0);
      const bool held = outcome == CallOutcome::Answered && grasp.response.success;
      controller_->graspDone(held);
      const std::string said = outcome == CallOutcome::Answered ? grasp.response.message : describe(outcome);
      ROS_INFO("%s: closing the gripper (%s): %s", owner_.c_str(), settings_.gripper_service.c_str(), said.c_str());
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        grasp_message_ = said;
        grasp_answered_ = true;
      }
      grasp_in_flight_ = false;
    }).detach();
  }
  if (std::isfinite(s.follow_target_stamp) && s.follow_target_stamp != last_target_stamp_ &&
      std::isfinite(s.follow_latency)) {
    last_target_stamp_ = s.follow_target_stamp;
    latencies_.push_back(s.follow_latency);
  }
  // Said when something changed, and at the publish rate while following; an arm that does not follow stays quiet.
  const bool holding = s.following && s.follow_phase == bc::FollowPhase::Holding;
  const bool phase_changed = s.following != follow_said_.following || s.follow_phase != follow_said_.phase ||
                             s.follow_reason != follow_said_.reason || s.follow_interrupted != follow_said_.interrupted;
  const bool changed = phase_changed || (holding && target_problem_ != follow_said_.problem);
  if (!changed && !(s.following && due)) return;
  std::string reason;
  if (!s.following && s.follow_interrupted) {
    reason = std::string("the controller left tracking: ") +
             (s.follow_stopped == bc::ControllerStatus::Ok || s.follow_stopped == bc::ControllerStatus::Saturated
                  ? "it restarted (the robot's clock went back)"
              : s.follow_stopped == bc::ControllerStatus::StaleState
                  ? "its states came late or stopped (StaleState); it held the arm and restarted where it was"
              : s.follow_stopped == bc::ControllerStatus::VelocityLimit
                  ? "VelocityLimit: " + bc::velocityLimitText(s.velocity, settings_.config.velocity_limit)
                  : bc::toString(s.follow_stopped));
  } else if (holding) {
    reason = std::string(bc::toString(s.follow_reason)) + (target_problem_.empty() ? "" : " (" + target_problem_ + ")");
  }
  if (changed) {
    follow_said_ = {s.following, s.follow_interrupted, s.follow_phase, s.follow_reason, target_problem_};
    last_follow_text_ = std::string(s.following ? bc::toString(s.follow_phase) : "not following") +
                        (reason.empty() ? "" : ": " + reason);
    if (phase_changed && (s.following || s.follow_interrupted)) {
      ROS_INFO("%s: %s", owner_.c_str(), last_follow_text_.c_str());
    }
  }
  bimanual_skills::FollowerState out;
  out.header.stamp = stamp;
  out.header.frame_id = settings_.world_frame;
  out.following = s.following;
  out.phase = s.following ? bc::toString(s.follow_phase) : "idle";
  out.reason = reason;
  out.goal.x = s.follow_goal.x(), out.goal.y = s.follow_goal.y(), out.goal.z = s.follow_goal.z();
  out.tool.x = s.follow_tool.x(), out.tool.y = s.follow_tool.y(), out.tool.z = s.follow_tool.z();
  out.error = s.follow_error;
  out.target_stamp = ros::Time(std::isfinite(s.follow_target_stamp) ? std::max(0.0, s.follow_target_stamp) : 0.0);
  out.latency = s.follow_latency;
  follow_publisher_.publish(out);
}

void ArmControllerInterface::finishGoal(const bc::ArmControllerState& state) {
  if (!active_ || state.goal_id != active_id_ || state.goal == bc::GoalState::Active) return;
  Result result;
  const std::string joint =
      state.goal_joint >= 0 ? joint_names_[static_cast<std::size_t>(state.goal_joint)] : std::string();
  std::ostringstream why;
  switch (state.goal) {
    case bc::GoalState::Succeeded:
      result.error_code = Result::SUCCESSFUL;
      why << "reached the goal (started at t = " << std::fixed << std::setprecision(6) << state.trajectory_start
          << " s)";
      break;
    case bc::GoalState::PathToleranceViolated:
      result.error_code = Result::PATH_TOLERANCE_VIOLATED;
      why << "joint " << joint << " left its path tolerance: " << (state.goal_error_is_velocity ? "velocity " : "")
          << "error " << state.goal_error << (state.goal_error_is_velocity ? " rad/s" : " rad")
          << "; the arm stops smoothly and holds";
      break;
    case bc::GoalState::GoalToleranceViolated:
      result.error_code = Result::GOAL_TOLERANCE_VIOLATED;
      why << "joint " << joint << " not within its goal tolerance " << active_goal_time_
          << " s after the end (goal_time_tolerance): " << (state.goal_error_is_velocity ? "velocity " : "error ")
          << state.goal_error << (state.goal_error_is_velocity ? " rad/s" : " rad");
      break;
    case bc::GoalState::Rejected:
      result.error_code = Result::INVALID_GOAL;
      why << "the controller refused the waypoints: " << bc::toString(state.rejection);
      break;
    case bc::GoalState::Aborted:
      result.error_code = Result::PATH_TOLERANCE_VIOLATED;
      if (state.abort_reason == bc::ControllerStatus::Ok || state.abort_reason == bc::ControllerStatus::Saturated) {
        why << "the controller restarted (its joint states started anew: a reset or a new robot clock); holding";
      } else if (state.abort_gap > 0.0) {
        why << "the controller stopped tracking: " << bc::toString(state.abort_reason) << " after a " << state.abort_gap
            << " s gap in its joint states (the robot ran without its torques meanwhile); holding";
      } else {
        why << "the controller stopped tracking: " << bc::toString(state.abort_reason)
            << " (velocity limit, stale or restarted joint states); holding";
      }
      break;
    default:
      result.error_code = Result::SUCCESSFUL;
      why << "preempted";
      break;
  }
  result.error_string = why.str();
  if (state.goal == bc::GoalState::Succeeded) {
    active_->setSucceeded(result, result.error_string);
  } else if (state.goal == bc::GoalState::Preempted) {
    active_->setCanceled(result, result.error_string);
  } else {
    active_->setAborted(result, result.error_string);
    ROS_WARN("%s: goal aborted: %s", owner_.c_str(), result.error_string.c_str());
  }
  active_.reset();
  active_id_ = 0;
}

void ArmControllerInterface::onPublish(const ros::SteadyTimerEvent&) {
  const bc::ArmControllerState* fresh = controller_->latestState();
  const std::lock_guard<std::mutex> lock(mutex_);
  if (!fresh) {
    // A loop that computes no torque while the robot's clock goes on has stopped.
    if (active_) {
      const std::string problem = loopProblem();
      if (!problem.empty()) abortActive(problem);
    }
    return;
  }
  last_ = *fresh;
  last_state_wall_ = bimanual_skills::realtime::monotonicSeconds();
  clock_at_state_ = ros::Time::now().toSec();
  const bc::ArmControllerState& s = *last_;
  const bool due = s.stamp < last_published_ || s.stamp - last_published_ >= 1.0 / settings_.publish_rate - 1e-9;
  if (controller_->canFollow()) follow(s, ros::Time(s.stamp), due);
  if (!due && !(active_ && s.goal_id == active_id_ && s.goal != bc::GoalState::Active)) return;
  last_published_ = s.stamp;
  const ros::Time stamp(s.stamp);
  bimanual_skills::JointTrajectoryControllerState message;
  message.header.stamp = stamp;
  message.joint_names = joint_names_;
  assign(message.desired.positions, s.desired_position);
  assign(message.desired.velocities, s.desired_velocity);
  assign(message.desired.accelerations, s.desired_acceleration);
  assign(message.actual.positions, s.position);
  assign(message.actual.velocities, s.velocity);
  assign(message.actual.effort, s.torque);
  assign(message.error.positions, s.position_error);
  assign(message.error.velocities, s.velocity_error);
  state_publisher_.publish(message);
  if (active_ && s.goal_id == active_id_) {
    bimanual_skills::FollowJointTrajectoryFeedback feedback;
    feedback.header = message.header;
    feedback.joint_names = joint_names_;
    feedback.desired = message.desired;
    feedback.actual = message.actual;
    feedback.error = message.error;
    active_->publishFeedback(feedback);
  }
  finishGoal(s);
  geometry_msgs::WrenchStamped wrench;
  wrench.header.stamp = stamp;
  wrench.header.frame_id = settings_.base_link;
  wrench.wrench.force.x = s.wrench[0];
  wrench.wrench.force.y = s.wrench[1];
  wrench.wrench.force.z = s.wrench[2];
  wrench.wrench.torque.x = s.wrench[3];
  wrench.wrench.torque.y = s.wrench[4];
  wrench.wrench.torque.z = s.wrench[5];
  wrench_publisher_.publish(wrench);
  sensor_msgs::JointState torque;
  torque.header.stamp = stamp;
  torque.name = joint_names_;
  assign(torque.effort, s.external_torque);
  torque_publisher_.publish(torque);
  publishToolPaths(s, stamp);
}

void ArmControllerInterface::publishToolPaths(const bc::ArmControllerState& state, const ros::Time& stamp) {
  static constexpr std::size_t kPathLength = 1000;
  const auto tool = [this](const Eigen::VectorXd& q) {
    geometry_msgs::Point p;
    if (kinematics::forwardKinematics(*settings_.model, *kinematics_, q) == kinematics::KinematicsStatus::Success) {
      const Eigen::Vector3d t = kinematics_->tipPose().translation();
      p.x = t.x();
      p.y = t.y();
      p.z = t.z();
    }
    return p;
  };
  for (auto* path : {&actual_path_, &desired_path_}) {
    if (path->size() >= kPathLength) path->pop_front();
  }
  actual_path_.push_back(tool(state.position));
  desired_path_.push_back(tool(state.desired_position));
  if (++publish_count_ % 10 != 0 || path_publisher_.getNumSubscribers() == 0) return;
  visualization_msgs::MarkerArray markers;
  for (int k = 0; k < 2; ++k) {
    visualization_msgs::Marker m;
    m.header.stamp = stamp;
    m.header.frame_id = settings_.base_link;
    m.ns = k == 0 ? "actual" : "commanded";
    m.type = visualization_msgs::Marker::LINE_STRIP;
    m.pose.orientation.w = 1.0;
    m.scale.x = 0.006;
    m.color.a = 1.0f;
    (k == 0 ? m.color.g : m.color.r) = 0.9f;
    const auto& path = k == 0 ? actual_path_ : desired_path_;
    m.points.assign(path.begin(), path.end());
    markers.markers.push_back(m);
  }
  path_publisher_.publish(markers);
}

void ArmControllerInterface::onDiagnostics(const ros::SteadyTimerEvent&) {
  const std::lock_guard<std::mutex> lock(mutex_);
  diagnostic_msgs::DiagnosticArray array;
  array.header.stamp = ros::Time::now();
  diagnostic_msgs::DiagnosticStatus status;
  status.name = owner_;
  status.hardware_id = arm_;
  const double silent = last_ ? bimanual_skills::realtime::monotonicSeconds() - last_state_wall_ : 0.0;
  const bool stale = last_ && silent > std::max(1.0, 2.0 * settings_.config.state_timeout);
  status.level = !last_ || stale ? diagnostic_msgs::DiagnosticStatus::WARN : diagnostic_msgs::DiagnosticStatus::OK;
  status.message = !last_  ? "waiting for joint states"
                   : stale ? "no control step for " + std::to_string(silent) + " s (robot paused or states stale)"
                           : std::string("running, mode ") + bc::toString(last_->mode);
  const auto add = [&status](const std::string& key, const std::string& value) {
    diagnostic_msgs::KeyValue kv;
    kv.key = key;
    kv.value = value;
    status.values.push_back(kv);
  };
  if (last_) {
    const bc::ArmControllerState& s = *last_;
    const auto count = [&s](bc::ControllerStatus c) { return std::to_string(s.status_counts[static_cast<int>(c)]); };
    add("mode", bc::toString(s.mode));
    add("max_tracking_error_rad", std::to_string(s.position_error.cwiseAbs().maxCoeff()));
    add("control_steps", std::to_string(s.sequence));
    add("control_period_s", std::to_string(s.period));
    add("saturated_steps", count(bc::ControllerStatus::Saturated));
    add("invalid_states", count(bc::ControllerStatus::InvalidState));
    add("stale_states", count(bc::ControllerStatus::StaleState));
    add("velocity_limit_events", count(bc::ControllerStatus::VelocityLimit));
    add("observer_irregular_steps", std::to_string(s.observer_irregular_steps));
    add("observer_restarts", std::to_string(s.observer_restarts));
    add("goal", bc::toString(s.goal));
  }
  if (controller_->canFollow()) {
    add("following", last_follow_text_.empty() ? "not following" : last_follow_text_);
    std::sort(latencies_.begin(), latencies_.end());
    std::ostringstream latency;
    latency << std::fixed << std::setprecision(1) << latencies_.size() << " estimates; median "
            << (latencies_.empty() ? 0.0 : 1e3 * latencies_[latencies_.size() / 2]) << " ms, p99 "
            << (latencies_.empty() ? 0.0 : 1e3 * latencies_[latencies_.size() * 99 / 100]) << " ms";
    add("follow_latency_last_second", latency.str());
    latencies_.clear();
    if (!grasp_message_.empty()) add("gripper", grasp_message_);
  }
  add("trajectories", std::to_string(trajectories_));
  add("rejected_trajectories", std::to_string(rejected_));
  add("last_rejection", last_rejection_);
  for (const auto& [key, value] : driver_diagnostics_) add(key, value);
  array.status.push_back(status);
  diagnostics_publisher_.publish(array);
}

}  // namespace bimanual_skills::ros_layer
