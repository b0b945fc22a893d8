/// \file
/// The cloth fold as a rollout::RolloutTask that runs on a robot through ROS interfaces only, what a pair of real
/// arms with grippers and a camera provides (bullet_sim provides the same for the simulation):
///   - reset the scene: a std_srvs/Trigger service (bullet_sim's ~reset; on hardware the operator_prompt node, which
///     waits for a person to lay the cloth flat);
///   - both arms: each a FollowJointTrajectory action ARM/follow_joint_trajectory and its controller state ARM/state
///     (bimanual_skills/JointTrajectoryControllerState);
///   - the grippers: a bimanual_skills/ClothGrasp service (bullet_sim's ~grasp) that does a stamped command at its
///     time (the release is asked for before the fold starts and happens at the planned instant, at any load);
///   - the camera: colour (bgr8) and depth (32FC1, metres) sensor_msgs/Image with their sensor_msgs/CameraInfo;
///   - optionally the cloth's ground truth (sensor_msgs/PointCloud2 of its nodes, bullet_sim's ~cloth) for the fold
///     quality q; without it q is not measured (NaN);
///   - a simulator also offers a std_srvs/SetBool pause (bullet_sim's ~pause): its clock is held from the grasp
///     while the fold's goals travel, so that a clock many times faster than the wall cannot outrun them on a loaded
///     machine, and the cloth is held for start_delay exactly.
/// One rollout: reset, take the camera's images of the flat cloth (the fold reward's reference), move both arms to
/// the fold's start, grasp, run the policy's joint references (the DMPs through CLIK, tasks::ClothFoldTask::plan,
/// identical to the in-process task's) as one trajectory goal per arm with a common start time, release, let the
/// cloth settle, and score the camera's images with the reward (tasks::FoldReward). Any
/// failure (a goal aborted or out of tolerance, a service that fails, a timeout, no image) ends the rollout with its
/// outcome, a reason and the failure reward; nothing hangs: every wait has a wall-clock limit, service calls included
/// (ros_layer::callWithin). A failure of the robot (FoldOutcome::RobotFailed: an interface that failed or did not
/// answer) also rebuilds the action clients before the next rollout, which then waits for their servers. After any
/// failure once the arms moved, the robot recovers what it can on its own, each step bounded: the grippers open and
/// the arms go up to above their start (the reason says how it went), so a person has only the cloth to lay. Moves
/// between configurations are timed from the joints' velocity limits. Target
/// bimanual_skills_ros_robot. Offline: allocates; one object per thread.
#pragma once

#include "bimanual_skills/FollowJointTrajectoryAction.h"
#include "bimanual_skills/JointTrajectoryControllerState.h"
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "bimanual_skills/rollout/parallel_evaluator.hpp"
#include "bimanual_skills/tasks/cloth_fold.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"

#include <actionlib/client/simple_action_client.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace bimanual_skills::ros_layer {

/// Where the robot's interfaces are and how long a rollout may wait for them (fold_learner's ~ros_* parameters).
struct FoldRobotInterfaces {
  std::string reset_service = "bullet_sim/reset";  ///< std_srvs/Trigger
  std::string grasp_service = "bullet_sim/grasp";  ///< bimanual_skills/ClothGrasp
  /// std_srvs/SetBool pausing a simulator's clock while the fold's goals travel; "" on a robot (its clock is the
  /// wall's, and start_delay is their time on the way).
  std::string pause_service = "bullet_sim/pause";
  /// bimanual_skills/SimStep of a simulator: with the pause service, the fold runs as one ~step from the grasp to
  /// the settled cloth, so that the images and the cloth observed are of that moment exactly, however late this
  /// process reads them; "" on a robot (or to let the simulator run free).
  std::string step_service = "bullet_sim/step";
  std::vector<std::string> arms = {"left", "right"};  ///< Namespaces of the arms' actions and states, left first.
  std::string camera = "camera";  ///< CAMERA/image_raw, CAMERA/camera_info, CAMERA/depth/image_raw, ...
  /// "orthographic": the camera is the reward's own top-down map camera (bullet_sim's camera/...); "perspective": an
  /// RGB-D camera (rectified pinhole, any pose on tf, e.g. bullet_sim's rgbd/... or a Kinect) whose depth is
  /// re-projected into that map. The CameraInfo and the frame are checked against the model (camera_contract.hpp).
  std::string camera_model = "orthographic";
  std::string world_frame = "world";  ///< The frame of the reward's map (the table's world) on tf.
  /// The least share of the reward's map a perspective camera must see (points or filled gaps) for a rollout.
  double min_coverage = 0.8;
  std::string cloth = "bullet_sim/cloth";  ///< Ground truth of the cloth; "" when the robot has none.
  /// Parameter where a simulator gives the digest of its world (sim::SimConfig::worldDigest): the task refuses to
  /// start when it differs from the learning's simulation file. Absent (a real robot) or "": not checked.
  std::string world_digest = "bullet_sim/world_digest";
  /// To the fold's start configuration, at least [s of the robot's clock]: longer where a joint moves far (each
  /// segment within half the joints' velocity limits).
  double move_time = 2.0;
  double approach_height = 0.05;   ///< The tools come down onto the cloth from this far above their start [m].
  double trajectory_rate = 100.0;  ///< Points per second of the fold's trajectory goals.
  /// From sending the fold's goals to their common start [s of the robot's clock]; with a pause service the clock
  /// stands still from the grasp until both controllers have accepted them. A controller that gets its goal after the
  /// start skips the points already past (control_msgs' rule), which the path tolerance then fails.
  double start_delay = 0.5;
  /// Longest wall-clock wait for any one interface [s], service calls included; a wait for the robot's motion counts
  /// it from the robot clock's last step (a 0.1x simulator or a long motion on hardware does not time out).
  double timeout = 30.0;
  /// Longest wall-clock wait for the reset service [s]: the one deliberately longer wait, since on hardware a person
  /// lays the cloth flat: longer than operator_prompt's ~timeout (600 s), so that its refusal comes across.
  double reset_timeout = 660.0;

  /// \throws std::invalid_argument naming the field that is out of range.
  void validate() const;
};

class FoldOnRobotTask : public rollout::RolloutTask, public rollout::RecordedFoldTask {
 public:
  /// Builds the task (the policy's encoding and references as rollout::FoldRolloutTask), connects to the
  /// interfaces and waits up to `robot.timeout` for the actions and the pause service. \throws
  /// std::invalid_argument for a bad configuration, std::runtime_error when an action server or the pause service
  /// (if one is named) does not appear.
  FoldOnRobotTask(const tasks::ClothFoldConfig& task, const tasks::FoldRewardConfig& reward,
                  const FoldRobotInterfaces& robot);
  ~FoldOnRobotTask() override;

  std::vector<std::string> termNames() const override;
  Eigen::VectorXd initialParameters() const override;
  /// One rollout on the robot. The seed does not enter (the robot has its own noise): the same policy gives a
  /// statistically, not bitwise, equal rollout. Its trajectory summary holds the measured tool paths, 3 rows per arm.
  rollout::RolloutResult run(const Eigen::VectorXd& parameters, std::uint32_t seed) override;

  /// The largest joint tracking error the arms' controllers reported during the last rollout's fold [rad].
  double lastTrackingError() const noexcept { return last_tracking_error_; }
  /// The robot's clock time the last rollout took from the start of the move to the start to its images (0 for a
  /// failed one) [s].
  double lastRobotSeconds() const noexcept { return last_robot_seconds_; }
  /// What the last rollout received, times from the fold's start: the measured joints and tool paths, the camera's
  /// images every kImagePeriod of the robot's clock from the fold's start to the images scored (those last), and the
  /// cloth's ground truth every kClothPeriod (when the robot has it).
  const tasks::FoldRollout& lastRecording() const override { return recording_; }
  static constexpr double kImagePeriod = 0.25, kClothPeriod = 0.05;  ///< [s of the robot's clock]
  /// A camera or cloth message stamped further ahead of this process's clock [s] is of another timeline (a
  /// simulator's, before its reset) and not used.
  static constexpr double kAheadOfClock = 0.5;

 private:
  struct Arm;
  struct Failure;
  /// The steps of a rollout; each throws Failure.
  /// The reset; returns the robot's time of the reset scene's third state.
  ros::Time reset();
  /// Both arms from where they are to above the start, then onto the cloth, timed from the velocity limits.
  void moveToStart();
  /// The shortest time (at least `shortest`) for both arms to move between configurations as rest-to-rest quintics
  /// within half their velocity limits [s].
  double moveTime(const std::vector<Eigen::VectorXd>& from, const std::vector<Eigen::VectorXd>& to,
                  double shortest) const;
  /// Both arms' last measured positions; throws Failure before any state came.
  std::vector<Eigen::VectorXd> measuredPositions();
  /// After a failed rollout that moved the robot: opens the grippers and lifts the arms to above their start, each
  /// step bounded (kRecoveryTimeout); says what it did.
  std::string recover() noexcept;
  void grasp(bool close);
  /// Runs the fold and opens the grippers; returns the time they opened at (as planned).
  ros::Time fold(const tasks::FoldPlan& plan);
  /// Asks the grippers to open at `release` of the robot's clock (a stamped ClothGrasp the gripper's loop keeps);
  /// throws Failure when the service does it at another time.
  void scheduleRelease(const ros::Time& release);
  void waitUntil(const ros::Time& time, const char* what);
  /// Pauses or resumes the simulator's clock (pause_service); pausing waits until the clock here has reached the
  /// paused time.
  void pause(bool paused);
  /// After a failed rollout: resumes a simulator this task paused, if it is still there, without waiting for it.
  void resumeAfterFailure() noexcept;
  void waitForGoal(Arm& arm, const std::string& what);
  /// The camera's colour and depth images (and the cloth's cloud, if the robot has one and `with_cloth`) stamped at
  /// `after` or later, checked against the reward's camera; a perspective camera's re-projected into its map.
  struct Camera;
  Camera cameraImages(const ros::Time& after, bool with_cloth);
  /// The flat cloth after the reset: the fold reward's reference.
  void observeFlat(const ros::Time& after);
  tasks::FoldRewardTerms observe(const ros::Time& after, double acceleration_cost);
  /// Polls `done` for at most `timeout` of wall time; with `while_clock_runs` (a wait for the robot's motion) the
  /// limit counts from the robot clock's last step instead, so a slow simulator or a long motion does not time out
  /// while a stopped one does. Throws Failure (RobotFailed) naming `what`.
  template <typename Done>
  void waitFor(const Done& done, const std::string& what, bool while_clock_runs = false);
  /// Calls `service` (a service's name) within `timeout`; throws Failure (RobotFailed) naming `what` when there is
  /// no server, the call fails or no answer comes in time. The response's own success is the caller's to check.
  template <typename Service>
  void call(const std::string& service, Service& request, double timeout, const std::string& what);
  /// New action clients for both arms, and the wait for their servers.
  void connectArms();
  /// Throws std::runtime_error when a simulator says it runs another world than `sim_config`.
  void checkWorld(const std::string& sim_config, const std::string& robot) const;
  /// Why the camera whose camera_info is `info` cannot be used (its model, size, distortion, frame on tf); "" when
  /// it can. For a perspective camera, sets camera_ (intrinsics and pose).
  std::string cameraProblem(const sensor_msgs::CameraInfo& info);
  /// Under mutex_: whether a camera or cloth message stamped `stamp` belongs to the scene since the last reset.
  bool sceneCounts(double stamp);

  tasks::ClothFoldTask task_;
  tasks::FoldReward reward_;
  FoldRobotInterfaces robot_;
  ros::CallbackQueue queue_;
  std::unique_ptr<ros::NodeHandle> node_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  std::vector<std::unique_ptr<Arm>> arms_;
  ros::Subscriber image_sub_, depth_sub_, info_sub_, cloth_sub_;
  std::mutex mutex_;  ///< Guards the latest messages below (written by the spinner's threads).
  sensor_msgs::ImageConstPtr image_, depth_;
  sensor_msgs::CameraInfoConstPtr info_;
  sensor_msgs::PointCloud2ConstPtr cloth_;
  /// The camera's and the cloth's messages across a reset (under mutex_), as the arms' states: the latest stamp seen,
  /// and the window that does not count while a reset runs (see reset()); outside a reset everything counts.
  double scene_last_stamp_ = -std::numeric_limits<double>::infinity();
  double scene_before_reset_ = std::numeric_limits<double>::infinity();
  double scene_reset_answered_ = std::numeric_limits<double>::infinity();
  tf2_ros::Buffer tf_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  vision::PinholeCamera camera_;          ///< The perspective camera as last checked (under mutex_).
  vision::HeightMapProjector projector_;  ///< Its images into the reward's map.
  /// The same for the frames recorded during a rollout (spinner thread, under mutex_); null for an orthographic one.
  std::unique_ptr<vision::HeightMapProjector> recording_projector_;
  /// While a rollout records (from the fold's start, `record_start_`, to its images): the frames received.
  bool recording_frames_ = false;
  ros::Time record_start_;
  double next_image_ = 0.0, next_cloth_ = 0.0;
  tasks::FoldRollout recording_;
  double last_tracking_error_ = 0.0, last_robot_seconds_ = 0.0, last_move_seconds_ = 0.0;
  bool paused_ = false;     ///< Whether this task paused the simulator (and must resume it).
  double paused_at_ = 0.0;  ///< The simulator's time when it last paused [s].
  bool reconnect_ = false;  ///< The last rollout failed on the robot: new action clients before the next.
};

}  // namespace bimanual_skills::ros_layer
