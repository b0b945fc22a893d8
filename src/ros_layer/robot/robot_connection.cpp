#include "bimanual_skills/ros_layer/robot/robot_connection.hpp"

#include "bimanual_skills/ClothGrasp.h"
#include "bimanual_skills/SimStep.h"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/ros_layer/trajectory_messages.hpp"
#include "bimanual_skills/sim/sim_config.hpp"

#include <sensor_msgs/point_cloud2_iterator.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <tf2_eigen/tf2_eigen.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <thread>

namespace bimanual_skills::ros_layer {

namespace {

/// Wall-clock pause between polls of a wait [s]: short against a rollout, long against the spinner's work.
constexpr double kPoll = 0.002;
/// An arm's states this far apart while its goal ran [s] mean the robot's loop or transport stopped.
constexpr double kStateGap = 0.1;
/// Colour and depth images stamped this far apart are of one moment [s] (a Kinect's two cameras run apart).
constexpr double kFrameSpread = 0.02;
/// Controller states of each arm to wait for after a reset before commanding the arms.
constexpr int kStatesAfterReset = 3;
/// Longest wait for resuming a simulator after a failed rollout [s]: the next rollout resumes it anyway.
constexpr double kResumeTimeout = 2.0;
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

}  // namespace

void RobotInterfaces::validate(const std::string& what) const {
  const auto fail = [&what](const std::string& why) { throw std::invalid_argument(what + ": " + why); };
  if (reset_service.empty() || grasp_service.empty()) fail("the reset and grasp services need names");
  if (arms.empty()) fail("no arm given");
  for (const std::string& arm : arms) {
    if (arm.empty()) fail("an arm's namespace is empty");
  }
  if (camera.empty()) fail("the camera needs a namespace");
  if (depth.empty()) fail("the depth camera needs a namespace (depth or depth_registered)");
  if (!(timeout > 0.0) || !std::isfinite(timeout)) fail("timeout must be finite and > 0");
  if (!(reset_timeout > 0.0) || !std::isfinite(reset_timeout)) fail("reset_timeout must be finite and > 0");
}

/// What the spinner writes of one arm (under the connection's mutex): the last state, the reset's count, and while
/// recording its samples.
struct RobotConnection::ArmState {
  Eigen::VectorXd actual;  ///< The last measured positions (empty before a state came).
  double stamp = -std::numeric_limits<double>::infinity();  ///< Of the last state [s].
  long fresh = 0;  ///< States received with a stamp other than the one before: the robot's progress.
  /// The longest stop of its states since the last goal was sent [s, of their stamps or of their arrival], and when
  /// the last one came (monotonic wall clock).
  double gap = 0.0, arrival = 0.0;
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

RobotConnection::RobotConnection(const RobotInterfaces& robot, std::vector<std::vector<std::string>> joints,
                                 const std::string& what, const std::string& sim_config, const std::string& robot_file,
                                 FrameHandler on_frame, ClothHandler on_cloth)
    : robot_(robot), on_frame_(std::move(on_frame)), on_cloth_(std::move(on_cloth)) {
  robot_.validate(what);
  if (joints.size() != robot_.arms.size()) {
    throw std::invalid_argument(what + ": " + std::to_string(robot_.arms.size()) + " arms named, the task has " +
                                std::to_string(joints.size()));
  }
  tf_listener_ = std::make_unique<tf2_ros::TransformListener>(tf_);
  node_ = std::make_unique<ros::NodeHandle>();
  node_->setCallbackQueue(&queue_);
  caller_ = std::make_unique<ServiceCaller>(*node_);
  const std::string camera = robot_.camera + "/";
  image_sub_ =
      node_->subscribe<sensor_msgs::Image>(camera + "image_raw", 2, [this](const sensor_msgs::ImageConstPtr& m) {
        const std::lock_guard<std::mutex> lock(mutex_);
        if (sceneCounts(m->header.stamp.toSec())) image_ = m;
      });
  info_sub_ = node_->subscribe<sensor_msgs::CameraInfo>(camera + "camera_info", 2,
                                                        [this](const sensor_msgs::CameraInfoConstPtr& m) {
                                                          const std::lock_guard<std::mutex> lock(mutex_);
                                                          if (!first_info_) first_info_ = m;
                                                          if (sceneCounts(m->header.stamp.toSec())) info_ = m;
                                                        });
  const std::string depth_ns = camera + robot_.depth + "/";
  depth_info_sub_ = node_->subscribe<sensor_msgs::CameraInfo>(depth_ns + "camera_info", 2,
                                                              [this](const sensor_msgs::CameraInfoConstPtr& m) {
                                                                const std::lock_guard<std::mutex> lock(mutex_);
                                                                if (!first_depth_info_) first_depth_info_ = m;
                                                                if (sceneCounts(m->header.stamp.toSec())) {
                                                                  depth_info_ = m;
                                                                }
                                                              });
  // The depth image comes second: a colour and depth pair of one moment goes to the frame handler.
  depth_sub_ =
      node_->subscribe<sensor_msgs::Image>(depth_ns + "image_raw", 2, [this](const sensor_msgs::ImageConstPtr& depth) {
        sensor_msgs::ImageConstPtr image;
        {
          const std::lock_guard<std::mutex> lock(mutex_);
          if (!sceneCounts(depth->header.stamp.toSec())) return;
          depth_ = depth;
          if (!image_ || std::abs((image_->header.stamp - depth->header.stamp).toSec()) > kFrameSpread) return;
          image = image_;
        }
        if (on_frame_) on_frame_(image, depth);
      });
  if (!robot_.cloth.empty()) {
    cloth_sub_ = node_->subscribe<sensor_msgs::PointCloud2>(robot_.cloth, 2,
                                                            [this](const sensor_msgs::PointCloud2ConstPtr& cloud) {
                                                              {
                                                                const std::lock_guard<std::mutex> lock(mutex_);
                                                                if (!sceneCounts(cloud->header.stamp.toSec())) return;
                                                                cloth_ = cloud;
                                                              }
                                                              if (on_cloth_) on_cloth_(cloud);
                                                            });
  }
  for (std::size_t a = 0; a < robot_.arms.size(); ++a) {
    auto arm = std::make_unique<Arm>();
    arm->name = robot_.arms[a];
    arm->joints = std::move(joints[a]);
    states_.push_back(std::make_unique<ArmState>());
    ArmState* raw = states_.back().get();
    const std::size_t dofs = arm->joints.size();
    state_subs_.push_back(node_->subscribe<bimanual_skills::JointTrajectoryControllerState>(
        arm->name + "/state", 100,
        [this, raw, dofs](const bimanual_skills::JointTrajectoryControllerState::ConstPtr& s) {
          const std::lock_guard<std::mutex> lock(mutex_);
          const double t = s->header.stamp.toSec();
          if (t != raw->stamp) {
            ++raw->fresh;
            // How long the robot's states stopped while a goal ran: as long as both their stamps (a clock that went
            // on without them) and their arrivals (a transport that held them) say. By the stamps alone a simulator
            // running 10 times faster than the wall's clock is 0.1 s apart between two states published 10 ms late
            // on a busy machine; by the arrivals alone a paused simulator sends nothing on purpose. Not while this
            // object holds a simulator's clock: paused, it sends nothing, and stepped, its stamps leap on purpose.
            const double arrival = realtime::monotonicSeconds();
            if (raw->arrival > 0.0 && !paused_ && t > raw->stamp) {
              raw->gap = std::max(raw->gap, std::min(t - raw->stamp, arrival - raw->arrival));
            }
            raw->arrival = arrival;
          }
          raw->stamp = t;
          if (t < raw->before_reset - 1e-9 || t > raw->reset_answered) {
            ++raw->after_reset;
            raw->after_reset_stamp = t;
          }
          if (s->actual.positions.size() != dofs) return;
          raw->actual =
              Eigen::Map<const Eigen::VectorXd>(s->actual.positions.data(), Eigen::Index(s->actual.positions.size()));
          if (!raw->recording) return;
          raw->times.push_back(t);
          raw->positions.push_back(raw->actual);
          for (const double e : s->error.positions) raw->max_error = std::max(raw->max_error, std::abs(e));
        }));
    arms_.push_back(std::move(arm));
  }
  spinner_ = std::make_unique<ros::AsyncSpinner>(2, &queue_);
  spinner_->start();
  // No destructor runs for an object whose constructor throws: the spinner must stop before the states its
  // callbacks write into go.
  try {
    // A pause service named but absent would fail every rollout after a timeout: refused once, here.
    if (!robot_.pause_service.empty() &&
        !ros::service::waitForService(node_->resolveName(robot_.pause_service), ros::Duration(robot_.timeout))) {
      throw std::runtime_error(what + ": no pause service " + node_->resolveName(robot_.pause_service) + " within " +
                               std::to_string(robot_.timeout) +
                               " s (a simulator's std_srvs/SetBool; on a robot set the pause service to \"\")");
    }
    checkWorld(what, sim_config, robot_file);
    try {
      // A paused simulator publishes no camera images and its actions no status (their clock stands still): it goes
      // on first (a learner stopped while it stood still leaves it paused).
      if (!robot_.pause_service.empty()) pause(false);
      waitFor(
          [&] {
            const std::lock_guard<std::mutex> lock(mutex_);
            return first_info_ != nullptr;
          },
          "the camera_info of " + node_->resolveName(robot_.camera));
    } catch (const RobotFault& f) {
      throw std::runtime_error(what + ": " + f.reason);
    }
  } catch (...) {
    spinner_->stop();
    throw;
  }
}

RobotConnection::~RobotConnection() {
  spinner_->stop();
}

void RobotConnection::waitFor(const std::function<bool()>& done, const std::string& what) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(robot_.timeout);
  while (!done()) {
    if (!ros::ok()) throw RobotFault{tasks::FoldOutcome::RobotFailed, "shut down while waiting for " + what};
    if (std::chrono::steady_clock::now() > deadline) {
      std::ostringstream message;
      message << "no answer from " << what << " within " << robot_.timeout << " s";
      throw RobotFault{tasks::FoldOutcome::RobotFailed, message.str()};
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(kPoll));
  }
}

RobotConnection::Progress RobotConnection::progress() {
  const std::lock_guard<std::mutex> lock(mutex_);
  Progress p;
  for (const auto& arm : states_) {
    p.states += arm->fresh;
    p.stamp = std::max(p.stamp, arm->stamp);
    p.slowest = std::min(p.slowest, arm->fresh);
  }
  return p;
}

void RobotConnection::waitWhileMoving(const std::function<bool()>& done, const std::string& what,
                                      const ros::Time& ends_by) {
  const auto limit = std::chrono::duration<double>(robot_.timeout);
  const Progress start = progress();
  auto deadline = std::chrono::steady_clock::now() + limit;
  Progress last = start;
  while (!done()) {
    if (!ros::ok()) throw RobotFault{tasks::FoldOutcome::RobotFailed, "shut down while waiting for " + what};
    const Progress now = progress();
    // Every arm's controller has sent a state of a new stamp: the robot moves on, at whatever rate (a wall clock's
    // robot, a simulator slower or faster than real time). A clock that moves on alone says nothing of the robot.
    if (now.slowest > last.slowest) {
      last = now;
      deadline = std::chrono::steady_clock::now() + limit;
    }
    std::ostringstream message;
    if (std::chrono::steady_clock::now() > deadline) {
      message << "no answer from " << what << ": ";
      if (now.slowest == start.slowest) {
        message << "a controller sent no state for " << robot_.timeout << " s (the robot's loop or its controller "
                << "stopped)";
      } else {
        message << "the controllers' states stopped for " << robot_.timeout << " s at t = " << std::fixed << now.stamp
                << " s (the robot's loop or a controller stopped)";
      }
      throw RobotFault{tasks::FoldOutcome::RobotFailed, message.str()};
    }
    if (!ends_by.isZero() && now.stamp > ends_by.toSec() + robot_.timeout) {
      message << "no answer from " << what << ": the robot's states are at t = " << std::fixed << now.stamp << " s, "
              << robot_.timeout << " s after it should have ended (t = " << ends_by.toSec() << " s)";
      throw RobotFault{tasks::FoldOutcome::RobotFailed, message.str()};
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(kPoll));
  }
}

void RobotConnection::checkWorld(const std::string& what, const std::string& sim_config,
                                 const std::string& robot_file) const {
  if (robot_.world_digest.empty()) return;
  const std::string key = node_->resolveName(robot_.world_digest);
  std::string simulated;
  if (!ros::param::get(key, simulated)) {
    ROS_INFO("%s: no %s: the robot's world is not checked against %s", what.c_str(), key.c_str(), sim_config.c_str());
    return;
  }
  const std::string expected = sim::SimConfig::worldDigest(sim_config, robot_file);
  if (simulated != expected) {
    throw std::runtime_error(what + ": the simulator runs another world: " + key + " is " + simulated +
                             ", the learning's simulation file " + sim_config +
                             (robot_file.empty() ? std::string() : " on the robot file " + robot_file) +
                             " (with its URDF and plant files) " + expected +
                             "; give both the same files (the learner's ~robot, sim.launch robot:=)");
  }
}

bool RobotConnection::sceneCounts(double stamp) {
  scene_last_stamp_ = stamp;
  return stamp < scene_before_reset_ - 1e-9 || stamp > scene_reset_answered_;
}

void RobotConnection::connectArms() {
  // No callback of an old client may run while it goes, nor one of a new client before it is whole: the spinner
  // stands still meanwhile (stop() joins its threads; the messages wait in the queue).
  spinner_->stop();
  for (const auto& arm : arms_) {
    arm->client.reset();
    arm->client = std::make_unique<Client>(*node_, arm->name + "/follow_joint_trajectory", false);
    arm->goal_sent = false;
  }
  spinner_->start();
  waitFor(
      [this] {
        return std::all_of(arms_.begin(), arms_.end(),
                           [](const auto& arm) { return arm->client->isServerConnected(); });
      },
      "the arms' follow_joint_trajectory actions");
}

bool RobotConnection::goalFailed(std::size_t a) const {
  const Client& client = *arms_[a]->client;
  const actionlib::SimpleClientGoalState state = client.getState();
  return !client.isServerConnected() || (state.isDone() && state != actionlib::SimpleClientGoalState::SUCCEEDED);
}

bool RobotConnection::goalAnswered(std::size_t a) const {
  return goalFailed(a) || arms_[a]->client->getState() != actionlib::SimpleClientGoalState::PENDING;
}

void RobotConnection::waitForAnswers(const ros::Time& start, double delay, const std::string& what) {
  waitFor(
      [&] {
        for (std::size_t a = 0; a < arms_.size(); ++a) {
          if (!goalAnswered(a)) return false;
        }
        return true;
      },
      "the controllers (" + what + ")");
  const double late = (ros::Time::now() - start).toSec();
  if (paused_ || late <= 0.0) return;
  std::ostringstream why;
  why << what << " were answered " << late << " s after their start (start_delay " << delay
      << " s is short for this robot's transport; the robot's)";
  throw RobotFault{tasks::FoldOutcome::RobotFailed, why.str()};
}

void RobotConnection::sendGoal(std::size_t a, const bimanual_skills::FollowJointTrajectoryGoal& goal) {
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    states_[a]->gap = 0.0;
  }
  Arm& arm = *arms_[a];
  arm.client->sendGoal(goal);
  arm.goal_sent = true;
}

void RobotConnection::cancelGoals() {
  for (const auto& arm : arms_) {
    if (arm->client && arm->goal_sent && !arm->client->getState().isDone()) arm->client->cancelGoal();
  }
}

void RobotConnection::settle() {
  cancelGoals();
  std::string busy;
  if (!caller_->drain(robot_.timeout, &busy)) {
    std::ostringstream message;
    message << "the robot has not answered the last rollout's calls to " << busy << " within " << robot_.timeout
            << " s more (a stuck server would run them late, into this rollout)";
    throw RobotFault{tasks::FoldOutcome::RobotFailed, message.str()};
  }
}

void RobotConnection::waitForGoal(std::size_t a, const std::string& what, const ros::Time& ends_by, Blame blame) {
  Arm& arm = *arms_[a];
  Client& client = *arm.client;
  waitWhileMoving(
      [&] {
        if (!client.isServerConnected()) {
          throw RobotFault{tasks::FoldOutcome::RobotFailed, arm.name + "'s follow_joint_trajectory action server " +
                                                                "went away during its " + what +
                                                                " (the robot or its controller stopped)"};
        }
        return client.getState().isDone();
      },
      arm.name + "'s " + what, ends_by);
  const auto result = client.getResult();
  if (client.getState() == actionlib::SimpleClientGoalState::SUCCEEDED && result) return;
  std::string why = arm.name + "'s " + what + " ended " + client.getState().toString() +
                    (result ? std::string(": ") + errorName(result->error_code) + " " + result->error_string : "");
  // Only a policy that the robot ran as asked is the policy's failure: a goal before its first point, or one that
  // ended because the robot's loop or its states stopped, is the robot's (run again, never learned from).
  double gap = 0.0;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    gap = states_[a]->gap;
  }
  // A velocity-limit stop just after a gap in the controller's states: the robot held or braked without its
  // torques meanwhile (ArmControllerState::abort_gap).
  const bool loop = result && (result->error_string.find("the control loop stopped") != std::string::npos ||
                               result->error_string.find("StaleState") != std::string::npos ||
                               result->error_string.find("gap in its joint states") != std::string::npos);
  if (blame == Blame::Robot) {
    throw RobotFault{tasks::FoldOutcome::RobotFailed, why + " (before the policy's first point: the robot's)"};
  }
  if (loop || gap > kStateGap) {
    std::ostringstream robot;
    robot << why << " (the robot's: " << (loop ? "its control loop or its states stopped" : "its states stopped")
          << "; states " << gap << " s apart at most)";
    throw RobotFault{tasks::FoldOutcome::RobotFailed, robot.str()};
  }
  throw RobotFault{tasks::FoldOutcome::ControllerFailed, why};
}

void RobotConnection::pause(bool paused) {
  std_srvs::SetBool request;
  request.request.data = paused;
  const std::string what = std::string(paused ? "pausing" : "resuming") + " the simulator";
  call(robot_.pause_service, request, robot_.timeout, what);
  if (!request.response.success) {
    throw RobotFault{tasks::FoldOutcome::RobotFailed, what + " failed: " + request.response.message};
  }
  paused_ = paused;
  if (!paused) return;
  // The clock here must have reached the paused time before a start is counted from it. bullet_sim says when it
  // stopped ("paused at t = 12.300000 s"); a simulator that does not is taken to have stopped once its clock has
  // stood still here for 0.2 s.
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

void RobotConnection::resumeAfterFailure() noexcept {
  if (!paused_) return;
  paused_ = false;
  try {
    // A simulator that is gone or stopped is waited for briefly only (the rollout has failed already).
    std_srvs::SetBool request;
    request.request.data = false;
    (void)caller_->call(robot_.pause_service, request, std::min(robot_.timeout, kResumeTimeout));
  } catch (const std::exception&) {  // best effort: the next rollout resumes it first anyway
  }
}

void RobotConnection::stepUntil(double until, double dt, const std::string& what) {
  bimanual_skills::SimStep step;
  step.request.steps = static_cast<std::uint32_t>(std::max(0L, std::lround((until - paused_at_) / dt)));
  // As long as the controllers' states go on: a simulator paces a step for controllers outside it at its
  // real-time factor, whatever that is.
  long seen = progress().slowest;
  call(robot_.step_service, step, robot_.timeout, what, Retry::Never, [&] {
    const long now = progress().slowest;
    const bool moved = now > seen;
    seen = now;
    return moved;
  });
  if (!step.response.success) throw RobotFault{tasks::FoldOutcome::RobotFailed, what + ": " + step.response.message};
}

void RobotConnection::waitUntil(const ros::Time& time, const std::string& what) {
  waitWhileMoving([&] { return ros::Time::now() >= time; }, "the robot's clock (" + what + ")", time);
}

ros::Time RobotConnection::reset() {
  std::vector<double> before(arms_.size());
  double scene_before = 0.0;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    // The camera's and the cloth's messages as the arms' states: none counts until the reset answered, then those of
    // the reset scene only (stamped before the last one before the reset, or after the last one when it answered),
    // so that an image of the last rollout's end, stamped later than the reset scene on a simulator, is not taken
    // for the reset scene.
    scene_before = scene_last_stamp_;
    scene_before_reset_ = -std::numeric_limits<double>::infinity();
    scene_reset_answered_ = std::numeric_limits<double>::infinity();
    image_ = depth_ = nullptr;
    info_ = depth_info_ = nullptr;
    cloth_ = nullptr;
    for (std::size_t a = 0; a < states_.size(); ++a) {
      ArmState& arm = *states_[a];
      before[a] = arm.stamp;
      arm.before_reset = -std::numeric_limits<double>::infinity();   // nothing counts until the answer (a reset
      arm.reset_answered = std::numeric_limits<double>::infinity();  // that failed before may have left them set)
    }
  }
  std_srvs::Trigger trigger;
  call(robot_.reset_service, trigger, robot_.reset_timeout, "the reset");
  if (!trigger.response.success) {
    throw RobotFault{tasks::FoldOutcome::RobotFailed, "the reset failed: " + trigger.response.message};
  }
  // The controllers have seen the reset scene once states of it come: stamped before the last one before the reset
  // (a simulation's clock went back) or after the last one when it answered (a robot's clock went on); states still
  // queued from before do not count, however late this process reads them.
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    for (std::size_t a = 0; a < states_.size(); ++a) {
      ArmState& arm = *states_[a];
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
        after = std::numeric_limits<double>::infinity();
        for (const auto& arm : states_) {
          if (arm->after_reset < kStatesAfterReset) return false;
          after = std::min(after, arm->after_reset_stamp);
        }
        return true;
      },
      "the arms' states after the reset");
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& arm : states_) {
      arm->before_reset = -std::numeric_limits<double>::infinity();
      arm->reset_answered = std::numeric_limits<double>::infinity();
    }
    scene_before_reset_ = scene_reset_answered_ = std::numeric_limits<double>::infinity();  // all count again
  }
  return ros::Time(std::max(0.0, after));
}

void RobotConnection::grasp(std::size_t a, bool close) {
  bimanual_skills::ClothGrasp request;
  request.request.arm = arms_[a]->name;
  request.request.grasp = close;
  call(robot_.grasp_service, request, robot_.timeout,
       std::string(close ? "closing " : "opening ") + arms_[a]->name + "'s gripper");
  if (!request.response.success) {
    throw RobotFault{close ? tasks::FoldOutcome::GraspFailed : tasks::FoldOutcome::RobotFailed,
                     request.response.message};
  }
}

void RobotConnection::scheduleRelease(std::size_t a, const ros::Time& release) {
  const std::string& name = arms_[a]->name;
  bimanual_skills::ClothGrasp request;
  request.request.arm = name;
  request.request.grasp = false;
  request.request.stamp = release;
  call(robot_.grasp_service, request, robot_.timeout, "scheduling " + name + "'s release");
  if (!request.response.success) throw RobotFault{tasks::FoldOutcome::RobotFailed, request.response.message};
  if (std::abs((request.response.executed - release).toSec()) > 1e-6) {
    std::ostringstream message;
    message << "the gripper service " << robot_.grasp_service << " does not schedule: " << name
            << "'s release for t = " << release.toSec() << " s was done at " << request.response.executed.toSec()
            << " s";
    throw RobotFault{tasks::FoldOutcome::RobotFailed, message.str()};
  }
}

double RobotConnection::moveTime(const std::vector<Eigen::VectorXd>& from, const std::vector<Eigen::VectorXd>& to,
                                 const std::vector<Eigen::VectorXd>& limits, double shortest) {
  double time = shortest;
  for (std::size_t a = 0; a < from.size(); ++a) {
    for (Eigen::Index j = 0; j < limits[a].size(); ++j) {
      time = std::max(time, kQuinticPeak * std::abs(to[a][j] - from[a][j]) / (kMoveSpeedShare * limits[a][j]));
    }
  }
  return time;
}

std::vector<Eigen::VectorXd> RobotConnection::measuredPositions() {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::vector<Eigen::VectorXd> q;
  for (std::size_t a = 0; a < arms_.size(); ++a) {
    if (states_[a]->actual.size() != static_cast<Eigen::Index>(arms_[a]->joints.size())) {
      throw RobotFault{tasks::FoldOutcome::RobotFailed, arms_[a]->name + "'s controller state has not come"};
    }
    q.push_back(states_[a]->actual);
  }
  return q;
}

bool RobotConnection::moveWithin(const std::vector<Eigen::VectorXd>& targets, double time, double timeout) {
  for (std::size_t a = 0; a < arms_.size(); ++a) {
    Arm& arm = *arms_[a];
    if (!arm.client->isServerConnected()) throw RobotFault{tasks::FoldOutcome::RobotFailed, arm.name + " is gone"};
    bimanual_skills::FollowJointTrajectoryGoal goal;
    goal.trajectory.joint_names = arm.joints;
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(targets[a].size());
    goal.trajectory.points.push_back(trajectoryPoint(targets[a], zero, zero, time));
    sendGoal(a, goal);
  }
  // At most the move's time and `timeout` more, and no longer than `timeout` after every arm's controller last sent
  // a state (a controller that stalled will not get there).
  const auto limit = std::chrono::duration<double>(timeout);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(time) + limit;
  auto silent = std::chrono::steady_clock::now() + limit;
  long seen = progress().slowest;
  bool there = true;
  for (const auto& arm : arms_) {
    while (!arm->client->getState().isDone() && ros::ok()) {
      const auto now = std::chrono::steady_clock::now();
      if (const long slowest = progress().slowest; slowest > seen) {
        seen = slowest;
        silent = now + limit;
      }
      if (now > deadline || now > silent) break;
      std::this_thread::sleep_for(std::chrono::duration<double>(kPoll));
    }
    there = there && arm->client->getState() == actionlib::SimpleClientGoalState::SUCCEEDED;
  }
  if (!there) cancelGoals();  // a robot that wakes up must not run the recovery into the next rollout
  return there;
}

std::string RobotConnection::openGrippers(double timeout) noexcept {
  std::string done;
  for (const auto& arm : arms_) {
    try {
      bimanual_skills::ClothGrasp request;
      request.request.arm = arm->name;
      request.request.grasp = false;
      const CallOutcome outcome = caller_->call(robot_.grasp_service, request, std::min(robot_.timeout, timeout));
      done +=
          (done.empty() ? "" : ", ") + arm->name +
          (outcome == CallOutcome::Answered && request.response.success
               ? "'s gripper opened"
               : "'s gripper not opened (" +
                     (outcome == CallOutcome::Answered ? request.response.message : std::string(describe(outcome))) +
                     ")");
    } catch (const std::exception& e) {
      done += (done.empty() ? "" : ", ") + arm->name + "'s gripper not opened (" + e.what() + ")";
    }
  }
  return done;
}

std::string RobotConnection::recover(const std::vector<Eigen::VectorXd>& targets,
                                     const std::vector<Eigen::VectorXd>& limits, double timeout,
                                     const std::string& moved, const std::string& not_moved) noexcept {
  std::string done = openGrippers(timeout);
  try {
    const double time = moveTime(measuredPositions(), targets, limits, 0.5);
    done += ", " + (moveWithin(targets, time, std::min(robot_.timeout, timeout)) ? moved : not_moved);
  } catch (const RobotFault& f) {
    done += ", " + not_moved + " (" + f.reason + ")";
  } catch (const std::exception& e) {
    done += std::string(", the recovery stopped: ") + e.what();
  }
  return done;
}

void RobotConnection::record(bool on) {
  const std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& arm : states_) {
    arm->recording = on;
    if (!on) continue;
    arm->times.clear();
    arm->positions.clear();
    arm->max_error = 0.0;
  }
}

RobotConnection::Recorded RobotConnection::recorded() {
  const std::lock_guard<std::mutex> lock(mutex_);
  Recorded out;
  for (const auto& arm : states_) {
    out.times.push_back(arm->times);
    out.positions.push_back(arm->positions);
    out.max_error = std::max(out.max_error, arm->max_error);
  }
  return out;
}

void RobotConnection::beginRollout() {
  settle();
  if (!robot_.pause_service.empty()) pause(false);
  if (reconnect_) {
    connectArms();
    reconnect_ = false;
  }
}

std::string RobotConnection::endFailedRollout(tasks::FoldOutcome outcome, bool moved,
                                              const std::vector<Eigen::VectorXd>& targets,
                                              const std::vector<Eigen::VectorXd>& limits, double timeout,
                                              const std::string& at_targets,
                                              const std::string& not_at_targets) noexcept {
  cancelGoals();
  reconnect_ = reconnect_ || outcome == tasks::FoldOutcome::RobotFailed;
  resumeAfterFailure();  // the recovery needs the clock
  if (!moved) return "";
  return "; recovery: " + recover(targets, limits, timeout, at_targets, not_at_targets);
}

RobotConnection::MeasuredPaths RobotConnection::measuredPaths(double rate,
                                                              const std::vector<const kinematics::ChainModel*>& models,
                                                              const std::vector<Eigen::Isometry3d>& bases,
                                                              double origin) {
  record(false);
  const Recorded states = recorded();
  MeasuredPaths out;
  out.max_error = states.max_error;
  const std::vector<std::size_t> samples = states.every(rate);
  const auto count = static_cast<Eigen::Index>(samples.size());
  out.times.resize(count);
  for (Eigen::Index k = 0; k < count; ++k) {
    out.times[k] = states.times.front()[samples[static_cast<std::size_t>(k)]] - origin;
  }
  for (std::size_t a = 0; a < states.positions.size(); ++a) {
    const kinematics::ChainModel& model = *models[a];
    kinematics::ChainData data(model);
    Eigen::MatrixXd joints(model.nq(), count);
    Eigen::Matrix3Xd tool(3, count);
    for (Eigen::Index k = 0; k < count; ++k) {
      const Eigen::VectorXd& q = states.positions[a][samples[static_cast<std::size_t>(k)]];
      (void)kinematics::forwardKinematics(model, data, q);
      joints.col(k) = q;
      tool.col(k) = bases[a] * data.tipPose().translation();
    }
    out.joints.push_back(std::move(joints));
    out.tools.push_back(std::move(tool));
  }
  return out;
}

sensor_msgs::CameraInfo RobotConnection::firstDepthInfo() {
  waitFor(
      [&] {
        const std::lock_guard<std::mutex> lock(mutex_);
        return first_depth_info_ != nullptr;
      },
      "the depth camera_info of " + node_->resolveName(robot_.camera + "/" + robot_.depth));
  const std::lock_guard<std::mutex> lock(mutex_);
  return *first_depth_info_;
}

RgbdReader RobotConnection::reader(const sensor_msgs::CameraInfo& info, const sensor_msgs::CameraInfo* depth_info) {
  try {
    if (!depth_info) return RgbdReader(info);
    std::optional<Eigen::Isometry3d> colour_from_depth;
    if (depth_info->header.frame_id != info.header.frame_id && robot_.register_depth) {
      try {
        colour_from_depth = tf2::transformToEigen(tf_.lookupTransform(info.header.frame_id, depth_info->header.frame_id,
                                                                      ros::Time(0), ros::Duration(robot_.timeout)));
      } catch (const tf2::TransformException& e) {
        throw std::invalid_argument("no transform from the depth camera's frame " + depth_info->header.frame_id +
                                    " to the colour camera's " + info.header.frame_id + " on tf (" + e.what() + ")");
      }
    }
    return RgbdReader(info, *depth_info, colour_from_depth, robot_.register_depth);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error("the camera " + node_->resolveName(robot_.camera) + " cannot be read: " + e.what());
  }
}

std::string RobotConnection::cameraPose(const sensor_msgs::CameraInfo& info, const std::string& world_frame,
                                        Eigen::Isometry3d& pose) {
  try {
    pose = tf2::transformToEigen(
        tf_.lookupTransform(world_frame, info.header.frame_id, ros::Time(0), ros::Duration(robot_.timeout)));
    return "";
  } catch (const tf2::TransformException& e) {
    return "no transform from " + world_frame + " to its frame " + info.header.frame_id + " on tf (" + e.what() + ")";
  }
}

bool RobotConnection::cloudVertices(const sensor_msgs::PointCloud2& cloud, Eigen::Matrix3Xd& vertices) {
  try {
    vertices.resize(3, static_cast<Eigen::Index>(cloud.width) * cloud.height);
    sensor_msgs::PointCloud2ConstIterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z");
    for (Eigen::Index i = 0; i < vertices.cols(); ++i, ++x, ++y, ++z) vertices.col(i) << *x, *y, *z;
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

std::vector<std::size_t> RobotConnection::Recorded::every(double rate) const {
  std::size_t samples = times.empty() ? 0 : std::numeric_limits<std::size_t>::max();
  for (const auto& arm : positions) samples = std::min(samples, arm.size());
  if (samples == 0) return {};
  const std::vector<double>& t = times.front();
  const double period = samples > 1 ? (t[samples - 1] - t[0]) / static_cast<double>(samples - 1) : 1.0;
  const auto stride = static_cast<std::size_t>(std::max(1.0, std::round(1.0 / (rate * period))));
  std::vector<std::size_t> kept;
  for (std::size_t k = 0; k < samples; k += stride) kept.push_back(k);
  return kept;
}

RobotConnection::Frame RobotConnection::frame(const ros::Time& after, bool with_cloth) {
  Frame out;
  with_cloth = with_cloth && !robot_.cloth.empty();
  waitFor(
      [&] {
        const std::lock_guard<std::mutex> lock(mutex_);
        out.image = image_;
        out.depth = depth_;
        out.info = info_;
        out.depth_info = depth_info_;
        out.cloth = cloth_;
        // Stamped after `after` and not ahead of the robot's clock, as its arms' states tell it (this process's clock
        // may still show the time before a simulator's reset: an image of the last rollout's end, rendered late, would
        // pass as one of the reset scene).
        double robot = -std::numeric_limits<double>::infinity();
        for (const auto& arm : states_) robot = std::max(robot, arm->stamp);
        const ros::Time latest(std::max(0.0, robot + kAheadOfClock));
        const auto fresh = [&](const auto& m) { return m && m->header.stamp >= after && m->header.stamp <= latest; };
        // One frame: colour and depth taken together (a camera that stamps them apart, within 20 ms).
        return fresh(out.image) && fresh(out.depth) && fresh(out.info) && fresh(out.depth_info) &&
               (!with_cloth || fresh(out.cloth)) &&
               std::abs((out.image->header.stamp - out.depth->header.stamp).toSec()) <= kFrameSpread;
      },
      "the camera " + robot_.camera + (with_cloth ? " and the cloth " + robot_.cloth : ""));
  if (!with_cloth) out.cloth = nullptr;
  return out;
}

}  // namespace bimanual_skills::ros_layer
