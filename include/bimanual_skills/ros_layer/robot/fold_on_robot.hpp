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

#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "bimanual_skills/rollout/parallel_evaluator.hpp"
#include "bimanual_skills/ros_layer/robot/robot_connection.hpp"
#include "bimanual_skills/tasks/cloth_fold.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"

#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace bimanual_skills::ros_layer {

/// The fold's interfaces (fold_learner's ~ros_* parameters): the robot's, and how the fold uses them.
struct FoldRobotInterfaces : RobotInterfaces {
  /// "orthographic": the camera is the reward's own top-down map camera (bullet_sim's camera/...); "perspective": an
  /// RGB-D camera (rectified pinhole, any pose on tf, e.g. bullet_sim's rgbd/... or a Kinect) whose depth is
  /// re-projected into that map. The CameraInfo and the frame are checked against the model (camera_contract.hpp).
  std::string camera_model = "orthographic";
  std::string world_frame = "world";  ///< The frame of the reward's map (the table's world) on tf.
  /// The least share of the reward's map a perspective camera must see (points or filled gaps) for a rollout.
  double min_coverage = 0.8;
  /// To the fold's start configuration, at least [s of the robot's clock]: longer where a joint moves far (each
  /// segment within half the joints' velocity limits).
  double move_time = 2.0;
  double approach_height = 0.05;   ///< The tools come down onto the cloth from this far above their start [m].
  double trajectory_rate = 100.0;  ///< Points per second of the fold's trajectory goals.
  /// From sending the fold's goals to their common start [s of the robot's clock]; with a pause service the clock
  /// stands still from the grasp until both controllers have accepted them. A controller that gets its goal after the
  /// start skips the points already past (control_msgs' rule), which the path tolerance then fails.
  double start_delay = 0.5;
  /// A camera that sees the arms (a robot's): before the reset and before the scored images the arms go to their
  /// rest posture (the robot file's start), out of the camera's view, and the images are taken there.
  bool clear_view = false;

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

 private:
  /// The steps of a rollout; each throws RobotFault.
  /// Both arms from where they are to above the start, then onto the cloth, timed from the velocity limits.
  void moveToStart();
  /// Both arms from where they are to their rest posture, out of the camera's view (clear_view); the robot's when it
  /// fails.
  void moveClear(const std::string& what);
  /// Arm a's configuration near `q` (within 0.5 rad per joint) with the tool `height` [m] higher, by global IK
  /// seeded at q, into `out`; false (out untouched) when there is none.
  bool raised(int a, const Eigen::VectorXd& q, double height, Eigen::VectorXd& out) const;
  /// Runs the fold and opens the grippers; returns the time they opened at (as planned).
  ros::Time fold(const tasks::FoldPlan& plan);
  /// The camera's colour and depth images (and the cloth's cloud, if the robot has one and `with_cloth`) stamped at
  /// `after` or later, checked against the reward's camera; a perspective camera's re-projected into its map.
  struct Camera;
  Camera cameraImages(const ros::Time& after, bool with_cloth);
  /// The flat cloth after the reset: the fold reward's reference.
  void observeFlat(const ros::Time& after);
  /// The reward of the first images after `after`; the fold's quality from `settled_cloth` (the cloth at the task's
  /// settle time, when the images come later) or else from the cloth that came with the images.
  tasks::FoldRewardTerms observe(const ros::Time& after, double acceleration_cost,
                                 const sensor_msgs::PointCloud2ConstPtr& settled_cloth = nullptr);
  /// Why the camera whose camera_info is `info` cannot be used (its model, size, distortion, frame on tf); "" when
  /// it can. For a perspective camera, sets camera_ (intrinsics and pose).
  std::string cameraProblem(const sensor_msgs::CameraInfo& info);
  /// Reads a colour and depth pair with the reader made for `info` and `depth_info` (made anew when they changed);
  /// "" or why not. Caller holds mutex_.
  std::string read(const sensor_msgs::Image& image, const sensor_msgs::Image& depth,
                   const sensor_msgs::CameraInfo& info, const sensor_msgs::CameraInfo& depth_info, cv::Mat& bgr,
                   cv::Mat& metres);
  /// On the spinner: a camera frame or the cloth's cloud while a rollout records.
  void onFrame(const sensor_msgs::ImageConstPtr& image, const sensor_msgs::ImageConstPtr& depth);
  void onCloth(const sensor_msgs::PointCloud2ConstPtr& cloud);
  std::vector<Eigen::VectorXd> velocityLimits() const;

  tasks::ClothFoldTask task_;
  tasks::FoldReward reward_;
  FoldRobotInterfaces robot_;
  std::vector<Eigen::VectorXd> above_start_;  ///< Each arm's start configuration with the tool approach_height higher.
  std::vector<Eigen::VectorXd> rest_;         ///< Each arm's rest posture (clear_view).
  std::mutex mutex_;              ///< Guards the camera model and the recording (written by the connection's spinner).
  vision::PinholeCamera camera_;  ///< The perspective camera as last checked (under mutex_).
  std::unique_ptr<RgbdReader> reader_;    ///< Its images as the vision module takes them (under mutex_).
  vision::HeightMapProjector projector_;  ///< Its images into the reward's map.
  /// The same for the frames recorded during a rollout (spinner thread, under mutex_); null for an orthographic one.
  std::unique_ptr<vision::HeightMapProjector> recording_projector_;
  /// While a rollout records (from the fold's start, `record_start_`, to its images): the frames received.
  bool recording_frames_ = false;
  ros::Time record_start_;
  double next_image_ = 0.0, next_cloth_ = 0.0;
  tasks::FoldRollout recording_;
  double last_tracking_error_ = 0.0, last_robot_seconds_ = 0.0, last_move_seconds_ = 0.0;
  /// Last: it goes first, its spinner with it, before anything its handlers write into.
  std::unique_ptr<RobotConnection> connection_;
};

}  // namespace bimanual_skills::ros_layer
