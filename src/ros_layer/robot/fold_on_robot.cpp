#include "bimanual_skills/ros_layer/robot/fold_on_robot.hpp"

#include "bimanual_skills/ClothGrasp.h"
#include "bimanual_skills/SimStep.h"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/rollout/fold_rollout_task.hpp"
#include "bimanual_skills/ros_layer/bounded_call.hpp"
#include "bimanual_skills/ros_layer/camera_contract.hpp"
#include "bimanual_skills/ros_layer/trajectory_messages.hpp"
#include "bimanual_skills/sim/sim_config.hpp"

#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>

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

/// Share of move_time spent reaching the configuration above the start (the rest: coming down onto the cloth).
constexpr double kApproachShare = 0.7;
/// Samples per second of the measured tool paths in a result.
constexpr double kPathRate = 50.0;
/// Longest wait for each step of the recovery after a failed rollout [s of wall time, beyond the motion's own
/// duration]: it is done on a robot that may be down.
constexpr double kRecoveryTimeout = 3.0;
/// Share of the settling time after the release in which a fold's goal must meet its goal tolerances.
constexpr double kGoalTimeShare = 0.5;
/// How far the tools rise before the arms go to their rest posture out of the camera's view (clear_view) [m].
constexpr double kClearLift = 0.15;

}  // namespace

void FoldRobotInterfaces::validate() const {
  const auto fail = [](const std::string& what) { throw std::invalid_argument("fold on the robot: " + what); };
  RobotInterfaces::validate("fold on the robot");
  if (arms.size() != 2) fail("two arms (left, right) are needed, " + std::to_string(arms.size()) + " given");
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
}

namespace {

/// Appends a camera frame at time t to a recording.
void addFrame(tasks::FoldRollout& recording, double t, const cv::Mat& bgr, const cv::Mat& depth) {
  recording.camera_colour.push_back(bgr);
  recording.camera_depth.push_back(depth);
  recording.camera_times.conservativeResize(recording.camera_times.size() + 1);
  recording.camera_times[recording.camera_times.size() - 1] = t;
}

}  // namespace

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
  if (cameraModel(robot_.camera_model) == CameraModel::Perspective) {
    recording_projector_ = std::make_unique<vision::HeightMapProjector>(reward_.config().renderer.camera);
  }
  for (int a = 0; a < 2; ++a) {
    // Above the start: the tool comes down onto the cloth's corner instead of sweeping over the table.
    const Eigen::VectorXd& start = task_.startPositions()[static_cast<std::size_t>(a)];
    Eigen::VectorXd above_start;
    if (!raised(a, start, robot_.approach_height, above_start)) {
      throw std::invalid_argument("fold on the robot: no configuration of " + robot_.arms[static_cast<std::size_t>(a)] +
                                  " near its start with the tool " + std::to_string(robot_.approach_height) +
                                  " m above it");
    }
    above_start_.push_back(above_start);
    if (robot_.clear_view) {
      const Eigen::VectorXd& rest = task_.simConfig().arms[static_cast<std::size_t>(a)].start;
      if (rest.size() != start.size()) {
        throw std::invalid_argument(
            "fold on the robot: clear_view needs the arms' rest posture (the robot file's "
            "start); the simulation file names the arms without one");
      }
      rest_.push_back(rest);
    }
  }
  connection_ = std::make_unique<RobotConnection>(
      robot_, std::vector<std::vector<std::string>>{task_.armModel(0).jointNames(), task_.armModel(1).jointNames()},
      "fold on the robot", task.sim_config, task.robot,
      [this](const sensor_msgs::ImageConstPtr& image, const sensor_msgs::ImageConstPtr& depth) {
        onFrame(image, depth);
      },
      [this](const sensor_msgs::PointCloud2ConstPtr& cloud) { onCloth(cloud); });
  // A camera the reward cannot use is refused once, here, with the reason (and again per image, if it changes).
  const std::string problem = cameraProblem(connection_->firstCameraInfo());
  if (!problem.empty()) {
    throw std::runtime_error("fold on the robot: the camera " + connection_->node().resolveName(robot_.camera) + " (" +
                             robot_.camera_model + ") cannot be used: " + problem);
  }
  try {
    const sensor_msgs::CameraInfo depth_info = connection_->firstDepthInfo();
    reader_ = std::make_unique<RgbdReader>(connection_->reader(connection_->firstCameraInfo(), &depth_info));
  } catch (const RobotFault& f) {
    throw std::runtime_error("fold on the robot: " + f.reason);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(std::string("fold on the robot: ") + e.what());
  }
  ROS_INFO("fold on the robot: the camera %s: %s", connection_->node().resolveName(robot_.camera).c_str(),
           reader_->description().c_str());
  // The arms last: a camera or world the learning cannot use is a setting to change, said before any wait for the
  // robot's actions.
  try {
    connection_->connectArms();
  } catch (const RobotFault& f) {
    throw std::runtime_error("fold on the robot: " + f.reason);
  }
}

FoldOnRobotTask::~FoldOnRobotTask() {
  connection_.reset();
}

std::string FoldOnRobotTask::read(const sensor_msgs::Image& image, const sensor_msgs::Image& depth,
                                  const sensor_msgs::CameraInfo& info, const sensor_msgs::CameraInfo& depth_info,
                                  cv::Mat& bgr, cv::Mat& metres) {
  if (!reader_->madeFor(info, &depth_info)) {
    try {  // a driver that changed its calibration or resolution
      reader_ = std::make_unique<RgbdReader>(connection_->reader(info, &depth_info));
    } catch (const std::runtime_error& e) {
      return e.what();
    }
  }
  return reader_->read(image, depth, bgr, metres);
}

void FoldOnRobotTask::onFrame(const sensor_msgs::ImageConstPtr& image, const sensor_msgs::ImageConstPtr& depth) {
  // While a rollout records: a colour and depth pair of one moment every kImagePeriod, read as the scored images.
  const std::lock_guard<std::mutex> lock(mutex_);
  const double t = (depth->header.stamp - record_start_).toSec();
  if (!recording_frames_ || t < next_image_) return;
  next_image_ = t + kImagePeriod;
  cv::Mat bgr, metres;
  // The reader made for the rollout's camera_info (a new one comes with the scored images; a frame it cannot read
  // is left out of the recording, the scored images fail the rollout with the reason).
  if (!reader_->read(*image, *depth, bgr, metres).empty()) return;
  if (recording_projector_) {  // a perspective camera's frames as the reward's map shows them
    if (recording_projector_->project(bgr, metres, camera_) != vision::VisionStatus::Ok) return;
    bgr = recording_projector_->bgr().clone();
    metres = recording_projector_->depth().clone();
  }
  addFrame(recording_, t, bgr, metres);
}

void FoldOnRobotTask::onCloth(const sensor_msgs::PointCloud2ConstPtr& cloud) {
  const std::lock_guard<std::mutex> lock(mutex_);
  const double t = (cloud->header.stamp - record_start_).toSec();
  if (!recording_frames_ || t < next_cloth_) return;
  next_cloth_ = t + kClothPeriod;
  Eigen::Matrix3Xd vertices;
  if (!RobotConnection::cloudVertices(*cloud, vertices)) return;
  recording_.cloth_frames.push_back(vertices);
  recording_.cloth_times.conservativeResize(recording_.cloth_times.size() + 1);
  recording_.cloth_times[recording_.cloth_times.size() - 1] = t;
}

std::vector<std::string> FoldOnRobotTask::termNames() const {
  return rollout::FoldRolloutTask::names();
}

Eigen::VectorXd FoldOnRobotTask::initialParameters() const {
  return rollout::encodeCoordinatedPolicy(
      {Eigen::MatrixXd::Identity(tasks::ClothFoldTask::kDofs, tasks::ClothFoldTask::kDofs)},
      task_.demonstrationParameters());
}

std::string FoldOnRobotTask::cameraProblem(const sensor_msgs::CameraInfo& info) {
  const CameraModel model = cameraModel(robot_.camera_model);
  const vision::TopDownCamera& map = reward_.config().renderer.camera;
  std::string problem = cameraInfoProblem(info, model, map);
  if (!problem.empty()) return problem;
  Eigen::Isometry3d pose;
  problem = connection_->cameraPose(info, robot_.world_frame, pose);
  if (!problem.empty()) return problem;
  if (model == CameraModel::Orthographic) return orthographicPoseProblem(pose, map);
  const std::lock_guard<std::mutex> lock(mutex_);  // the recording's projection reads it on the spinner
  camera_ = pinholeCamera(info, pose);
  return "";
}

std::vector<Eigen::VectorXd> FoldOnRobotTask::velocityLimits() const {
  return {task_.armModel(0).velocityLimits(), task_.armModel(1).velocityLimits()};
}

bool FoldOnRobotTask::raised(int a, const Eigen::VectorXd& q, double height, Eigen::VectorXd& out) const {
  kinematics::ChainData data(task_.armModel(a));
  (void)kinematics::forwardKinematics(task_.armModel(a), data, q);
  Eigen::Isometry3d up = data.tipPose();
  up.translation() += task_.basePose(a).linear().transpose() * Eigen::Vector3d(0.0, 0.0, height);
  kinematics::GlobalIkParameters parameters;
  parameters.timeout = 1.0;  // never binding: the same configuration under any load
  kinematics::GlobalIkSolver solver(task_.armModel(a), parameters);
  Eigen::VectorXd solution = q;
  if (solver.solve(up, q, solution).status != kinematics::IkStatus::Converged ||
      (solution - q).cwiseAbs().maxCoeff() > 0.5) {
    return false;
  }
  out = solution;
  return true;
}

void FoldOnRobotTask::moveClear(const std::string& what) {
  // Straight up first, then to the rest posture: a tool just released on the folded cloth must not sweep through it
  // on its way out.
  const std::vector<Eigen::VectorXd> now = connection_->measuredPositions();
  std::vector<Eigen::VectorXd> lifted = now;
  // No lift near this posture (an arm at its limits): it goes straight to the rest posture.
  for (std::size_t a = 0; a < 2; ++a) (void)raised(static_cast<int>(a), now[a], kClearLift, lifted[a]);
  const double lift = RobotConnection::moveTime(now, lifted, velocityLimits(), 0.25 * robot_.move_time);
  const double time = lift + RobotConnection::moveTime(lifted, rest_, velocityLimits(), robot_.move_time);
  for (std::size_t a = 0; a < 2; ++a) {
    bimanual_skills::FollowJointTrajectoryGoal goal;
    goal.trajectory.joint_names = connection_->arm(a).joints;
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(rest_[a].size());
    goal.trajectory.points.push_back(trajectoryPoint(lifted[a], zero, zero, lift));
    goal.trajectory.points.push_back(trajectoryPoint(rest_[a], zero, zero, time));
    connection_->sendGoal(a, goal);
  }
  const ros::Time ends_by = ros::Time::now() + ros::Duration(time);
  for (std::size_t a = 0; a < 2; ++a) connection_->waitForGoal(a, what, ends_by, RobotConnection::Blame::Robot);
}

void FoldOnRobotTask::moveToStart() {
  // Both arms together, each segment as long as the widest joint move needs at half its velocity limit (the
  // configured move_time at least): from where the arms are to above the start, then down onto the cloth.
  const std::vector<Eigen::VectorXd> now = connection_->measuredPositions();
  const double up = RobotConnection::moveTime(now, above_start_, velocityLimits(), kApproachShare * robot_.move_time);
  const double down = RobotConnection::moveTime(above_start_, task_.startPositions(), velocityLimits(),
                                                (1.0 - kApproachShare) * robot_.move_time);
  last_move_seconds_ = up + down;
  for (std::size_t a = 0; a < 2; ++a) {
    RobotConnection::Arm& arm = connection_->arm(a);
    bimanual_skills::FollowJointTrajectoryGoal goal;
    goal.trajectory.joint_names = arm.joints;
    const Eigen::VectorXd& q = task_.startPositions()[a];
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(q.size());
    goal.trajectory.points.push_back(trajectoryPoint(above_start_[a], zero, zero, up));
    goal.trajectory.points.push_back(trajectoryPoint(q, zero, zero, up + down));
    connection_->sendGoal(a, goal);
  }
  const ros::Time ends_by = ros::Time::now() + ros::Duration(up + down);
  for (std::size_t a = 0; a < 2; ++a)
    connection_->waitForGoal(a, "move to the start", ends_by, RobotConnection::Blame::Robot);
}

ros::Time FoldOnRobotTask::fold(const tasks::FoldPlan& plan) {
  // One goal per arm over the hold, the movement and the hold up to the release, both starting at the same time;
  // the grippers open at the planned release, as in the in-process task (the scene is sensitive to when: a fold
  // near the table's edge slides on after the release).
  const int every = std::max(1, static_cast<int>(std::lround(1.0 / (robot_.trajectory_rate * plan.dt))));
  const ros::Time start = ros::Time::now() + ros::Duration(robot_.start_delay);
  connection_->record(true);
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    recording_frames_ = true;
    record_start_ = start;
    next_image_ = next_cloth_ = -std::numeric_limits<double>::infinity();
  }
  for (std::size_t a = 0; a < 2; ++a) {
    RobotConnection::Arm& arm = connection_->arm(a);
    bimanual_skills::FollowJointTrajectoryGoal goal;
    goal.trajectory.header.stamp = start;
    goal.trajectory.joint_names = arm.joints;
    for (int k = 0; k <= plan.release; k += every) {
      goal.trajectory.points.push_back(
          trajectoryPoint(plan.position[a].col(k), plan.velocity[a].col(k), plan.acceleration[a].col(k), k * plan.dt));
    }
    goal.path_tolerance = pathTolerances(arm.joints, task_.config().max_tracking_error);
    // The end as the path: a goal that ends far off is the policy's (GOAL_TOLERANCE_VIOLATED), decided within half
    // the settling time, before the images are taken (a simulator stepped to them stands still there).
    goal.goal_tolerance = goal.path_tolerance;
    goal.goal_time_tolerance = ros::Duration(kGoalTimeShare * task_.config().settle);
    connection_->sendGoal(a, goal);
  }
  connection_->waitForAnswers(start, robot_.start_delay, "the fold's goals");
  for (std::size_t a = 0; a < 2; ++a) {
    if (connection_->goalFailed(a)) {
      connection_->waitForGoal(a, "fold trajectory", ros::Time(), RobotConnection::Blame::Policy);
    }
  }
  // The grippers open at the planned release, on the robot's clock: the gripper's loop does it at its time, however
  // late this process would be to ask.
  const ros::Time release = start + ros::Duration(plan.release * plan.dt);
  for (std::size_t a = 0; a < 2; ++a) connection_->scheduleRelease(a, release);
  if (connection_->paused() && !robot_.step_service.empty()) {
    // A simulator steps from the grasp to the settled cloth and stands still there.
    connection_->stepUntil(release.toSec() + task_.config().settle, plan.dt, "stepping the simulator through the fold");
  } else if (connection_->paused()) {
    connection_->pause(false);
  }
  // Until the release, unless an arm's goal fails first (waitForGoal then reports why).
  connection_->waitWhileMoving(
      [&] { return connection_->goalFailed(0) || connection_->goalFailed(1) || ros::Time::now() >= release; },
      "the robot's clock (the fold's release)", release);
  const ros::Time ends_by = release + ros::Duration(kGoalTimeShare * task_.config().settle);
  for (std::size_t a = 0; a < 2; ++a)
    connection_->waitForGoal(a, "fold trajectory", ends_by, RobotConnection::Blame::Policy);
  connection_->record(false);
  return release;
}

struct FoldOnRobotTask::Camera {
  cv::Mat bgr, metres;  ///< In the reward's map.
  ros::Time stamp;
  sensor_msgs::PointCloud2ConstPtr cloth;
};

FoldOnRobotTask::Camera FoldOnRobotTask::cameraImages(const ros::Time& after, bool with_cloth) {
  const RobotConnection::Frame frame = connection_->frame(after, with_cloth);
  const sensor_msgs::ImageConstPtr &image = frame.image, &depth = frame.depth;
  const sensor_msgs::CameraInfoConstPtr& info = frame.info;
  Camera out;
  out.cloth = frame.cloth;
  const std::string problem = cameraProblem(*info);
  if (!problem.empty()) {
    throw RobotFault{tasks::FoldOutcome::RobotFailed, "the camera " + robot_.camera + " cannot be used: " + problem};
  }
  cv::Mat bgr, metres;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    const std::string unread = read(*image, *depth, *info, *frame.depth_info, bgr, metres);
    if (!unread.empty()) {
      throw RobotFault{tasks::FoldOutcome::RobotFailed, "the camera " + robot_.camera + " cannot be read: " + unread};
    }
  }
  out.stamp = image->header.stamp;
  if (cameraModel(robot_.camera_model) == CameraModel::Orthographic) {
    out.bgr = bgr;
    out.metres = metres;
    return out;
  }
  const vision::VisionStatus status = projector_.project(bgr, metres, camera_);
  const vision::HeightMapCoverage& c = projector_.coverage();
  const vision::TopDownCamera& map = projector_.map();
  const double seen = static_cast<double>(c.observed + c.filled) / (map.rows * map.columns);
  if (status != vision::VisionStatus::Ok || seen < robot_.min_coverage) {
    std::ostringstream why;
    why << "the camera's depth re-projected into the reward's map: " << vision::toString(status) << ", " << 100.0 * seen
        << " % of the map seen (min_coverage " << 100.0 * robot_.min_coverage << " %)";
    throw RobotFault{tasks::FoldOutcome::RobotFailed, why.str()};
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
    throw RobotFault{tasks::FoldOutcome::RobotFailed, std::string("the camera does not show the flat cloth after the "
                                                                  "reset: ") +
                                                          e.what()};
  }
}

tasks::FoldRewardTerms FoldOnRobotTask::observe(const ros::Time& after, double acceleration_cost,
                                                const sensor_msgs::PointCloud2ConstPtr& settled_cloth) {
  const Camera camera = cameraImages(after, true);
  const sensor_msgs::PointCloud2ConstPtr& cloth = settled_cloth ? settled_cloth : camera.cloth;
  tasks::FoldRewardTerms terms =
      reward_.evaluateImages(tasks::FoldOutcome::Ok, acceleration_cost, camera.bgr, camera.metres);
  terms.fold_quality = terms.fold_distance = terms.fold_displacement = std::numeric_limits<double>::quiet_NaN();
  if (cloth) {
    Eigen::Matrix3Xd vertices;
    try {  // a cloud without x, y, z or of another cloth is the robot's fault, not the learner's
      if (!RobotConnection::cloudVertices(*cloth, vertices)) throw std::invalid_argument("no float fields x, y, z");
      const tasks::FoldQuality fold = task_.foldQualityOf(vertices);
      terms.fold_quality = fold.q;
      terms.fold_distance = fold.distance;
      terms.fold_displacement = fold.displacement;
    } catch (const std::exception& e) {
      throw RobotFault{tasks::FoldOutcome::RobotFailed, "unusable cloth cloud " + robot_.cloth + ": " + e.what()};
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
    reason = why + connection_->endFailedRollout(outcome, moved, above_start_, velocityLimits(), kRecoveryTimeout,
                                                 "the arms retracted above their start", "the arms not retracted");
  };
  try {
    if (!rollout::decodeCoordinatedPolicy(parameters, tasks::ClothFoldTask::kDofs, task_.policyBasisSize(),
                                          coordination, weights)) {
      throw RobotFault{tasks::FoldOutcome::InvalidPolicy,
                       "the parameters do not encode a coordinated policy of 12 DoF and " +
                           std::to_string(task_.policyBasisSize()) + " weights per latent DoF"};
    }
    const tasks::FoldPlan plan = task_.plan(coordination, weights);
    acceleration_cost = plan.acceleration_cost;
    if (plan.outcome != tasks::FoldOutcome::Ok) throw RobotFault{plan.outcome, plan.reason};
    connection_->beginRollout();
    if (robot_.clear_view) {  // a person lays the cloth flat with the arms out of the way, and the camera sees it so
      moved = true;
      moveClear("move out of the camera's view before the reset");
    }
    observeFlat(connection_->reset());  // the flat cloth: images of the reset scene (this process's clock may lag)
    moved = true;
    moveToStart();
    // The move took last_move_seconds_ (the clock read before it may still be the one before a reset; nor can a
    // time just after a reset take it away: ros::Time is never negative).
    const ros::Time at_start = ros::Time::now();
    // A simulator stands still from the grasp until both arms have the fold's goals: the cloth is held for exactly
    // start_delay before the fold, however long the messages take.
    if (!robot_.pause_service.empty()) connection_->pause(true);
    for (std::size_t a = 0; a < 2; ++a) connection_->grasp(a, true);
    const ros::Time settled = fold(plan) + ros::Duration(task_.config().settle);
    connection_->waitUntil(settled, "the cloth settling");
    // The fold's quality is the cloth's at the task's settle time, as on every backend; the cloth slides on after
    // it (0.05 of q within 3 s on the demonstration), and the images come once the arms are out of the way, at the
    // task's image_delay after the settle time, as in-process.
    const double delay = task_.config().image_delay;
    sensor_msgs::PointCloud2ConstPtr cloth_settled;
    if (robot_.clear_view || delay > 0.0) cloth_settled = cameraImages(settled, true).cloth;
    if (robot_.clear_view) moveClear("move out of the camera's view before the images");
    ros::Time images = settled + ros::Duration(delay);
    if (connection_->paused() && !robot_.step_service.empty()) {
      connection_->stepUntil(images.toSec(), task_.simConfig().step, "stepping the simulator to the images' time");
    } else if (ros::Time::now() < images) {
      connection_->waitUntil(images, "the images' time");
    } else if (robot_.clear_view) {
      // Later than in-process: the arms were out of the camera's view only after the images' time.
      const double late = (ros::Time::now() - images).toSec();
      ROS_WARN_THROTTLE(60.0,
                        "fold on the robot: the arms were out of the camera's view %.2f s after the settle time, "
                        "%.2f s later than the task's image_delay (%.2f s): the images come that much later than "
                        "in-process; raise image_delay in the learning file for one timeline",
                        delay + late, late, delay);
      images = ros::Time::now();
    }
    terms = observe(images, acceleration_cost, cloth_settled);
    if (connection_->paused()) connection_->pause(false);  // a simulator stepped to the settled cloth runs on
    last_robot_seconds_ = last_move_seconds_ + (ros::Time::now() - at_start).toSec();
  } catch (const RobotFault& failure) {
    fail(failure.outcome, failure.reason);
  } catch (const std::exception& e) {
    // Anything else the ROS layer throws (a clock out of range, a transport error) fails this rollout, not the
    // learning.
    fail(tasks::FoldOutcome::RobotFailed, std::string("the ROS layer failed: ") + e.what());
  }
  connection_->resumeAfterFailure();  // a failure while the simulator stood still: it goes on
  // The measured tool paths at kPathRate of the robot's clock.
  RobotConnection::MeasuredPaths measured =
      connection_->measuredPaths(kPathRate, {&task_.armModel(0), &task_.armModel(1)},
                                 {task_.basePose(0), task_.basePose(1)}, record_start_.toSec());
  last_tracking_error_ = measured.max_error;
  if (measured.times.size() > 0) paths = measured.tools;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    recording_.path_times = std::move(measured.times);
    if (!paths.empty()) recording_.joint_path = std::move(measured.joints);
    recording_frames_ = false;
    recording_.outcome = terms.outcome;
    recording_.reason = reason;
    recording_.actual_path = paths;
    recording_.cloth_triangles = task_.clothTriangles();
    recording_.cloth_rest_vertices = task_.clothRestVertices();
    if (recording_.cloth_vertices.cols() > 0) recording_.fold = task_.foldQualityOf(recording_.cloth_vertices);
  }
  rollout::RolloutResult result = rollout::FoldRolloutTask::resultOf(terms, reason, paths);
  result.wall_seconds = realtime::secondsSince(wall_start);
  return result;
}

}  // namespace bimanual_skills::ros_layer
