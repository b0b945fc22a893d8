/// \file
/// What a rollout on a robot needs of its ROS interfaces, whatever the task: each arm's FollowJointTrajectory action
/// and controller state, the scene's reset (a std_srvs/Trigger), the grippers (bimanual_skills/ClothGrasp, stamped
/// commands kept by the gripper's loop), a simulator's pause and step, the camera's colour, depth and CameraInfo, and
/// optionally the cloth's ground truth (sensor_msgs/PointCloud2). Every wait has a wall-clock limit, service calls
/// included (ServiceCaller); a wait for the robot's motion counts it from the controllers' last state. A step that
/// fails throws RobotFault with its outcome and the reason. Messages across a reset count as the reset scene's only
/// once they are of it (a simulator's clock goes back, a robot's goes on), however late this process reads them. Used
/// by FoldOnRobotTask and ScarfOnRobotTask. Target bimanual_skills_ros_robot. Offline: allocates; one object per thread
/// of rollouts.
#pragma once

#include "bimanual_skills/FollowJointTrajectoryAction.h"
#include "bimanual_skills/JointTrajectoryControllerState.h"
#include "bimanual_skills/kinematics/chain_model.hpp"
#include "bimanual_skills/ros_layer/bounded_call.hpp"
#include "bimanual_skills/ros_layer/rgbd_reader.hpp"
#include "bimanual_skills/tasks/cloth_fold.hpp"

#include <actionlib/client/simple_action_client.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <atomic>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

namespace bimanual_skills::ros_layer {

/// A failed step of a rollout on the robot: how it ended and why.
struct RobotFault {
  tasks::FoldOutcome outcome;
  std::string reason;
};

/// Where the robot's interfaces are and how long a rollout may wait for them (the learners' ~ros_* parameters).
struct RobotInterfaces {
  std::string reset_service = "bullet_sim/reset";  ///< std_srvs/Trigger
  std::string grasp_service = "bullet_sim/grasp";  ///< bimanual_skills/ClothGrasp
  /// std_srvs/SetBool pausing a simulator's clock while a rollout's goals travel; "" on a robot (its clock is the
  /// wall's, and start_delay is their time on the way).
  std::string pause_service = "bullet_sim/pause";
  /// bimanual_skills/SimStep of a simulator: with the pause service, the rollout runs as one ~step from its start to
  /// its images, so that the images and the cloth observed are of that moment exactly, however late this process
  /// reads them; "" on a robot (or to let the simulator run free).
  std::string step_service = "bullet_sim/step";
  std::vector<std::string> arms = {"left", "right"};  ///< Namespaces of the arms' actions and states, left first.
  std::string camera = "camera";  ///< CAMERA/image_raw and CAMERA/camera_info: the colour camera (raw or rectified).
  /// CAMERA/DEPTH/image_raw and CAMERA/DEPTH/camera_info: "depth" (the depth camera's own frame, or a simulator's
  /// one camera) or "depth_registered" (registered to the colour camera by the driver).
  std::string depth = "depth";
  /// Depth on a frame other than the colour camera's is registered here from tf (RgbdReader); false: refused.
  bool register_depth = false;
  std::string cloth = "bullet_sim/cloth";  ///< Ground truth of the cloth; "" when the robot has none.
  /// Parameter where a simulator gives the digest of its world (sim::SimConfig::worldDigest): the task refuses to
  /// start when it differs from the learning's simulation file. Absent (a real robot) or "": not checked.
  std::string world_digest = "bullet_sim/world_digest";
  /// Longest wall-clock wait for any one interface [s], service calls included; a wait for the robot's motion counts
  /// it from the robot clock's last step (a 0.1x simulator or a long motion on hardware does not time out).
  double timeout = 30.0;
  /// Longest wall-clock wait for the reset service [s]: the one deliberately longer wait, since on hardware a person
  /// sets the scene: longer than operator_prompt's ~timeout (600 s), so that its refusal comes across.
  double reset_timeout = 660.0;

  /// \throws std::invalid_argument naming the field that is out of range, after `what` ("fold on the robot").
  void validate(const std::string& what) const;
};

class RobotConnection {
 public:
  using Client = actionlib::SimpleActionClient<bimanual_skills::FollowJointTrajectoryAction>;
  /// A colour and a depth image of one stamp of the scene since the last reset, as they come (on the spinner).
  using FrameHandler =
      std::function<void(const sensor_msgs::ImageConstPtr& colour, const sensor_msgs::ImageConstPtr& depth)>;
  /// A cloth cloud of the scene since the last reset, as it comes (on the spinner).
  using ClothHandler = std::function<void(const sensor_msgs::PointCloud2ConstPtr& cloud)>;

  /// One arm's action and the states its controller reported.
  struct Arm {
    std::string name;
    std::vector<std::string> joints;
    std::unique_ptr<Client> client;
    bool goal_sent = false;  ///< Whether `client` has sent a goal (one it may have to cancel).
  };
  /// The latest camera messages (and the cloth's cloud) of one moment.
  struct Frame {
    sensor_msgs::ImageConstPtr image, depth;
    sensor_msgs::CameraInfoConstPtr info, depth_info;
    sensor_msgs::PointCloud2ConstPtr cloth;
  };
  /// The states recorded since record(true): per arm their stamps, positions, and the largest tracking error.
  struct Recorded {
    std::vector<std::vector<double>> times;
    std::vector<std::vector<Eigen::VectorXd>> positions;
    double max_error = 0.0;
    /// The indices of the samples every arm has (their states share the controllers' stamps), thinned to about
    /// `rate` per second of their stamps.
    std::vector<std::size_t> every(double rate) const;
  };

  /// Subscribes, waits up to `robot.timeout` for the pause service (if one is named: the simulator is resumed) and
  /// the camera's first CameraInfo, and checks the simulator's world against `sim_config` on `robot_file`; the arms'
  /// actions come with connectArms(). `joints[a]` are arm a's joint names. \throws std::runtime_error with the reason
  /// (after `what`).
  RobotConnection(const RobotInterfaces& robot, std::vector<std::vector<std::string>> joints, const std::string& what,
                  const std::string& sim_config, const std::string& robot_file, FrameHandler on_frame,
                  ClothHandler on_cloth);
  ~RobotConnection();
  RobotConnection(const RobotConnection&) = delete;
  RobotConnection& operator=(const RobotConnection&) = delete;

  ros::NodeHandle& node() { return *node_; }
  const RobotInterfaces& interfaces() const noexcept { return robot_; }
  std::size_t arms() const noexcept { return arms_.size(); }
  Arm& arm(std::size_t a) { return *arms_[a]; }
  /// The camera's first CameraInfo (from the constructor).
  const sensor_msgs::CameraInfo& firstCameraInfo() const { return *first_info_; }
  /// A reader of the camera for `info` (colour only) or for `info` and `depth_info`, the transform between their
  /// frames from tf when they differ; 	hrows std::runtime_error with the reason it cannot read them.
  RgbdReader reader(const sensor_msgs::CameraInfo& info, const sensor_msgs::CameraInfo* depth_info);
  /// The depth camera's first CameraInfo, waiting up to the timeout for it; throws RobotFault when none comes.
  sensor_msgs::CameraInfo firstDepthInfo();

  /// Polls `done` for at most the timeout of wall time. Throws RobotFault (RobotFailed) naming `what`.
  void waitFor(const std::function<bool()>& done, const std::string& what);
  /// A wait for the robot's motion: polls `done` while every arm's controller keeps sending states of new stamps,
  /// at most the timeout of wall time after the last such state of the slowest arm (a robot on the wall clock
  /// whose controller stalls is found as one on a simulator's clock that stops), and, unless `ends_by` is zero,
  /// until the states' stamps pass `ends_by` + timeout (a goal that should have ended). Throws RobotFault
  /// (RobotFailed) naming `what` and which bound ran out.
  void waitWhileMoving(const std::function<bool()>& done, const std::string& what, const ros::Time& ends_by);
  /// Calls `service` (a service's name) within `timeout` (ServiceCaller::call); throws RobotFault (RobotFailed)
  /// naming `what` when there is no server, the call fails, its last call is unanswered or no answer comes in time.
  /// The response's own success is the caller's to check.
  template <typename Service>
  void call(const std::string& service, Service& request, double timeout, const std::string& what,
            Retry retry = Retry::IfDropped, const std::function<bool()>& progressed = {}) {
    const CallOutcome outcome = caller_->call(service, request, timeout, retry, progressed);
    if (outcome == CallOutcome::Answered) return;
    std::ostringstream message;
    message << what << " (" << caller_->resolve(service) << "): " << describe(outcome);
    if (outcome != CallOutcome::Failed && outcome != CallOutcome::Busy) message << " within " << timeout << " s";
    throw RobotFault{tasks::FoldOutcome::RobotFailed, message.str()};
  }
  /// Before a rollout: waits up to the timeout for the calls of the last one still unanswered and cancels its
  /// goals, so that nothing the robot runs late reaches into this rollout; throws RobotFault (RobotFailed) when a
  /// call is still unanswered.
  void settle();

  /// New action clients for the arms, and the wait for their servers (a simulator must be running: paused, its
  /// actions publish no status). \throws RobotFault with the reason.
  void connectArms();
  /// Resets the scene and waits for the arms' states of it; returns the robot's time of the reset scene's third
  /// state.
  ros::Time reset();
  /// Closes or opens arm a's gripper now (GraspFailed when closing grasps nothing).
  void grasp(std::size_t a, bool close);
  /// Asks arm a's gripper to open at `release` of the robot's clock; throws when the service does it at another time.
  void scheduleRelease(std::size_t a, const ros::Time& release);
  /// Pauses or resumes the simulator's clock (pause_service); pausing waits until the clock here has reached the
  /// paused time.
  void pause(bool paused);
  bool paused() const noexcept { return paused_; }
  double pausedAt() const noexcept { return paused_at_; }
  /// After a failed rollout: resumes a simulator this object paused, if it is still there, without waiting for it.
  void resumeAfterFailure() noexcept;
  /// Steps a paused simulator to `until` [s of its clock] at `dt` per step; throws with the reason.
  void stepUntil(double until, double dt, const std::string& what);
  void waitUntil(const ros::Time& time, const std::string& what);
  /// Whose failure a goal that does not succeed is: the robot's (a move before the policy's first point), or the
  /// policy's unless the robot's loop or states stopped while it ran.
  enum class Blame { Robot, Policy };
  /// Waits for arm a's goal to end (waitWhileMoving, its motion due to end by `ends_by` of the robot's clock; zero:
  /// unbounded by the stamps): RobotFailed when its server goes or the failure is the robot's (see Blame: a result
  /// saying the control loop stopped or its states were stale, or states more than 0.1 s apart while it ran),
  /// ControllerFailed when the policy's goal does not succeed.
  void waitForGoal(std::size_t a, const std::string& what, const ros::Time& ends_by, Blame blame);
  /// Whether arm a's server went or its goal ended other than SUCCEEDED; whether its controller answered the goal.
  bool goalFailed(std::size_t a) const;
  bool goalAnswered(std::size_t a) const;
  /// Waits (the timeout) until every arm's controller has answered its goal (accepted or refused it): on a simulator
  /// this object paused, before its clock goes on; on a robot before `start`, or the goals came late (a transport
  /// slow for the start's delay `delay`: RobotFailed, the robot's). `what` names the goals.
  void waitForAnswers(const ros::Time& start, double delay, const std::string& what);
  /// Sends `goal` to arm a's controller.
  void sendGoal(std::size_t a, const bimanual_skills::FollowJointTrajectoryGoal& goal);
  /// Cancels every arm's goal that has not ended.
  void cancelGoals();
  /// Every arm's last measured positions; throws before any state came.
  std::vector<Eigen::VectorXd> measuredPositions();
  /// After a failed rollout that moved the robot: opens the grippers, then moves the arms to `targets` timed from
  /// the velocity limits `limits`, each step bounded by `timeout`; says how it went, with `moved` or `not_moved`.
  std::string recover(const std::vector<Eigen::VectorXd>& targets, const std::vector<Eigen::VectorXd>& limits,
                      double timeout, const std::string& moved, const std::string& not_moved) noexcept;

  /// Starts (clearing what was recorded) or stops recording the arms' states.
  void record(bool on);
  Recorded recorded();

  /// The frame every task's rollout shares. Before one: nothing of the last rollout still under way (settle()), a
  /// simulator left paused going on (a learner stopped while it stood still: paused, it publishes no states and its
  /// actions no status, so a reconnect could not connect), and new action clients when the last rollout failed on
  /// the robot. Throws RobotFault.
  void beginRollout();
  /// After a rollout that failed with `outcome`: cancels the goals, has the next rollout connect anew when the
  /// failure was the robot's, resumes a simulator this object paused, and when the robot had moved (`moved`)
  /// recovers as recover() does. Returns "; recovery: " and how it went, or "" when the robot had not moved.
  std::string endFailedRollout(tasks::FoldOutcome outcome, bool moved, const std::vector<Eigen::VectorXd>& targets,
                               const std::vector<Eigen::VectorXd>& limits, double timeout,
                               const std::string& at_targets, const std::string& not_at_targets) noexcept;
  /// The arms' states recorded since record(true), thinned to about `rate` per second (Recorded::every): their times
  /// from `origin` [s of the robot's clock], and per arm its joints (one column per sample) and its tool's positions
  /// in the world (forward kinematics of `models[a]` placed at `bases[a]`). Stops the recording.
  struct MeasuredPaths {
    Eigen::VectorXd times;
    std::vector<Eigen::MatrixXd> joints;
    std::vector<Eigen::Matrix3Xd> tools;
    double max_error = 0.0;  ///< Recorded::max_error
  };
  MeasuredPaths measuredPaths(double rate, const std::vector<const kinematics::ChainModel*>& models,
                              const std::vector<Eigen::Isometry3d>& bases, double origin);
  /// The camera's colour, depth and CameraInfo of one moment (within 20 ms), and the cloth's cloud if
  /// `with_cloth` and the robot has one, stamped at `after` or later and not ahead of this process' clock.
  Frame frame(const ros::Time& after, bool with_cloth);

  /// The shortest time (at least `shortest`) to move between configurations as rest-to-rest quintics within half
  /// the joints' velocity limits `limits[a]` [s].
  static double moveTime(const std::vector<Eigen::VectorXd>& from, const std::vector<Eigen::VectorXd>& to,
                         const std::vector<Eigen::VectorXd>& limits, double shortest);

  /// The pose of `info`'s frame in `world_frame` from tf (waiting up to the timeout); "" or why there is none.
  std::string cameraPose(const sensor_msgs::CameraInfo& info, const std::string& world_frame, Eigen::Isometry3d& pose);

  /// The cloth's nodes of a point cloud with float x, y, z fields; false for a cloud without them.
  static bool cloudVertices(const sensor_msgs::PointCloud2& cloud, Eigen::Matrix3Xd& vertices);

  /// A camera or cloth message stamped further ahead of the robot's clock (its arms' latest states) [s] is of
  /// another timeline (a simulator's, before its reset) and not used.
  static constexpr double kAheadOfClock = 0.5;

 private:
  struct ArmState;
  /// Moves the arms to `targets` in `time` [s] and waits at most `time + timeout` of wall time (the recovery after
  /// a failure, on a robot that may be down): whether every arm got there. Throws when an arm is gone.
  bool moveWithin(const std::vector<Eigen::VectorXd>& targets, double time, double timeout);
  /// The arms' controller states so far: how many of new stamps (in all, and of the arm with the fewest), and the
  /// newest stamp.
  struct Progress {
    long states = 0, slowest = std::numeric_limits<long>::max();
    double stamp = -std::numeric_limits<double>::infinity();
  };
  Progress progress();
  /// Opens every gripper within `timeout` each; says how it went ("left's gripper opened, ...").
  std::string openGrippers(double timeout) noexcept;
  void checkWorld(const std::string& what, const std::string& sim_config, const std::string& robot_file) const;
  /// Under mutex_: whether a camera or cloth message stamped `stamp` belongs to the scene since the last reset.
  bool sceneCounts(double stamp);

  RobotInterfaces robot_;
  FrameHandler on_frame_;
  ClothHandler on_cloth_;
  ros::CallbackQueue queue_;
  std::unique_ptr<ros::NodeHandle> node_;
  std::unique_ptr<ServiceCaller> caller_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;
  std::vector<std::unique_ptr<Arm>> arms_;
  std::vector<std::unique_ptr<ArmState>> states_;
  ros::Subscriber image_sub_, depth_sub_, info_sub_, depth_info_sub_, cloth_sub_;
  std::vector<ros::Subscriber> state_subs_;
  std::mutex mutex_;  ///< Guards the latest messages and the arms' states (written by the spinner's threads).
  sensor_msgs::ImageConstPtr image_, depth_;
  sensor_msgs::CameraInfoConstPtr info_, first_info_, depth_info_, first_depth_info_;
  sensor_msgs::PointCloud2ConstPtr cloth_;
  /// The camera's and the cloth's messages across a reset (under mutex_), as the arms' states: the latest stamp seen,
  /// and the window that does not count while a reset runs (see reset()); outside a reset everything counts.
  double scene_last_stamp_ = -std::numeric_limits<double>::infinity();
  double scene_before_reset_ = std::numeric_limits<double>::infinity();
  double scene_reset_answered_ = std::numeric_limits<double>::infinity();
  tf2_ros::Buffer tf_;
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  std::atomic<bool> paused_{false};  ///< Whether this object paused the simulator (and must resume it).
  bool reconnect_ = false;           ///< The last rollout failed on the robot: new action clients before the next.
  double paused_at_ = 0.0;           ///< The simulator's time when it last paused [s].
};

}  // namespace bimanual_skills::ros_layer
