/// \file
/// The scarf-placing task (thesis Sec. 4.3.1) as a rollout::RolloutTask that runs on a robot through ROS interfaces
/// only (RobotConnection): bullet_sim's scarf scene from sim.launch (config/scarf_sim.yaml with config/
/// scarf_start.yaml), or a real arm holding a scarf before a mannequin. One rollout: the reset (the arm at its start,
/// the scarf in its tool), the policy's joint references (tasks::ScarfTask::plan, identical to the in-process
/// task's) as one FollowJointTrajectory goal, the tool opening at the planned instant (a stamped ClothGrasp), the
/// scarf settling, then the cost: c_t from the plan, c_torque from the arm's controller's own observer
/// (ARM/estimated_external_torque over the motion), c_cam from the colour image of the perspective camera, which
/// must be the task's (its CameraInfo and its pose on tf: d_ref and the hanging level are pixels of that camera).
/// The scarf's ground truth, when the robot has it (a simulator's cloud), is recorded beside the cost. Any failure
/// ends the rollout with its outcome and reason; a robot's failure (RobotFailed) rebuilds the action client, opens
/// the tool and takes the arm back to its start. Target bimanual_skills_ros_robot. Offline: allocates.
#pragma once

#include "bimanual_skills/rollout/parallel_evaluator.hpp"
#include "bimanual_skills/rollout/scarf_learning.hpp"
#include "bimanual_skills/ros_layer/robot/robot_connection.hpp"
#include "bimanual_skills/tasks/scarf_task.hpp"

#include <sensor_msgs/JointState.h>

#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace bimanual_skills::ros_layer {

/// The scarf's interfaces (scarf_learner's robot parameters): the robot's, and how the rollout uses them.
struct ScarfRobotInterfaces : RobotInterfaces {
  ScarfRobotInterfaces() {
    arms = {"left"};
    camera = "rgbd";
  }
  std::string world_frame = "world";  ///< The frame the task's camera pose is given in, on tf.
  double trajectory_rate = 100.0;     ///< Points per second of the motion's trajectory goal.
  /// From sending the goal to its start [s of the robot's clock]; with a pause service the clock stands still until
  /// the controller has accepted it.
  double start_delay = 0.5;
  /// To the start when the reset leaves the arm elsewhere, at least [s of the robot's clock] (within half the
  /// joints' velocity limits).
  double move_time = 2.0;
  /// Move the arm to the start before the reset, which then lays the scarf in its tool: for a robot whose reset
  /// leaves the arm where it is (a person lays the scene anew; bullet_sim ~hardware).
  bool move_before_reset = false;

  /// \throws std::invalid_argument naming the field that is out of range.
  void validate() const;
};

class ScarfOnRobotTask : public rollout::RolloutTask, public rollout::RecordedScarfTask {
 public:
  /// Builds the task, connects to the interfaces and checks the camera against the task's. \throws
  /// std::invalid_argument for a bad configuration, std::runtime_error when an interface does not appear or the
  /// camera cannot be used (with the reason).
  ScarfOnRobotTask(const tasks::ScarfTaskConfig& task, const ScarfRobotInterfaces& robot);
  ~ScarfOnRobotTask() override;

  std::vector<std::string> termNames() const override;
  Eigen::VectorXd initialParameters() const override;
  /// One rollout on the robot; the seed does not enter (the robot has its own noise). The scarf's force on the tool
  /// (a simulator's truth inside it) is not measured: NaN.
  rollout::RolloutResult run(const Eigen::VectorXd& parameters, std::uint32_t seed) override;

  tasks::ScarfTask& task() noexcept { return task_; }
  /// The last rollout as the in-process task reports one (measured paths, camera image, scarf mesh if any).
  const tasks::ScarfRollout& lastRollout() const override { return last_; }

 private:
  /// Why the camera whose camera_info is `info` is not the task's; "" when it is.
  std::string cameraProblem(const sensor_msgs::CameraInfo& info);
  void onTorque(const sensor_msgs::JointStateConstPtr& message);
  /// Moves the arm to the task's start (a trajectory goal within half its velocity limits) unless it is there.
  void moveToStart();
  /// Runs the plan from the reset scene; fills last_'s measures.
  void runPlan(const tasks::ScarfPlan& plan);

  tasks::ScarfTask task_;
  ScarfRobotInterfaces robot_;
  tasks::ScarfRollout last_;
  double origin_ = 0.0;  ///< The robot's time of the last rollout's start (its goal's stamp) [s].
  std::mutex mutex_;     ///< Guards the torque window and its sums (written by the connection's spinner).
  double torque_from_ = 0.0, torque_to_ = -1.0;  ///< The motion's window of the robot's clock [s].
  double torque_sum_ = 0.0, torque_peak_ = 0.0;
  long torque_samples_ = 0;
  /// Goes second to last, its spinner with it, before anything its handlers write into.
  std::unique_ptr<RgbdReader> reader_;  ///< The colour camera as its camera_info last said (rollout thread).
  std::unique_ptr<RobotConnection> connection_;
  /// On the connection's node and queue: goes first (a throwing constructor too), before them.
  ros::Subscriber torque_sub_;
};

}  // namespace bimanual_skills::ros_layer
