#include "bimanual_skills/ros_layer/robot/scarf_on_robot.hpp"

#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/rollout/coordinated_parameters.hpp"
#include "bimanual_skills/rollout/scarf_learning.hpp"
#include "bimanual_skills/ros_layer/camera_contract.hpp"
#include "bimanual_skills/ros_layer/trajectory_messages.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace bimanual_skills::ros_layer {

namespace {

/// Samples per second of the measured paths in a result.
constexpr double kPathRate = 50.0;
/// Longest wait for each step of the recovery after a failed rollout [s of wall time, beyond the motion's own].
constexpr double kRecoveryTimeout = 3.0;
/// The reset must leave the arm this close to the task's start, else it is moved there first [rad].
constexpr double kAtStart = 0.01;
/// How far the camera may be from the task's: its intrinsics [px], its position [m] and its orientation [rad]. The
/// cost's d_ref and hanging level are pixels of the task's camera.
constexpr double kIntrinsicsTolerance = 0.5, kPositionTolerance = 0.01, kAngleTolerance = 0.01;

}  // namespace

void ScarfRobotInterfaces::validate() const {
  const auto fail = [](const std::string& what) { throw std::invalid_argument("scarf on the robot: " + what); };
  RobotInterfaces::validate("scarf on the robot");
  if (arms.size() != 1)
    fail("one arm (the one holding the scarf) is needed, " + std::to_string(arms.size()) + " given");
  if (world_frame.empty()) fail("the world frame needs a name");
  if (!(trajectory_rate >= 1.0) || !(trajectory_rate <= 1000.0)) fail("trajectory_rate must lie in [1, 1000] Hz");
  if (!(start_delay >= 0.0) || !(start_delay <= 10.0)) fail("start_delay must lie in [0, 10] s");
  if (!(move_time > 0.0) || !std::isfinite(move_time)) fail("move_time must be finite and > 0");
}

ScarfOnRobotTask::ScarfOnRobotTask(const tasks::ScarfTaskConfig& task, const ScarfRobotInterfaces& robot)
    : task_(task), robot_(robot) {
  robot_.validate();
  connection_ = std::make_unique<RobotConnection>(
      robot_, std::vector<std::vector<std::string>>{task_.jointNames()[static_cast<std::size_t>(task_.arm())]},
      "scarf on the robot", task.sim_config, "", nullptr, nullptr);
  torque_sub_ = connection_->node().subscribe<sensor_msgs::JointState>(
      robot_.arms.front() + "/estimated_external_torque", 1000,
      [this](const sensor_msgs::JointStateConstPtr& m) { onTorque(m); });
  const std::string problem = cameraProblem(connection_->firstCameraInfo());
  if (!problem.empty()) {
    throw std::runtime_error("scarf on the robot: the camera " + connection_->node().resolveName(robot_.camera) +
                             " cannot be used: " + problem);
  }
  try {
    connection_->connectArms();
  } catch (const RobotFault& f) {
    throw std::runtime_error("scarf on the robot: " + f.reason);
  }
}

ScarfOnRobotTask::~ScarfOnRobotTask() {
  torque_sub_.shutdown();  // its callback before the connection's spinner and queue go
  connection_.reset();
}

std::vector<std::string> ScarfOnRobotTask::termNames() const {
  return rollout::ScarfRolloutTask::names();
}

Eigen::VectorXd ScarfOnRobotTask::initialParameters() const {
  const int d = task_.dofs();
  return rollout::encodeCoordinatedPolicy({Eigen::MatrixXd::Identity(d, d)}, task_.demonstrationWeights());
}

void ScarfOnRobotTask::onTorque(const sensor_msgs::JointStateConstPtr& message) {
  const double t = message->header.stamp.toSec();
  const std::lock_guard<std::mutex> lock(mutex_);
  // A message of another size or with a non-finite value is not an estimate of this arm: not counted (none at all
  // fails the rollout as the robot's).
  if (t < torque_from_ || t >= torque_to_ || message->effort.size() != static_cast<std::size_t>(task_.dofs()) ||
      !std::all_of(message->effort.begin(), message->effort.end(), [](double v) { return std::isfinite(v); })) {
    return;
  }
  double sum = 0.0;
  for (const double tau : message->effort) {
    sum += std::abs(tau);
    torque_peak_ = std::max(torque_peak_, std::abs(tau));
  }
  torque_sum_ += sum / static_cast<double>(message->effort.size());
  ++torque_samples_;
}

std::string ScarfOnRobotTask::cameraProblem(const sensor_msgs::CameraInfo& info) {
  if (info.P[8] == 0.0 && info.P[9] == 0.0 && info.P[10] == 0.0 && info.P[11] == 1.0) {
    return "it is an orthographic camera (P's third row is [0 0 0 1]); the cost needs the task's perspective camera";
  }
  std::string problem = cameraInfoProblem(info, CameraModel::Perspective, vision::TopDownCamera{});
  if (!problem.empty()) return problem;
  Eigen::Isometry3d pose;
  problem = connection_->cameraPose(info, robot_.world_frame, pose);
  if (!problem.empty()) return problem;
  const vision::PinholeCamera seen = pinholeCamera(info, pose), &expected = task_.camera();
  std::ostringstream why;
  if (seen.width != expected.width || seen.height != expected.height) {
    why << "its images are " << seen.width << " x " << seen.height << ", the task's camera's " << expected.width
        << " x " << expected.height;
  } else if (std::max({std::abs(seen.fx - expected.fx), std::abs(seen.fy - expected.fy),
                       std::abs(seen.cx - expected.cx), std::abs(seen.cy - expected.cy)}) > kIntrinsicsTolerance) {
    why << "its intrinsics (fx, fy, cx, cy) = (" << seen.fx << ", " << seen.fy << ", " << seen.cx << ", " << seen.cy
        << ") px are not the task's (" << expected.fx << ", " << expected.fy << ", " << expected.cx << ", "
        << expected.cy << ")";
  } else {
    const double offset = (seen.pose.translation() - expected.pose.translation()).norm();
    const double angle = Eigen::AngleAxisd(seen.pose.linear().transpose() * expected.pose.linear()).angle();
    if (offset > kPositionTolerance || angle > kAngleTolerance) {
      why << "its frame " << info.header.frame_id << " lies " << offset << " m and " << angle
          << " rad from the task's camera (the start file's rgbd_eye and rgbd_target; d_ref and the hanging level "
             "are pixels of that camera)";
    }
  }
  return why.str();
}

void ScarfOnRobotTask::moveToStart() {
  const Eigen::VectorXd& start = task_.startPosition();
  const Eigen::VectorXd at = connection_->measuredPositions().front();
  if ((at - start).cwiseAbs().maxCoeff() <= kAtStart) return;
  const std::vector<Eigen::VectorXd> limits = {task_.armModel().velocityLimits()};
  RobotConnection::Arm& arm = connection_->arm(0);
  bimanual_skills::FollowJointTrajectoryGoal goal;
  goal.trajectory.joint_names = arm.joints;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(start.size());
  const double move = RobotConnection::moveTime({at}, {start}, limits, robot_.move_time);
  goal.trajectory.points.push_back(trajectoryPoint(start, zero, zero, move));
  connection_->sendGoal(0, goal);
  connection_->waitForGoal(0, "move to the start", ros::Time::now() + ros::Duration(move),
                           RobotConnection::Blame::Robot);
}

void ScarfOnRobotTask::runPlan(const tasks::ScarfPlan& plan) {
  const tasks::ScarfTaskConfig& c = task_.config();
  const Eigen::VectorXd& start = task_.startPosition();
  // The arm at the task's start, holding the scarf (the reset's, or a move there).
  moveToStart();
  // A simulator stands still until the controller has the goal: the scarf hangs for hold_before exactly.
  if (!robot_.pause_service.empty()) connection_->pause(true);
  const ros::Time origin = ros::Time::now() + ros::Duration(robot_.start_delay);
  origin_ = origin.toSec();
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    torque_from_ = origin.toSec() + plan.move_start * plan.dt;
    torque_to_ = origin.toSec() + plan.release * plan.dt;
    torque_sum_ = torque_peak_ = 0.0;
    torque_samples_ = 0;
  }
  connection_->record(true);
  // One goal: the start held until the motion, the DMP's references (every point's time that of its period in the
  // in-process task), then the last one held.
  RobotConnection::Arm& arm = connection_->arm(0);
  bimanual_skills::FollowJointTrajectoryGoal goal;
  goal.trajectory.header.stamp = origin;
  goal.trajectory.joint_names = arm.joints;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(start.size());
  // Held until the period before the motion's first (column 0 is the reference of period move_start).
  if (plan.move_start > 1)
    goal.trajectory.points.push_back(trajectoryPoint(start, zero, zero, (plan.move_start - 1) * plan.dt));
  const int every = std::max(1, static_cast<int>(std::lround(1.0 / (robot_.trajectory_rate * plan.dt))));
  const auto last = static_cast<int>(plan.position.cols()) - 1;
  for (int j = 0;; j = std::min(j + every, last)) {
    goal.trajectory.points.push_back(trajectoryPoint(plan.position.col(j), plan.velocity.col(j),
                                                     plan.acceleration.col(j), (plan.move_start + j) * plan.dt));
    if (j == last) break;
  }
  goal.trajectory.points.push_back(trajectoryPoint(plan.position.col(last), zero, zero, plan.move_end * plan.dt));
  int last_point = plan.move_end;
  if (plan.clear_end > plan.release) {  // held until the release, then up and out of the camera's view (as in-process)
    goal.trajectory.points.push_back(trajectoryPoint(plan.position.col(last), zero, zero, plan.release * plan.dt));
    goal.trajectory.points.push_back(trajectoryPoint(plan.lifted, zero, zero, plan.lift_end * plan.dt));
    goal.trajectory.points.push_back(trajectoryPoint(c.clear_posture, zero, zero, plan.clear_end * plan.dt));
    last_point = plan.clear_end;
  }
  goal.path_tolerance = pathTolerances(arm.joints, c.max_tracking_error);
  // The end as the path, decided within half the time to the images (a simulator stepped to them stands still
  // there): a goal that ends far off is the policy's.
  goal.goal_tolerance = goal.path_tolerance;
  const double after_motion = (plan.end - last_point) * plan.dt;
  goal.goal_time_tolerance = ros::Duration(0.5 * after_motion);
  connection_->sendGoal(0, goal);
  connection_->waitForAnswers(origin, robot_.start_delay, "the motion's goal");
  if (connection_->goalFailed(0)) connection_->waitForGoal(0, "motion", ros::Time(), RobotConnection::Blame::Policy);
  if (c.release) connection_->scheduleRelease(0, origin + ros::Duration(plan.release * plan.dt));
  const ros::Time end = origin + ros::Duration(plan.end * plan.dt);
  if (connection_->paused() && !robot_.step_service.empty()) {
    connection_->stepUntil(end.toSec(), plan.dt, "stepping the simulator through the motion");
  } else if (connection_->paused()) {
    connection_->pause(false);
  }
  connection_->waitWhileMoving([&] { return connection_->goalFailed(0) || ros::Time::now() >= end; },
                               "the robot's clock (the scarf settling)", end);
  connection_->waitForGoal(0, "motion", origin + ros::Duration(last_point * plan.dt + 0.5 * after_motion),
                           RobotConnection::Blame::Policy);
  connection_->record(false);

  // The cost's terms (the plan's accelerations are in already): the controller's observer, the camera's colour image.
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (torque_samples_ == 0) {
      throw RobotFault{
          tasks::FoldOutcome::RobotFailed,
          "no " + connection_->node().resolveName(robot_.arms.front() + "/estimated_external_torque") +
              " of the arm's " + std::to_string(task_.dofs()) +
              " joints with finite values during the motion (c_torque is the arm's controller's observer)"};
    }
    last_.mean_abs_torque = torque_sum_ / static_cast<double>(torque_samples_);
    last_.peak_abs_torque = torque_peak_;
    torque_to_ = -1.0;
  }
  const RobotConnection::Frame frame = connection_->frame(end, true);
  const std::string problem = cameraProblem(*frame.info);
  if (!problem.empty()) {
    throw RobotFault{tasks::FoldOutcome::RobotFailed, "the camera " + robot_.camera + " cannot be used: " + problem};
  }
  std::string unread;
  try {  // the colour camera as its camera_info says now (raw images rectified into P)
    if (!reader_ || !reader_->madeFor(*frame.info)) {
      reader_ = std::make_unique<RgbdReader>(connection_->reader(*frame.info, nullptr));
    }
    unread = reader_->readColour(*frame.image, last_.bgr);
  } catch (const std::runtime_error& e) {
    unread = e.what();
  }
  if (!unread.empty()) {
    throw RobotFault{tasks::FoldOutcome::RobotFailed, "the camera " + robot_.camera + " cannot be read: " + unread};
  }
  last_.camera = tasks::scarfCameraTerms(last_.bgr, c.camera);
  if (frame.cloth) {
    try {  // a cloud without x, y, z or of another scarf is the robot's fault, not the learner's
      if (!RobotConnection::cloudVertices(*frame.cloth, last_.cloth_vertices)) {
        throw std::invalid_argument("no float fields x, y, z");
      }
      last_.truth = task_.truthOf(last_.cloth_vertices);
    } catch (const std::exception& e) {
      throw RobotFault{tasks::FoldOutcome::RobotFailed, "unusable scarf cloud " + robot_.cloth + ": " + e.what()};
    }
  }
  if (connection_->paused()) connection_->pause(false);  // a simulator stepped to the settled scarf runs on
  last_.simulated_seconds = plan.end * plan.dt;
}

rollout::RolloutResult ScarfOnRobotTask::run(const Eigen::VectorXd& parameters, std::uint32_t /*seed*/) {
  const auto wall_start = std::chrono::steady_clock::now();
  const tasks::ScarfTaskConfig& c = task_.config();
  last_ = tasks::ScarfRollout{};
  // Inside the simulator only: NaN on a robot.
  last_.mean_tool_force = last_.peak_tool_force = std::numeric_limits<double>::quiet_NaN();
  last_.mean_force_error = last_.max_force_error = std::numeric_limits<double>::quiet_NaN();
  bool moved = false;
  try {
    std::vector<Eigen::MatrixXd> coordination;
    Eigen::VectorXd weights;
    if (!rollout::decodeCoordinatedPolicy(parameters, task_.dofs(), c.kernels, coordination, weights)) {
      throw RobotFault{tasks::FoldOutcome::InvalidPolicy, "the parameters do not encode a coordinated policy of " +
                                                              std::to_string(task_.dofs()) + " DoF and " +
                                                              std::to_string(c.kernels) + " weights per latent DoF"};
    }
    const tasks::ScarfPlan plan = task_.plan(coordination, weights);
    last_.acceleration = plan.acceleration_cost;
    if (plan.outcome != tasks::FoldOutcome::Ok) throw RobotFault{plan.outcome, plan.reason};
    connection_->beginRollout();
    if (robot_.move_before_reset) moveToStart();
    (void)connection_->reset();
    moved = true;
    runPlan(plan);
  } catch (const RobotFault& fault) {
    last_.outcome = fault.outcome;
    last_.reason = fault.reason;
  } catch (const std::exception& e) {
    // Anything else the ROS layer throws fails this rollout, not the learning.
    last_.outcome = tasks::FoldOutcome::RobotFailed;
    last_.reason = std::string("the ROS layer failed: ") + e.what();
  }
  if (last_.outcome != tasks::FoldOutcome::Ok) {
    last_.reason += connection_->endFailedRollout(last_.outcome, moved, {task_.startPosition()},
                                                  {task_.armModel().velocityLimits()}, kRecoveryTimeout,
                                                  "the arm back at its start", "the arm not back at its start");
  }
  connection_->resumeAfterFailure();
  // The measured joint and tool paths.
  RobotConnection::MeasuredPaths measured =
      connection_->measuredPaths(kPathRate, {&task_.armModel()}, {task_.basePose()}, origin_);
  last_.max_tracking_error = measured.max_error;
  last_.path_times = std::move(measured.times);
  last_.joint_path = std::move(measured.joints.front());
  last_.tool_path = std::move(measured.tools.front());
  tasks::scoreScarfRollout(c, last_);
  last_.wall_seconds = realtime::secondsSince(wall_start);
  return rollout::ScarfRolloutTask::resultOf(last_);
}

}  // namespace bimanual_skills::ros_layer
