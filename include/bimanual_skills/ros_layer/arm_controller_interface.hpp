/// \file
/// The ROS side of one arm's controller, whoever runs its real-time loop (a simulator's or a hardware driver's
/// loop thread, or a node driven by joint-state messages): the `command` topic and the `follow_joint_trajectory`
/// action (trajectory_msgs in, joint_trajectory_controller's semantics), the `set_mode` service, and the `state`,
/// `estimated_wrench`, `estimated_external_torque`, `tool_paths` and /diagnostics outputs, and following a tracked
/// object (set_mode follow: the tracker's estimates in, the gripper's service called when the follower asks,
/// `follow_state` out), all served from non-real-time threads and joined to the loop only through
/// control::RealtimeArmController's lock-free handoffs.
#pragma once

#include "bimanual_skills/FollowJointTrajectoryAction.h"
#include "bimanual_skills/SetControlMode.h"
#include "bimanual_skills/TrackedObject.h"
#include "bimanual_skills/control/realtime_arm_controller.hpp"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/ros_layer/bounded_call.hpp"
#include "bimanual_skills/ros_layer/parameters.hpp"

#include <actionlib/server/action_server.h>
#include <geometry_msgs/Point.h>
#include <ros/ros.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <atomic>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace bimanual_skills::ros_layer {

/// What the controller parameters say (see ArmControllerInterface's parameters).
struct ControllerSettings {
  std::shared_ptr<const kinematics::ChainModel> model;  ///< The chain base_link -> tip_link.
  std::string base_link, tip_link, friction_file;
  control::ArmControllerConfig config;
  dynamics::FrictionModel friction;
  control::ControllerMode initial_mode = control::ControllerMode::Hold;
  bool start_following = false;  ///< initial_mode follow or grasp: follow the tracked object from the start...
  bool start_grasping = false;   ///< ...and grasp it (grasp).
  double publish_rate = 100.0;   ///< [Hz] of state, the estimates and action feedback.
  control::TrajectoryTolerances default_tolerances;  ///< When a goal does not set them.
  double loop_timeout = 0.5;  ///< [s of the robot's clock] without a control cycle: the active goal is aborted.
  // Following a tracked object (set_mode follow), when target_topic is set.
  std::string target_topic;     ///< bimanual_skills/TrackedObject in world_frame ("": following off).
  std::string gripper_service;  ///< bimanual_skills/ClothGrasp closing the gripper ("": none, a grasp fails).
  std::string world_frame;      ///< The robot description's root: the follower's world.
  control::TargetFollowerConfig follow;
};

/// Defaults of a controller's parameters that come from the robot (its robot file, sim/robot_file.hpp): the chain,
/// the gains and the friction model. A parameter that is set wins.
struct ControllerDefaults {
  std::string base_link, tip_link, friction_file;
  Eigen::VectorXd kp, kv;  ///< Empty: the built-in 50 and 5 per joint.
};

/// The parameters a controller reads (under its parameter namespace), with their meaning, for --help texts.
extern const char* const kControllerParameterHelp;

/// Reads and checks the controller parameters of arm `arm` for the chain that `robot_description` gives, with the
/// robot's `defaults`. \throws std::invalid_argument with the parameter's name and the reason for a mistyped or
/// out-of-range value, an unknown link, no link given (neither parameter nor robot) or an unreadable friction file.
ControllerSettings readControllerSettings(ParameterReader& parameters, const std::string& arm,
                                          const std::string& robot_description,
                                          const ControllerDefaults& defaults = ControllerDefaults());

/// One arm's controller as ROS sees it. The loop that drives it calls realtime().update(...) on its own thread;
/// everything here runs on the callback queue of `node` (whatever spins it). Topics, the action and the service
/// are relative to `node` (the arm's namespace).
class ArmControllerInterface {
 public:
  /// Reads the controller parameters through `parameters` (the caller warns about unknown keys when it has read
  /// its own). \throws std::invalid_argument (see readControllerSettings).
  ArmControllerInterface(ros::NodeHandle node, ParameterReader& parameters, const std::string& arm,
                         const std::string& robot_description, const std::string& owner,
                         const ControllerDefaults& defaults = ControllerDefaults());
  ~ArmControllerInterface();
  ArmControllerInterface(const ArmControllerInterface&) = delete;
  ArmControllerInterface& operator=(const ArmControllerInterface&) = delete;

  /// The real-time side, for the loop.
  control::RealtimeArmController& realtime() noexcept { return *controller_; }
  const std::vector<std::string>& jointNames() const noexcept { return joint_names_; }
  const std::string& arm() const noexcept { return arm_; }
  const ControllerSettings& settings() const noexcept { return settings_; }
  /// Counted outside the loop by the node that drives it (e.g. joint-state messages dropped), for /diagnostics.
  void setDriverDiagnostics(std::vector<std::pair<std::string, std::string>> values);
  /// The host's loop has stopped for good (a simulation that diverged, a driver's fault): the active goal is aborted
  /// with `why`. (A loop that just stops computing torques while the robot's clock goes on is found by loop_timeout.)
  void loopStopped(const std::string& why);

 private:
  using Server = actionlib::ActionServer<bimanual_skills::FollowJointTrajectoryAction>;
  using GoalHandle = Server::GoalHandle;

  /// Now, as the loop counts it: the later of this process's clock and the loop's last state's stamp.
  ros::Time loopNow();
  void onCommand(const trajectory_msgs::JointTrajectory::ConstPtr& message);
  void onGoal(GoalHandle goal);
  void onCancel(GoalHandle goal);
  bool onSetMode(bimanual_skills::SetControlMode::Request& request,
                 bimanual_skills::SetControlMode::Response& response);
  void onPublish(const ros::SteadyTimerEvent&);
  void onTarget(const bimanual_skills::TrackedObject::ConstPtr& message);
  /// Following: the grasp the loop asks for (a bounded call on a thread of its own), the follower's state.
  void follow(const control::ArmControllerState& state, const ros::Time& stamp, bool due);
  void onDiagnostics(const ros::SteadyTimerEvent&);
  /// Hands a trajectory (already converted) to the loop; `goal_id` 0 for a topic command.
  void sendTrajectory(control::Waypoints&& waypoints, const control::TrajectoryTolerances& tolerances,
                      std::uint64_t goal_id, const ros::Time& start);
  /// Why the loop cannot run a goal now ("" when it can): it stopped for good, or computed no torque for loop_timeout
  /// of the robot's clock. Caller holds mutex_.
  std::string loopProblem() const;
  /// [s of this process's clock] since the loop's last state (0 before any). Caller holds mutex_.
  double loopIdle() const;
  /// Ends the active goal (if any) as aborted, with `why`. Caller holds mutex_.
  void abortActive(const std::string& why);
  void sendMode(control::ControllerMode mode);
  /// Ends the active goal (if any) as canceled, with `why`. Caller holds mutex_.
  void cancelActive(const std::string& why);
  void finishGoal(const control::ArmControllerState& state);
  void publishToolPaths(const control::ArmControllerState& state, const ros::Time& stamp);

  std::string arm_, owner_;
  ros::NodeHandle node_;
  ControllerSettings settings_;
  std::unique_ptr<control::RealtimeArmController> controller_;
  std::vector<std::string> joint_names_;

  std::mutex mutex_;  ///< The non-real-time state below (callbacks may run on several threads).
  std::optional<control::ArmControllerState> last_;
  std::optional<GoalHandle> active_;  ///< The accepted goal whose trajectory the loop runs or will take.
  std::string loop_stopped_;          ///< Why the host's loop stopped for good (loopStopped); "" while it runs.
  double active_goal_time_ = 0.0;     ///< The active goal's goal_time_tolerance [s].
  std::uint64_t active_id_ = 0, next_goal_id_ = 0;
  long trajectories_ = 0, rejected_ = 0;
  std::string last_rejection_;
  std::vector<std::pair<std::string, std::string>> driver_diagnostics_;
  std::unique_ptr<kinematics::ChainData> kinematics_;
  std::deque<geometry_msgs::Point> actual_path_, desired_path_;
  long publish_count_ = 0;
  double last_state_wall_ = 0.0;
  double clock_at_state_ = 0.0;     ///< This process's ROS time when the last state came [s].
  double last_published_ = -1e300;  ///< Stamp of the last state published [s].

  // Following.
  std::string target_problem_;  ///< Why the last target message could not be used ("" when it could).
  ServiceCaller gripper_;       ///< The gripper's service (follow/gripper_service).
  std::atomic<bool> grasp_in_flight_{false};
  bool grasp_answered_ = false;   ///< The request in the loop's states was answered (until a state without one).
  std::string last_follow_text_;  ///< Phase and reason last said.
  struct FollowSaid {
    bool following = false, interrupted = false;
    control::FollowPhase phase = control::FollowPhase::Idle;
    control::HoldReason reason = control::HoldReason::None;
    std::string problem;
  } follow_said_;                  ///< What follow_state last said.
  std::vector<double> latencies_;  ///< Of the estimates used since the last diagnostics [s].
  double last_target_stamp_ = -1.0;
  std::string grasp_message_;  ///< The gripper's last answer.

  ros::Publisher state_publisher_, wrench_publisher_, torque_publisher_, path_publisher_, diagnostics_publisher_,
      follow_publisher_;
  ros::Subscriber command_subscriber_, target_subscriber_;
  ros::ServiceServer mode_service_;
  std::unique_ptr<Server> server_;
  ros::SteadyTimer publish_timer_, diagnostics_timer_;
};

}  // namespace bimanual_skills::ros_layer
