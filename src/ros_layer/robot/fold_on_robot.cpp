#include "bimanual_skills/ros_layer/robot/fold_on_robot.hpp"

#include "bimanual_skills/ClothGrasp.h"
#include "bimanual_skills/SimStep.h"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "bimanual_skills/ros_layer/bounded_call.hpp"
#include "bimanual_skills/ros_layer/camera_contract.hpp"
#include "bimanual_skills/sim/sim_config.hpp"

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <tf2_eigen/tf2_eigen.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace bimanual_skills::ros_layer {

namespace {

using Client = actionlib::SimpleActionClient<bimanual_skills::FollowJointTrajectoryAction>;

/// Wall-clock pause between polls of a wait [s]: short against a rollout, long against the spinner's work.
constexpr double kPoll = 0.002;
/// Controller states of each arm to wait for after a reset before commanding the arms.
constexpr std::uint64_t kStatesAfterReset = 3;
/// Share of move_time spent reaching the configuration above the start (the rest: coming down onto the cloth).
constexpr double kApproachShare = 0.7;
/// Samples per second of the measured tool paths in a result.
constexpr double kPathRate = 50.0;
/// Longest wait for resuming a simulator after a failed rollout [s]: the next rollout resumes it anyway.
constexpr double kResumeTimeout = 2.0;
/// Longest wait for each step of the recovery after a failed rollout [s of wall time, beyond the motion's own
/// duration]: it is done on a robot that may be down.
constexpr double kRecoveryTimeout = 3.0;
/// Share of a joint's velocity limit a move between configurations may reach.
constexpr double kMoveSpeedShare = 0.5;
/// Peak over mean speed of a rest-to-rest quintic.
constexpr double kQuinticPeak = 1.875;

const char* errorName(int code) {
  switch (code) {
    case bimanual_skills::FollowJointTrajectoryResult::SUCCESSFUL:
      return "SUCCESSFUL";
    case bimanual_skills::FollowJointTrajectoryResult::INVALID_GOAL:
      return "INVALID_GOAL";
    case bimanual_skills::FollowJointTrajectoryResult::INVALID_JOINTS:
      return "INVALID_JOINTS";
    case bimanual_skills::FollowJointTrajectoryResult::OLD_HEADER_TIMESTAMP:
      return "OLD_HEADER_TIMESTAMP";
    case bimanual_skills::FollowJointTrajectoryResult::PATH_TOLERANCE_VIOLATED:
      return "PATH_TOLERANCE_VIOLATED";
    case bimanual_skills::FollowJointTrajectoryResult::GOAL_TOLERANCE_VIOLATED:
      return "GOAL_TOLERANCE_VIOLATED";
    default:
      return "unknown error code";
  }
}

trajectory_msgs::JointTrajectoryPoint point(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                            const Eigen::VectorXd& qdd, double t) {
  trajectory_msgs::JointTrajectoryPoint p;
  p.positions.assign(q.data(), q.data() + q.size());
  p.velocities.assign(qd.data(), qd.data() + qd.size());
  p.accelerations.assign(qdd.data(), qdd.data() + qdd.size());
  p.time_from_start = ros::Duration(t);
  return p;
}

}  // namespace

void FoldRobotInterfaces::validate() const {
  const auto fail = [](const std::string& what) { throw std::invalid_argument("fold on the robot: " + what); };
  if (reset_service.empty() || grasp_service.empty()) fail("the reset and grasp services need names");
  if (arms.size() != 2) fail("two arms (left, right) are needed, " + std::to_string(arms.size()) + " given");
  if (camera.empty()) fail("the camera needs a namespace");
  try {
    cameraModel(camera_model);
  } catch (const std::invalid_argument& e) {
    fail(e.what());
  }
  if (world_frame.empty()) fail("the world frame needs a name");
  if (!(min_coverage >= 0.0) || !(min_coverage <= 1.0)) fail("min_coverage must lie in [0, 1]");
  if (!(move_time > 0.0) || !std::isfinite(move_time)) fail("move_time must be finite and > 0");
  if (!(approach_height >= 0.0) || !(approach_height <= 0.5)) fail("approach_height must lie in [0, 0.5] m");
  if (!(trajectory_rate >= 1.0) || !(trajectory_rate <= 1000.0)) fail("trajectory_rate must lie in [1, 1000] Hz");
  if (!(start_delay >= 0.0) || !(start_delay <= 10.0)) fail("start_delay must lie in [0, 10] s");
  if (!(timeout > 0.0) || !std::isfinite(timeout)) fail("timeout must be finite and > 0");
  if (!(reset_timeout > 0.0) || !std::isfinite(reset_timeout)) fail("reset_timeout must be finite and > 0");
}

namespace {

/// The cloth's nodes of a point cloud with float x, y, z fields; false for a cloud without them.
bool cloudVertices(const sensor_msgs::PointCloud2& cloud, Eigen::Matrix3Xd& vertices) {
  try {
    vertices.resize(3, static_cast<Eigen::Index>(cloud.width) * cloud.height);
    sensor_msgs::PointCloud2ConstIterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z");
    for (Eigen::Index i = 0; i < vertices.cols(); ++i, ++x, ++y, ++z) vertices.col(i) << *x, *y, *z;
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

/// Appends a camera frame at time t to a recording.
void addFrame(tasks::FoldRollout& recording, double t, const cv::Mat& bgr, const cv::Mat& depth) {
  recording.camera_colour.push_back(bgr);
  recording.camera_depth.push_back(depth);
  recording.camera_times.conservativeResize(recording.camera_times.size() + 1);
  recording.camera_times[recording.camera_times.size() - 1] = t;
}

}  // namespace

/// A failed step of a rollout: how it ended and why.
struct FoldOnRobotTask::Failure {
  tasks::FoldOutcome outcome;
  std::string reason;
};

/// One arm's trajectory action and controller state.
struct FoldOnRobotTask::Arm {
  std::string name;
  std::vector<std::string> joints;
  Eigen::VectorXd above_start;  ///< The start configuration with the tool approach_height higher.
  std::unique_ptr<Client> client;
  ros::Subscriber state_sub;
  // Written by the spinner (guarded by the task's mutex): the last state, the reset's count, and while a fold runs its
  // samples.
  Eigen::VectorXd actual;  ///< The last measured positions (empty before a state came).
  double stamp = -std::numeric_limits<double>::infinity();  ///< Of the last state [s].
  /// Around a reset: the last stamp before it and when it answered, and the states since that are the reset
  /// scene's (a clock gone back, or on past the answer), with the last one's stamp.
  double before_reset = -std::numeric_limits<double>::infinity();
  double reset_answered = std::numeric_limits<double>::infinity(), after_reset_stamp = 0.0;
  int after_reset = 0;
  bool recording = false;
  std::vector<double> times;
  std::vector<Eigen::VectorXd> positions;
  double max_error = 0.0;
};

FoldOnRobotTask::FoldOnRobotTask(const tasks::ClothFoldConfig& task, const tasks::FoldRewardConfig& reward,
                                 const FoldRobotInterfaces& robot)
    : task_(task),
      reward_(
          [&] {
            // The camera of the simulation's reward (bullet_sim publishes the same), with the learner's settings.
            tasks::FoldRewardConfig r = reward;
            r.renderer = tasks::rendererFor(task_.simConfig());
            r.renderer.noise = reward.renderer.noise;
            return r;
          }(),
          task_.simConfig().cloth.length * task_.simConfig().cloth.width, task_.idealFoldVertices(),
          task_.clothTriangles()),
      robot_(robot),
      projector_(reward_.config().renderer.camera) {
  robot_.validate();
  tf_listener_ = std::make_unique<tf2_ros::TransformListener>(tf_);
  if (cameraModel(robot_.camera_model) == CameraModel::Perspective) {
    recording_projector_ = std::make_unique<vision::HeightMapProjector>(reward_.config().renderer.camera);
  }
  node_ = std::make_unique<ros::NodeHandle>();
  node_->setCallbackQueue(&queue_);
  const std::string camera = robot_.camera + "/";
  const auto keep = [this](auto& slot) {
    return [this, &slot](const auto& message) {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (sceneCounts(message->header.stamp.toSec())) slot = message;
    };
  };
  image_sub_ = node_->subscribe<sensor_msgs::Image>(camera + "image_raw", 2, keep(image_));
  // While a rollout records: a colour and depth pair of one stamp every kImagePeriod (the depth image comes second).
  depth_sub_ = node_->subscribe<sensor_msgs::Image>(
      camera + "depth/image_raw", 2, [this](const sensor_msgs::ImageConstPtr& depth) {
        sensor_msgs::ImageConstPtr image;
        double t = 0.0;
        {
          const std::lock_guard<std::mutex> lock(mutex_);
          if (!sceneCounts(depth->header.stamp.toSec())) return;
          depth_ = depth;
          t = (depth->header.stamp - record_start_).toSec();
          if (!recording_frames_ || !image_ || image_->header.stamp != depth->header.stamp || t < next_image_) return;
          next_image_ = t + kImagePeriod;
          image = image_;
        }
        try {
          cv::Mat bgr = cv_bridge::toCvCopy(image, "bgr8")->image, metres = cv_bridge::toCvCopy(depth, "32FC1")->image;
          const std::lock_guard<std::mutex> lock(mutex_);
          if (!recording_frames_) return;  // no longer this rollout's
          if (recording_projector_) {      // a perspective camera's frames as the reward's map shows them
            if (recording_projector_->project(bgr, metres, camera_) != vision::VisionStatus::Ok) return;
            bgr = recording_projector_->bgr().clone();
            metres = recording_projector_->depth().clone();
          }
          addFrame(recording_, t, bgr, metres);
        } catch (const cv_bridge::Exception&) {
          // An image of another encoding: observe() fails the rollout with the reason.
        }
      });
  info_sub_ = node_->subscribe<sensor_msgs::CameraInfo>(camera + "camera_info", 2, keep(info_));
  if (!robot_.cloth.empty()) {
    cloth_sub_ = node_->subscribe<sensor_msgs::PointCloud2>(
        robot_.cloth, 2, [this](const sensor_msgs::PointCloud2ConstPtr& cloud) {
          const std::lock_guard<std::mutex> lock(mutex_);
          if (!sceneCounts(cloud->header.stamp.toSec())) return;
          cloth_ = cloud;
          const double t = (cloud->header.stamp - record_start_).toSec();
          if (!recording_frames_ || t < next_cloth_) return;
          next_cloth_ = t + kClothPeriod;
          Eigen::Matrix3Xd vertices;
          if (!cloudVertices(*cloud, vertices)) return;
          recording_.cloth_frames.push_back(vertices);
          recording_.cloth_times.conservativeResize(recording_.cloth_times.size() + 1);
          recording_.cloth_times[recording_.cloth_times.size() - 1] = t;
        });
  }
  for (int a = 0; a < 2; ++a) {
    auto arm = std::make_unique<Arm>();
    arm->name = robot_.arms[static_cast<std::size_t>(a)];
    arm->joints = task_.armModel(a).jointNames();
    // Above the start: the tool comes down onto the cloth's corner instead of sweeping over the table.
    const Eigen::VectorXd& start = task_.startPositions()[static_cast<std::size_t>(a)];
    kinematics::ChainData data(task_.armModel(a));
    (void)kinematics::forwardKinematics(task_.armModel(a), data, start);
    Eigen::Isometry3d above = data.tipPose();
    above.translation() += task_.basePose(a).linear().transpose() * Eigen::Vector3d(0.0, 0.0, robot_.approach_height);
    kinematics::GlobalIkParameters parameters;
    parameters.timeout = 1.0;  // never binding: the same configuration under any load
    kinematics::GlobalIkSolver solver(task_.armModel(a), parameters);
    arm->above_start = start;
    if (solver.solve(above, start, arm->above_start).status != kinematics::IkStatus::Converged ||
        (arm->above_start - start).cwiseAbs().maxCoeff() > 0.5) {
      throw std::invalid_argument("fold on the robot: no configuration of " + arm->name +
                                  " near its start with the tool " + std::to_string(robot_.approach_height) +
                                  " m above it");
    }
    Arm* raw = arm.get();
    arm->state_sub = node_->subscribe<bimanual_skills::JointTrajectoryControllerState>(
        arm->name + "/state", 100, [this, raw](const bimanual_skills::JointTrajectoryControllerState::ConstPtr& s) {
          const std::lock_guard<std::mutex> lock(mutex_);
          const double t = s->header.stamp.toSec();
          raw->stamp = t;
          if (t < raw->before_reset - 1e-9 || t > raw->reset_answered) {
            ++raw->after_reset;
            raw->after_reset_stamp = t;
          }
          if (s->actual.positions.size() != raw->joints.size()) return;
          raw->actual =
              Eigen::Map<const Eigen::VectorXd>(s->actual.positions.data(), Eigen::Index(s->actual.positions.size()));
          if (!raw->recording) return;
          raw->times.push_back(s->header.stamp.toSec());
          raw->positions.push_back(
              Eigen::Map<const Eigen::VectorXd>(s->actual.positions.data(), Eigen::Index(s->actual.positions.size())));
          for (const double e : s->error.positions) raw->max_error = std::max(raw->max_error, std::abs(e));
        });
    arms_.push_back(std::move(arm));
  }
  spinner_ = std::make_unique<ros::AsyncSpinner>(2, &queue_);
  spinner_->start();
  // No destructor runs for an object whose constructor throws: the spinner must stop before the arms its callbacks
  // write into go.
  try {
    // A pause service named but absent would fail every rollout after a timeout: refused once, here.
    if (!robot_.pause_service.empty() &&
        !ros::service::waitForService(node_->resolveName(robot_.pause_service), ros::Duration(robot_.timeout))) {
      throw std::runtime_error("fold on the robot: no pause service " + node_->resolveName(robot_.pause_service) +
                               " within " + std::to_string(robot_.timeout) +
                               " s (a simulator's std_srvs/SetBool; on a robot set the pause service to \"\")");
    }
    checkWorld(task.sim_config, task.robot);
    // A camera the reward cannot use is refused once, here, with the reason (and again per image, if it changes).
    sensor_msgs::CameraInfoConstPtr info;
    try {
      waitFor(
          [&] {
            const std::lock_guard<std::mutex> lock(mutex_);
            info = info_;
            return info != nullptr;
          },
          "the camera_info of " + node_->resolveName(robot_.camera));
    } catch (const Failure& f) {
      throw std::runtime_error("fold on the robot: " + f.reason);
    }
    const std::string problem = cameraProblem(*info);
    if (!problem.empty()) {
      throw std::runtime_error("fold on the robot: the camera " + node_->resolveName(robot_.camera) + " (" +
                               robot_.camera_model + ") cannot be used: " + problem);
    }
    // The arms last: a camera or world the learning cannot use is a setting to change, said before any wait for the
    // robot's actions.
    try {
      connectArms();
    } catch (const Failure& f) {
      throw std::runtime_error("fold on the robot: " + f.reason);
    }
  } catch (...) {
    spinner_->stop();
    throw;
  }
}

FoldOnRobotTask::~FoldOnRobotTask() {
  spinner_->stop();
}

std::vector<std::string> FoldOnRobotTask::termNames() const {
  return rollout::FoldRolloutTask::names();
}

Eigen::VectorXd FoldOnRobotTask::initialParameters() const {
  return rollout::encodeCoordinatedPolicy(
      {Eigen::MatrixXd::Identity(tasks::ClothFoldTask::kDofs, tasks::ClothFoldTask::kDofs)},
      task_.demonstrationParameters());
}

template <typename Done>
void FoldOnRobotTask::waitFor(const Done& done, const std::string& what, bool while_clock_runs) {
  const auto limit = std::chrono::duration<double>(robot_.timeout);
  auto deadline = std::chrono::steady_clock::now() + limit;
  ros::Time clock = ros::Time::now();
  while (!done()) {
    if (!ros::ok()) throw Failure{tasks::FoldOutcome::RobotFailed, "shut down while waiting for " + what};
    if (while_clock_runs && ros::Time::now() != clock) {  // the robot is moving on, at whatever rate
      clock = ros::Time::now();
      deadline = std::chrono::steady_clock::now() + limit;
    }
    if (std::chrono::steady_clock::now() > deadline) {
      std::ostringstream message;
      message << "no answer from " << what << " within " << robot_.timeout << " s";
      throw Failure{tasks::FoldOutcome::RobotFailed, message.str()};
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(kPoll));
  }
}

template <typename Service>
void FoldOnRobotTask::call(const std::string& service, Service& request, double timeout, const std::string& what) {
  ros::ServiceClient client = node_->serviceClient<Service>(service);
  const CallOutcome outcome = callWithin(client, request, timeout);
  if (outcome == CallOutcome::Answered) return;
  std::ostringstream message;
  message << what << " (" << client.getService() << "): " << describe(outcome);
  if (outcome != CallOutcome::Failed) message << " within " << timeout << " s";
  throw Failure{tasks::FoldOutcome::RobotFailed, message.str()};
}

void FoldOnRobotTask::checkWorld(const std::string& sim_config, const std::string& robot) const {
  if (robot_.world_digest.empty()) return;
  const std::string key = node_->resolveName(robot_.world_digest);
  std::string simulated;
  if (!ros::param::get(key, simulated)) {
    ROS_INFO("fold on the robot: no %s: the robot's world is not checked against %s", key.c_str(), sim_config.c_str());
    return;
  }
  const std::string expected = sim::SimConfig::worldDigest(sim_config, robot);
  if (simulated != expected) {
    throw std::runtime_error("fold on the robot: the simulator runs another world: " + key + " is " + simulated +
                             ", the learning's simulation file " + sim_config +
                             (robot.empty() ? std::string() : " on the robot file " + robot) +
                             " (with its URDF and plant files) " + expected +
                             "; give both the same files (fold_learner ~robot, sim.launch robot:=)");
  }
}

bool FoldOnRobotTask::sceneCounts(double stamp) {
  scene_last_stamp_ = stamp;
  return stamp < scene_before_reset_ - 1e-9 || stamp > scene_reset_answered_;
}

std::string FoldOnRobotTask::cameraProblem(const sensor_msgs::CameraInfo& info) {
  const CameraModel model = cameraModel(robot_.camera_model);
  const vision::TopDownCamera& map = reward_.config().renderer.camera;
  std::string problem = cameraInfoProblem(info, model, map);
  if (!problem.empty()) return problem;
  Eigen::Isometry3d pose;
  try {
    pose = tf2::transformToEigen(
        tf_.lookupTransform(robot_.world_frame, info.header.frame_id, ros::Time(0), ros::Duration(robot_.timeout)));
  } catch (const tf2::TransformException& e) {
    return "no transform from " + robot_.world_frame + " to its frame " + info.header.frame_id + " on tf (" + e.what() +
           ")";
  }
  if (model == CameraModel::Orthographic) return orthographicPoseProblem(pose, map);
  const std::lock_guard<std::mutex> lock(mutex_);  // the recording's projection reads it on the spinner
  camera_ = pinholeCamera(info, pose);
  return "";
}

void FoldOnRobotTask::connectArms() {
  // No callback of an old client may run while it goes, nor one of a new client before it is whole: the spinner
  // stands still meanwhile (stop() joins its threads; the messages wait in the queue).
  spinner_->stop();
  for (const auto& arm : arms_) {
    arm->client.reset();
    arm->client = std::make_unique<Client>(*node_, arm->name + "/follow_joint_trajectory", false);
  }
  spinner_->start();
  waitFor([this] { return arms_[0]->client->isServerConnected() && arms_[1]->client->isServerConnected(); },
          "the arms' follow_joint_trajectory actions");
}

void FoldOnRobotTask::waitForGoal(Arm& arm, const std::string& what) {
  Client& client = *arm.client;
  waitFor(
      [&] {
        if (!client.isServerConnected()) {
          throw Failure{tasks::FoldOutcome::RobotFailed, arm.name + "'s follow_joint_trajectory action server went " +
                                                             "away during its " + what +
                                                             " (the robot or its controller stopped)"};
        }
        return client.getState().isDone();
      },
      arm.name + "'s " + what, true);
  const auto result = client.getResult();
  if (client.getState() != actionlib::SimpleClientGoalState::SUCCEEDED || !result) {
    throw Failure{tasks::FoldOutcome::ControllerFailed,
                  arm.name + "'s " + what + " ended " + client.getState().toString() +
                      (result ? std::string(": ") + errorName(result->error_code) + " " + result->error_string : "")};
  }
}

void FoldOnRobotTask::pause(bool paused) {
  std_srvs::SetBool request;
  request.request.data = paused;
  const std::string what = std::string(paused ? "pausing" : "resuming") + " the simulator";
  call(robot_.pause_service, request, robot_.timeout, what);
  if (!request.response.success) {
    throw Failure{tasks::FoldOutcome::RobotFailed, what + " failed: " + request.response.message};
  }
  paused_ = paused;
  if (!paused) return;
  // The clock here must have reached the paused time before the fold's start is counted from it. bullet_sim says
  // when it stopped ("paused at t = 12.300000 s"); a simulator that does not is taken to have stopped once its clock
  // has stood still here for 0.2 s.
  double at = 0.0;
  const bool told = std::sscanf(request.response.message.c_str(), "paused at t = %lf s", &at) == 1 && std::isfinite(at);
  paused_at_ = told ? at : ros::Time::now().toSec();
  ros::Time seen = ros::Time::now();
  auto since = std::chrono::steady_clock::now();
  waitFor(
      [&] {
        const ros::Time now = ros::Time::now();
        if (told && now.toSec() >= at - 1e-6) return true;
        if (now != seen) {
          seen = now;
          since = std::chrono::steady_clock::now();
        }
        return std::chrono::steady_clock::now() - since > std::chrono::milliseconds(200);
      },
      "the simulator's clock (after the pause)");
}

void FoldOnRobotTask::resumeAfterFailure() noexcept {
  if (!paused_) return;
  paused_ = false;
  try {
    // A simulator that is gone or stopped is waited for briefly only (the rollout has failed already).
    std_srvs::SetBool request;
    request.request.data = false;
    (void)callWithin(node_->serviceClient<std_srvs::SetBool>(robot_.pause_service), request,
                     std::min(robot_.timeout, kResumeTimeout));
  } catch (const std::exception&) {  // best effort: the next rollout resumes it first anyway
  }
}

void FoldOnRobotTask::waitUntil(const ros::Time& time, const char* what) {
  waitFor([&] { return ros::Time::now() >= time; }, std::string("the robot's clock (") + what + ")", true);
}

ros::Time FoldOnRobotTask::reset() {
  double before[2], scene_before = 0.0;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    // The camera's and the cloth's messages as the arms' states: none counts until the reset answered, then those of
    // the reset scene only (stamped before the last one before the reset, or after the last one when it answered),
    // so that an image of the last rollout's fold, stamped later than the reset scene on a simulator, is not taken
    // for the flat cloth.
    scene_before = scene_last_stamp_;
    scene_before_reset_ = -std::numeric_limits<double>::infinity();
    scene_reset_answered_ = std::numeric_limits<double>::infinity();
    image_ = depth_ = nullptr;
    info_ = nullptr;
    cloth_ = nullptr;
    for (int a = 0; a < 2; ++a) {
      Arm& arm = *arms_[static_cast<std::size_t>(a)];
      before[a] = arm.stamp;
      arm.before_reset = -std::numeric_limits<double>::infinity();   // nothing counts until the answer (a reset
      arm.reset_answered = std::numeric_limits<double>::infinity();  // that failed before may have left them set)
    }
  }
  std_srvs::Trigger trigger;
  call(robot_.reset_service, trigger, robot_.reset_timeout, "the reset");
  if (!trigger.response.success) {
    throw Failure{tasks::FoldOutcome::RobotFailed, "the reset failed: " + trigger.response.message};
  }
  // The controllers have seen the reset scene once states of it come: stamped before the last one before the reset
  // (a simulation's clock went back) or after the last one when it answered (a robot's clock went on); states still
  // queued from before do not count, however late this process reads them.
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    for (int a = 0; a < 2; ++a) {
      Arm& arm = *arms_[static_cast<std::size_t>(a)];
      arm.before_reset = before[a];
      arm.reset_answered = arm.stamp;
      arm.after_reset = 0;
    }
    scene_before_reset_ = scene_before;
    scene_reset_answered_ = scene_last_stamp_;
  }
  double after = 0.0;
  waitFor(
      [&] {
        const std::lock_guard<std::mutex> lock(mutex_);
        if (std::min(arms_[0]->after_reset, arms_[1]->after_reset) < static_cast<int>(kStatesAfterReset)) {
          return false;
        }
        after = std::min(arms_[0]->after_reset_stamp, arms_[1]->after_reset_stamp);
        return true;
      },
      "the arms' states after the reset");
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& arm : arms_) {
      arm->before_reset = -std::numeric_limits<double>::infinity();
      arm->reset_answered = std::numeric_limits<double>::infinity();
    }
    scene_before_reset_ = scene_reset_answered_ = std::numeric_limits<double>::infinity();  // all count again
  }
  return ros::Time(std::max(0.0, after));
}

void FoldOnRobotTask::grasp(bool close) {
  for (const auto& arm : arms_) {
    bimanual_skills::ClothGrasp request;
    request.request.arm = arm->name;
    request.request.grasp = close;
    call(robot_.grasp_service, request, robot_.timeout,
         std::string(close ? "closing " : "opening ") + arm->name + "'s gripper");
    if (!request.response.success) {
      throw Failure{close ? tasks::FoldOutcome::GraspFailed : tasks::FoldOutcome::RobotFailed,
                    request.response.message};
    }
  }
}

void FoldOnRobotTask::scheduleRelease(const ros::Time& release) {
  for (const auto& arm : arms_) {
    bimanual_skills::ClothGrasp request;
    request.request.arm = arm->name;
    request.request.grasp = false;
    request.request.stamp = release;
    call(robot_.grasp_service, request, robot_.timeout, "scheduling " + arm->name + "'s release");
    if (!request.response.success) throw Failure{tasks::FoldOutcome::RobotFailed, request.response.message};
    if (std::abs((request.response.executed - release).toSec()) > 1e-6) {
      std::ostringstream message;
      message << "the gripper service " << robot_.grasp_service << " does not schedule: " << arm->name
              << "'s release for t = " << release.toSec() << " s was done at " << request.response.executed.toSec()
              << " s";
      throw Failure{tasks::FoldOutcome::RobotFailed, message.str()};
    }
  }
}

double FoldOnRobotTask::moveTime(const std::vector<Eigen::VectorXd>& from, const std::vector<Eigen::VectorXd>& to,
                                 double shortest) const {
  double time = shortest;
  for (int a = 0; a < 2; ++a) {
    const auto i = static_cast<std::size_t>(a);
    const Eigen::VectorXd& limit = task_.armModel(a).velocityLimits();
    for (Eigen::Index j = 0; j < limit.size(); ++j) {
      time = std::max(time, kQuinticPeak * std::abs(to[i][j] - from[i][j]) / (kMoveSpeedShare * limit[j]));
    }
  }
  return time;
}

std::vector<Eigen::VectorXd> FoldOnRobotTask::measuredPositions() {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::vector<Eigen::VectorXd> q;
  for (const auto& arm : arms_) {
    if (arm->actual.size() != static_cast<Eigen::Index>(arm->joints.size())) {
      throw Failure{tasks::FoldOutcome::RobotFailed, arm->name + "'s controller state has not come"};
    }
    q.push_back(arm->actual);
  }
  return q;
}

void FoldOnRobotTask::moveToStart() {
  // Both arms together, each segment as long as the widest joint move needs at half its velocity limit (the
  // configured move_time at least): from where the arms are to above the start, then down onto the cloth.
  const std::vector<Eigen::VectorXd> now = measuredPositions();
  std::vector<Eigen::VectorXd> above;
  for (const auto& arm : arms_) above.push_back(arm->above_start);
  const double up = moveTime(now, above, kApproachShare * robot_.move_time);
  const double down = moveTime(above, task_.startPositions(), (1.0 - kApproachShare) * robot_.move_time);
  last_move_seconds_ = up + down;
  for (int a = 0; a < 2; ++a) {
    Arm& arm = *arms_[static_cast<std::size_t>(a)];
    bimanual_skills::FollowJointTrajectoryGoal goal;
    goal.trajectory.joint_names = arm.joints;
    const Eigen::VectorXd& q = task_.startPositions()[static_cast<std::size_t>(a)];
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(q.size());
    goal.trajectory.points.push_back(point(arm.above_start, zero, zero, up));
    goal.trajectory.points.push_back(point(q, zero, zero, up + down));
    arm.client->sendGoal(goal);
  }
  for (const auto& arm : arms_) waitForGoal(*arm, "move to the start");
}

std::string FoldOnRobotTask::recover() noexcept {
  std::string done;
  const auto note = [&done](const std::string& what) { done += (done.empty() ? "" : ", ") + what; };
  try {
    for (const auto& arm : arms_) {
      bimanual_skills::ClothGrasp request;
      request.request.arm = arm->name;
      request.request.grasp = false;
      const CallOutcome outcome = callWithin(node_->serviceClient<bimanual_skills::ClothGrasp>(robot_.grasp_service),
                                             request, std::min(robot_.timeout, kRecoveryTimeout));
      note(arm->name +
           (outcome == CallOutcome::Answered && request.response.success
                ? "'s gripper opened"
                : "'s gripper not opened (" +
                      (outcome == CallOutcome::Answered ? request.response.message : std::string(describe(outcome))) +
                      ")"));
    }
    // Up to the configurations above the start, timed from the velocity limits, if the arms still answer.
    std::vector<Eigen::VectorXd> above;
    for (const auto& arm : arms_) above.push_back(arm->above_start);
    const double time = moveTime(measuredPositions(), above, 0.5);
    for (const auto& arm : arms_) {
      if (!arm->client->isServerConnected()) throw Failure{tasks::FoldOutcome::RobotFailed, arm->name + " is gone"};
      bimanual_skills::FollowJointTrajectoryGoal goal;
      goal.trajectory.joint_names = arm->joints;
      const Eigen::VectorXd zero = Eigen::VectorXd::Zero(arm->above_start.size());
      goal.trajectory.points.push_back(point(arm->above_start, zero, zero, time));
      arm->client->sendGoal(goal);
    }
    const auto deadline = std::chrono::steady_clock::now() +
                          std::chrono::duration<double>(time + std::min(robot_.timeout, kRecoveryTimeout));
    bool retracted = true;
    for (const auto& arm : arms_) {
      while (!arm->client->getState().isDone() && std::chrono::steady_clock::now() < deadline && ros::ok()) {
        std::this_thread::sleep_for(std::chrono::duration<double>(kPoll));
      }
      retracted = retracted && arm->client->getState() == actionlib::SimpleClientGoalState::SUCCEEDED;
    }
    note(retracted ? "the arms retracted above their start" : "the arms not retracted");
  } catch (const Failure& f) {
    note("the arms not retracted (" + f.reason + ")");
  } catch (const std::exception& e) {
    note(std::string("the recovery stopped: ") + e.what());
  }
  return done;
}

ros::Time FoldOnRobotTask::fold(const tasks::FoldPlan& plan) {
  // One goal per arm over the hold, the movement and the hold up to the release, both starting at the same time;
  // the grippers open at the planned release, as in the in-process task (the scene is sensitive to when: a fold
  // near the table's edge slides on after the release).
  const int every = std::max(1, static_cast<int>(std::lround(1.0 / (robot_.trajectory_rate * plan.dt))));
  const ros::Time start = ros::Time::now() + ros::Duration(robot_.start_delay);
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& arm : arms_) {
      arm->recording = true;
      arm->times.clear();
      arm->positions.clear();
      arm->max_error = 0.0;
    }
    recording_frames_ = true;
    record_start_ = start;
    next_image_ = next_cloth_ = -std::numeric_limits<double>::infinity();
  }
  for (int a = 0; a < 2; ++a) {
    Arm& arm = *arms_[static_cast<std::size_t>(a)];
    const auto i = static_cast<std::size_t>(a);
    bimanual_skills::FollowJointTrajectoryGoal goal;
    goal.trajectory.header.stamp = start;
    goal.trajectory.joint_names = arm.joints;
    for (int k = 0; k <= plan.release; k += every) {
      goal.trajectory.points.push_back(
          point(plan.position[i].col(k), plan.velocity[i].col(k), plan.acceleration[i].col(k), k * plan.dt));
    }
    for (const std::string& joint : arm.joints) {
      bimanual_skills::JointTolerance tolerance;
      tolerance.name = joint;
      tolerance.position = task_.config().max_tracking_error;
      goal.path_tolerance.push_back(tolerance);
    }
    arm.client->sendGoal(goal);
  }
  const auto failed = [](const Arm& arm) {
    const actionlib::SimpleClientGoalState state = arm.client->getState();
    return !arm.client->isServerConnected() || (state.isDone() && state != actionlib::SimpleClientGoalState::SUCCEEDED);
  };
  if (paused_) {
    // Both controllers have the goals (or one refused it) before the clock goes on.
    const auto answered = [&failed](const Arm& arm) {
      return failed(arm) || arm.client->getState() != actionlib::SimpleClientGoalState::PENDING;
    };
    waitFor([&] { return answered(*arms_[0]) && answered(*arms_[1]); }, "the arms' controllers (the fold's goals)");
    for (const auto& arm : arms_) {
      if (failed(*arm)) waitForGoal(*arm, "fold trajectory");
    }
  }
  // The grippers open at the planned release, on the robot's clock: the gripper's loop does it at its time, however
  // late this process would be to ask.
  const ros::Time release = start + ros::Duration(plan.release * plan.dt);
  scheduleRelease(release);
  if (paused_ && !robot_.step_service.empty()) {
    // A simulator steps from the grasp to the settled cloth and stands still there.
    const double until = release.toSec() + task_.config().settle;
    bimanual_skills::SimStep step;
    step.request.steps = static_cast<std::uint32_t>(std::max(0L, std::lround((until - paused_at_) / plan.dt)));
    call(robot_.step_service, step, robot_.timeout + (until - paused_at_), "stepping the simulator through the fold");
    if (!step.response.success) {
      throw Failure{tasks::FoldOutcome::RobotFailed,
                    "stepping the simulator through the fold: " + step.response.message};
    }
  } else if (paused_) {
    pause(false);
  }
  // Until the release, unless an arm's goal fails first (waitForGoal then reports why).
  waitFor([&] { return failed(*arms_[0]) || failed(*arms_[1]) || ros::Time::now() >= release; },
          "the robot's clock (the fold's release)", true);
  for (const auto& arm : arms_) waitForGoal(*arm, "fold trajectory");
  const std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& arm : arms_) arm->recording = false;
  return release;
}

struct FoldOnRobotTask::Camera {
  cv::Mat bgr, metres;  ///< In the reward's map.
  ros::Time stamp;
  sensor_msgs::PointCloud2ConstPtr cloth;
};

FoldOnRobotTask::Camera FoldOnRobotTask::cameraImages(const ros::Time& after, bool with_cloth) {
  sensor_msgs::ImageConstPtr image, depth;
  sensor_msgs::CameraInfoConstPtr info;
  Camera out;
  with_cloth = with_cloth && !robot_.cloth.empty();
  waitFor(
      [&] {
        const std::lock_guard<std::mutex> lock(mutex_);
        image = image_;
        depth = depth_;
        info = info_;
        out.cloth = cloth_;
        // Stamped after `after` and not ahead of this clock: an image of the last rollout's end, rendered late and
        // stamped later than the reset scene on a simulator whose clock went back, is not of this scene.
        const ros::Time latest = ros::Time::now() + ros::Duration(kAheadOfClock);
        const auto fresh = [&](const auto& m) { return m && m->header.stamp >= after && m->header.stamp <= latest; };
        // One frame: colour and depth taken together (a camera that stamps them apart, within 20 ms).
        return fresh(image) && fresh(depth) && fresh(info) && (!with_cloth || fresh(out.cloth)) &&
               std::abs((image->header.stamp - depth->header.stamp).toSec()) <= 0.02;
      },
      "the camera " + robot_.camera + (with_cloth ? " and the cloth " + robot_.cloth : ""));
  if (!with_cloth) out.cloth = nullptr;
  const std::string problem = cameraProblem(*info);
  if (!problem.empty()) {
    throw Failure{tasks::FoldOutcome::RobotFailed, "the camera " + robot_.camera + " cannot be used: " + problem};
  }
  if (image->width != info->width || image->height != info->height || depth->width != info->width ||
      depth->height != info->height) {
    throw Failure{tasks::FoldOutcome::RobotFailed,
                  "the camera's images are " + std::to_string(image->width) + " x " + std::to_string(image->height) +
                      " and " + std::to_string(depth->width) + " x " + std::to_string(depth->height) +
                      ", its camera_info " + std::to_string(info->width) + " x " + std::to_string(info->height)};
  }
  cv_bridge::CvImageConstPtr bgr, metres;
  try {
    bgr = cv_bridge::toCvShare(image, "bgr8");
    metres = cv_bridge::toCvShare(depth, "32FC1");
  } catch (const cv_bridge::Exception& e) {
    throw Failure{tasks::FoldOutcome::RobotFailed, std::string("unreadable camera image: ") + e.what()};
  }
  out.stamp = image->header.stamp;
  if (cameraModel(robot_.camera_model) == CameraModel::Orthographic) {
    out.bgr = bgr->image;
    out.metres = metres->image;
    return out;
  }
  const vision::VisionStatus status = projector_.project(bgr->image, metres->image, camera_);
  const vision::HeightMapCoverage& c = projector_.coverage();
  const vision::TopDownCamera& map = projector_.map();
  const double seen = static_cast<double>(c.observed + c.filled) / (map.rows * map.columns);
  if (status != vision::VisionStatus::Ok || seen < robot_.min_coverage) {
    std::ostringstream why;
    why << "the camera's depth re-projected into the reward's map: " << vision::toString(status) << ", " << 100.0 * seen
        << " % of the map seen (min_coverage " << 100.0 * robot_.min_coverage << " %)";
    throw Failure{tasks::FoldOutcome::RobotFailed, why.str()};
  }
  out.bgr = projector_.bgr();
  out.metres = projector_.depth();
  return out;
}

void FoldOnRobotTask::observeFlat(const ros::Time& after) {
  const Camera camera = cameraImages(after, false);
  try {
    reward_.observeFlat(camera.bgr, camera.metres);
  } catch (const std::invalid_argument& e) {
    throw Failure{tasks::FoldOutcome::RobotFailed, std::string("the camera does not show the flat cloth after the "
                                                               "reset: ") +
                                                       e.what()};
  }
}

tasks::FoldRewardTerms FoldOnRobotTask::observe(const ros::Time& after, double acceleration_cost) {
  const Camera camera = cameraImages(after, true);
  const sensor_msgs::PointCloud2ConstPtr& cloth = camera.cloth;
  tasks::FoldRewardTerms terms =
      reward_.evaluateImages(tasks::FoldOutcome::Ok, acceleration_cost, camera.bgr, camera.metres);
  terms.fold_quality = terms.fold_distance = terms.fold_displacement = std::numeric_limits<double>::quiet_NaN();
  if (cloth) {
    Eigen::Matrix3Xd vertices;
    try {  // a cloud without x, y, z or of another cloth is the robot's fault, not the learner's
      if (!cloudVertices(*cloth, vertices)) throw std::invalid_argument("no float fields x, y, z");
      const tasks::FoldQuality fold = task_.foldQualityOf(vertices);
      terms.fold_quality = fold.q;
      terms.fold_distance = fold.distance;
      terms.fold_displacement = fold.displacement;
    } catch (const std::exception& e) {
      throw Failure{tasks::FoldOutcome::RobotFailed, "unusable cloth cloud " + robot_.cloth + ": " + e.what()};
    }
    const std::lock_guard<std::mutex> lock(mutex_);
    recording_.cloth_vertices = vertices;
  }
  // The images scored close the recording.
  const std::lock_guard<std::mutex> lock(mutex_);
  recording_frames_ = false;
  addFrame(recording_, (camera.stamp - record_start_).toSec(), camera.bgr.clone(), camera.metres.clone());
  return terms;
}

rollout::RolloutResult FoldOnRobotTask::run(const Eigen::VectorXd& parameters, std::uint32_t /*seed*/) {
  const auto wall_start = std::chrono::steady_clock::now();
  last_tracking_error_ = last_robot_seconds_ = 0.0;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    recording_ = tasks::FoldRollout{};
    recording_frames_ = false;
  }
  tasks::FoldRewardTerms terms;
  std::string reason;
  std::vector<Eigen::Matrix3Xd> paths;
  std::vector<Eigen::MatrixXd> coordination;
  Eigen::VectorXd weights;
  double acceleration_cost = 0.0;
  bool moved = false;  // whether the robot moved (and a failure must be recovered from)
  const auto fail = [&](tasks::FoldOutcome outcome, const std::string& why) {
    terms = tasks::FoldRewardTerms{};
    terms.outcome = outcome;
    terms.reward = reward_.config().failure_reward;
    terms.r_acceleration = reward_.config().acceleration_weight * acceleration_cost;
    reason = why;
    for (const auto& arm : arms_) arm->client->cancelGoal();
    reconnect_ = reconnect_ || outcome == tasks::FoldOutcome::RobotFailed;
    if (!moved) return;
    resumeAfterFailure();  // the recovery needs the clock
    reason += "; recovery: " + recover();
  };
  try {
    if (!rollout::decodeCoordinatedPolicy(parameters, tasks::ClothFoldTask::kDofs, task_.policyBasisSize(),
                                          coordination, weights)) {
      throw Failure{tasks::FoldOutcome::InvalidPolicy,
                    "the parameters do not encode a coordinated policy of 12 DoF and " +
                        std::to_string(task_.policyBasisSize()) + " weights per latent DoF"};
    }
    const tasks::FoldPlan plan = task_.plan(coordination, weights);
    acceleration_cost = plan.acceleration_cost;
    if (plan.outcome != tasks::FoldOutcome::Ok) throw Failure{plan.outcome, plan.reason};
    if (reconnect_) {
      connectArms();
      reconnect_ = false;
    }
    // A simulator left paused (a learner stopped while it stood still) goes on first: paused, it publishes no
    // states and every rollout would fail.
    if (!robot_.pause_service.empty()) pause(false);
    observeFlat(reset());  // the flat cloth: images of the reset scene (this process's clock may lag)
    moved = true;
    moveToStart();
    // The move took last_move_seconds_ (the clock read before it may still be the one before a reset; nor can a
    // time just after a reset take it away: ros::Time is never negative).
    const ros::Time at_start = ros::Time::now();
    // A simulator stands still from the grasp until both arms have the fold's goals: the cloth is held for exactly
    // start_delay before the fold, however long the messages take.
    if (!robot_.pause_service.empty()) pause(true);
    grasp(true);
    const ros::Time settled = fold(plan) + ros::Duration(task_.config().settle);
    waitUntil(settled, "the cloth settling");
    terms = observe(settled, acceleration_cost);
    if (paused_) pause(false);  // a simulator stepped to the settled cloth runs on
    last_robot_seconds_ = last_move_seconds_ + (ros::Time::now() - at_start).toSec();
  } catch (const Failure& failure) {
    fail(failure.outcome, failure.reason);
  } catch (const std::exception& e) {
    // Anything else the ROS layer throws (a clock out of range, a transport error) fails this rollout, not the
    // learning.
    fail(tasks::FoldOutcome::RobotFailed, std::string("the ROS layer failed: ") + e.what());
  }
  resumeAfterFailure();  // a failure while the simulator stood still: it goes on
  // The measured tool paths at kPathRate of the robot's clock.
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    std::size_t samples = std::numeric_limits<std::size_t>::max();
    for (const auto& arm : arms_) {
      arm->recording = false;
      last_tracking_error_ = std::max(last_tracking_error_, arm->max_error);
      samples = std::min(samples, arm->positions.size());
    }
    // The same samples of both arms (their states share the controllers' stamps), thinned to kPathRate.
    const std::vector<double>& times = arms_[0]->times;
    const double period = samples > 1 ? (times[samples - 1] - times[0]) / static_cast<double>(samples - 1) : 1.0;
    const auto stride = static_cast<std::size_t>(std::max(1.0, std::round(1.0 / (kPathRate * period))));
    const auto thinned = static_cast<Eigen::Index>(samples > 0 ? (samples + stride - 1) / stride : 0);
    recording_.path_times.resize(thinned);
    for (std::size_t k = 0; k < samples; k += stride) {
      recording_.path_times[static_cast<Eigen::Index>(k / stride)] = times[k] - record_start_.toSec();
    }
    for (int a = 0; a < 2 && samples > 0; ++a) {
      const Arm& arm = *arms_[static_cast<std::size_t>(a)];
      kinematics::ChainData data(task_.armModel(a));
      Eigen::Matrix3Xd path(3, thinned);
      Eigen::MatrixXd joints(arm.positions.front().size(), thinned);
      for (std::size_t k = 0; k < samples; k += stride) {
        (void)kinematics::forwardKinematics(task_.armModel(a), data, arm.positions[k]);
        path.col(static_cast<Eigen::Index>(k / stride)) = task_.basePose(a) * data.tipPose().translation();
        joints.col(static_cast<Eigen::Index>(k / stride)) = arm.positions[k];
      }
      paths.push_back(path);
      recording_.joint_path.push_back(joints);
    }
    recording_frames_ = false;
    recording_.outcome = terms.outcome;
    recording_.reason = reason;
    recording_.actual_path = paths;
    recording_.cloth_triangles = task_.clothTriangles();
    recording_.cloth_rest_vertices = task_.clothRestVertices();
    if (recording_.cloth_vertices.cols() > 0) recording_.fold = task_.foldQualityOf(recording_.cloth_vertices);
  }
  rollout::RolloutResult result = rollout::FoldRolloutTask::resultOf(terms, reason, paths);
  result.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  return result;
}

}  // namespace bimanual_skills::ros_layer
