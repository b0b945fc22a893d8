// rostest (test/fold_on_robot.test): the fold through the ROS backend against sim.launch.
// 1. fold_learner _backend:=ros learns 1 update x 4 rollouts: every rollout ends with a finite reward and an outcome,
//    a finished one scored by the fold reward on the camera's images against the flat cloth it saw after the reset
//    (mismatch strictly inside (0, 1)),
//    the camera topics carry bgr8 and 32FC1 images with their CameraInfo, the trajectory actions report success;
//    the learner's pictures of its final policy (final.png, final_top_K.png) are images the camera sent, not renders.
// 2. A rollout of a FoldOnRobotTask here, with bullet_sim killed (SIGKILL) while the fold's trajectories run, ends
//    as a failed rollout with a reason within the task's timeouts; the next one fails at once too, and neither hangs.
// 3. operator_prompt (the hardware's scene reset) with nobody at its terminal refuses the reset with a reason.
#include "bimanual_skills/FollowJointTrajectoryAction.h"
#include "bimanual_skills/FollowJointTrajectoryActionGoal.h"
#include "bimanual_skills/FollowJointTrajectoryActionResult.h"
#include "bimanual_skills/JointTrajectoryControllerState.h"
#include "bimanual_skills/rollout/fold_learning.hpp"
#include "bimanual_skills/ros_layer/robot/fold_on_robot.hpp"
#include "bimanual_skills/sim/robot_file.hpp"
#include "bimanual_skills/sim/sim_config.hpp"
#include "cli/pinned_numerics.hpp"
#include "node_pid.hpp"

#include <actionlib/client/simple_action_client.h>
#include <actionlib_msgs/GoalStatus.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_srvs/Trigger.h>
#include <opencv2/imgcodecs.hpp>

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/types.h>
#include <algorithm>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace bs = bimanual_skills;

namespace {

std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  bool quoted = false;
  for (const char c : line) {
    if (c == '"') {
      quoted = !quoted;
    } else if (c == ',' && !quoted) {
      cells.push_back(cell);
      cell.clear();
    } else {
      cell += c;
    }
  }
  cells.push_back(cell);
  return cells;
}

/// A hash of an image's pixels (its rows, without padding).
std::size_t pixelHash(const unsigned char* data, std::size_t step, int rows, std::size_t row_bytes) {
  std::string pixels;
  pixels.reserve(row_bytes * static_cast<std::size_t>(rows));
  for (int r = 0; r < rows; ++r) pixels.append(reinterpret_cast<const char*>(data) + step * r, row_bytes);
  return std::hash<std::string>{}(pixels);
}

std::string configPath() {
  std::string path;
  ros::param::get("~config", path);
  return path;
}

/// fold_learner's output directory once it wrote summary.json (at most 240 s of wall time); "" if it did not.
std::string learnerOutput() {
  std::string out;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(240.0);
  while (ros::ok() && ros::WallTime::now() < deadline) {
    if (ros::param::get("/fold_learner/out", out) && std::filesystem::exists(out + "/summary.json")) return out;
    ros::WallDuration(0.1).sleep();
  }
  return "";
}

/// A rollouts.csv: its header and rows of cells.
struct Rollouts {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  /// The index of a column (header.size() when there is none).
  std::size_t column(const std::string& name) const {
    return static_cast<std::size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  }
};

Rollouts readRollouts(const std::string& dir) {
  Rollouts r;
  std::ifstream csv(dir + "/rollouts.csv");
  std::string line;
  if (std::getline(csv, line)) r.header = splitCsv(line);
  while (std::getline(csv, line)) r.rows.push_back(splitCsv(line));
  return r;
}

}  // namespace

TEST(FoldOnRobot, LearnsThroughTheTrajectoryActionsTheGripperAndTheCamera) {
  ros::NodeHandle node;
  std::atomic<int> images{0}, depths{0}, infos{0}, bad_images{0};
  std::mutex hashes_mutex;
  std::set<std::size_t> image_hashes;  // of every colour image the camera sent
  const auto image_sub =
      node.subscribe<sensor_msgs::Image>("/camera/image_raw", 100, [&](const sensor_msgs::ImageConstPtr& m) {
        ++images;
        if (m->encoding != "bgr8" || m->width != 320 || m->height != 240 || m->header.frame_id != "top_down_camera")
          ++bad_images;
        const std::size_t hash = pixelHash(m->data.data(), m->step, static_cast<int>(m->height), 3 * m->width);
        const std::lock_guard<std::mutex> lock(hashes_mutex);
        image_hashes.insert(hash);
      });
  const auto depth_sub =
      node.subscribe<sensor_msgs::Image>("/camera/depth/image_raw", 10, [&](const sensor_msgs::ImageConstPtr& m) {
        ++depths;
        if (m->encoding != "32FC1" || m->width != 320 || m->height != 240) ++bad_images;
      });
  const auto info_sub =
      node.subscribe<sensor_msgs::CameraInfo>("/camera/camera_info", 10, [&](const sensor_msgs::CameraInfoConstPtr& m) {
        ++infos;
        if (m->width != 320 || m->height != 240 || m->K[0] <= 0.0) ++bad_images;
      });
  std::atomic<int> succeeded{0}, failed{0};
  const auto on_result = [&](const bimanual_skills::FollowJointTrajectoryActionResultConstPtr& m) {
    if (m->status.status == actionlib_msgs::GoalStatus::SUCCEEDED && m->result.error_code == 0) {
      ++succeeded;
    } else {
      ++failed;
    }
  };
  const auto left_sub = node.subscribe<bimanual_skills::FollowJointTrajectoryActionResult>(
      "/left/follow_joint_trajectory/result", 20, on_result);
  const auto right_sub = node.subscribe<bimanual_skills::FollowJointTrajectoryActionResult>(
      "/right/follow_joint_trajectory/result", 20, on_result);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const std::string out = learnerOutput();
  ASSERT_FALSE(out.empty()) << "fold_learner did not finish in 240 s";
  const Rollouts rollouts = readRollouts(out);
  const std::size_t outcome = rollouts.column("outcome"), reward = rollouts.column("reward"),
                    reason = rollouts.column("reason"), mismatch = rollouts.column("fold_mismatch"),
                    r_fold = rollouts.column("r_fold");
  ASSERT_LT(reason, rollouts.header.size());
  ASSERT_LT(mismatch, rollouts.header.size());
  int rows = 0, ok = 0;
  for (const std::vector<std::string>& cells : rollouts.rows) {
    const std::string line = cells.empty() ? "" : cells.front() + ", ...";
    ASSERT_EQ(cells.size(), rollouts.header.size()) << line;
    ++rows;
    EXPECT_TRUE(std::isfinite(std::stod(cells[reward]))) << line;
    EXPECT_FALSE(cells[outcome].empty()) << line;
    if (cells[outcome] == "Ok") {
      ++ok;
      // The fold reward of the camera's images against the flat cloth it saw after the reset: a fold is neither the
      // ideal (0) nor the flat cloth (1), nor unknown for want of a flat image (1).
      EXPECT_GT(std::stod(cells[mismatch]), 0.02) << line;
      EXPECT_LT(std::stod(cells[mismatch]), 0.9) << line;
      EXPECT_EQ(std::stod(cells[r_fold]), std::stod(cells[mismatch])) << line;
    } else {
      EXPECT_FALSE(cells[reason].empty()) << line;
    }
  }
  // Epoch 0: its policy and 4 samples; epoch 1: 4 samples and its policy.
  EXPECT_EQ(rows, 10);
  EXPECT_GE(ok, 8) << "most rollouts of a small exploration fold";
  std::printf(
      "through ROS: %d rollouts, %d Ok; %d colour, %d depth images, %d camera_info; goals: %d succeeded, %d not\n",
      rows, ok, images.load(), depths.load(), infos.load(), succeeded.load(), failed.load());
  EXPECT_GT(images, 0);
  EXPECT_GT(depths, 0);
  EXPECT_GT(infos, 0);
  EXPECT_EQ(bad_images, 0);
  // Per successful rollout and arm: the move to the start and the fold (the first rollout's may come before these
  // subscriptions connect: the learner starts beside this test).
  EXPECT_GE(succeeded, 4 * (ok - 1));
  // The robot's pictures are its camera's images: the final policy's scored image and its filmstrip, which moves.
  const std::lock_guard<std::mutex> lock(hashes_mutex);
  std::map<std::string, std::size_t> picture_hashes;
  for (const std::string name : {"final", "final_top_0", "final_top_5"}) {
    const cv::Mat picture = cv::imread(out + "/" + name + ".png", cv::IMREAD_COLOR);
    ASSERT_FALSE(picture.empty()) << out << "/" << name << ".png";
    const std::size_t hash =
        pixelHash(picture.data, picture.step, picture.rows, static_cast<std::size_t>(3 * picture.cols));
    EXPECT_EQ(image_hashes.count(hash), 1U) << name << ".png is not an image the camera sent";
    picture_hashes[name] = hash;
  }
  EXPECT_NE(picture_hashes["final_top_0"], picture_hashes["final"]) << "the filmstrip starts before the fold's end";
  EXPECT_EQ(picture_hashes["final_top_5"], picture_hashes["final"]) << "the filmstrip ends on the image scored";
  EXPECT_TRUE(std::filesystem::exists(out + "/depth_final.png"));
  EXPECT_TRUE(std::filesystem::exists(out + "/best_rollout.bag"));
}

// Before the simulator is killed below: its actions are up, a pause service of another name is not.
TEST(FoldOnRobot, AnAbsentPauseServiceIsRefusedAtOnceNotOnEveryRollout) {
  const bs::rollout::FoldLearningConfig config = bs::rollout::FoldLearningConfig::fromYamlFile(configPath());
  bs::ros_layer::FoldRobotInterfaces robot;
  robot.timeout = 2.0;
  robot.pause_service = "no_such_simulator/pause";
  try {
    bs::ros_layer::FoldOnRobotTask task(config.task, config.reward, robot);
    ADD_FAILURE() << "built without its pause service";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no pause service /no_such_simulator/pause"), std::string::npos) << e.what();
  }
  robot.pause_service = "";  // a robot: no pause, and the task is built
  EXPECT_NO_THROW(bs::ros_layer::FoldOnRobotTask(config.task, config.reward, robot));
}

// A simulator of another world is refused at start, with both digests; the one of the same world is used.
TEST(FoldOnRobot, ASimulatorOfAnotherWorldIsRefused) {
  const bs::rollout::FoldLearningConfig config = bs::rollout::FoldLearningConfig::fromYamlFile(configPath());
  std::string simulated;
  ASSERT_TRUE(ros::param::get("/bullet_sim/world_digest", simulated)) << "bullet_sim gives no ~world_digest";
  EXPECT_EQ(simulated, bs::sim::SimConfig::worldDigest(config.task.sim_config));
  bs::ros_layer::FoldRobotInterfaces robot;
  robot.timeout = 10.0;
  ros::param::set("/other_simulator/world_digest", "00000000deadbeef");
  robot.world_digest = "/other_simulator/world_digest";
  try {
    bs::ros_layer::FoldOnRobotTask task(config.task, config.reward, robot);
    ADD_FAILURE() << "built against a simulator of another world";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("the simulator runs another world: /other_simulator/world_digest is "
                                         "00000000deadbeef"),
              std::string::npos)
        << e.what();
  }
  robot.world_digest = "/bullet_sim/world_digest";
  EXPECT_NO_THROW(bs::ros_layer::FoldOnRobotTask(config.task, config.reward, robot));
}

TEST(FoldOnRobot, AKilledSimulatorGivesAFailedRolloutNotAHang) {
  const bs::rollout::FoldLearningConfig config = bs::rollout::FoldLearningConfig::fromYamlFile(configPath());
  bs::ros_layer::FoldRobotInterfaces robot;
  robot.timeout = 10.0;  // a loaded machine (make test) can take seconds to answer; a dead simulator must still fail
  robot.reset_timeout = 10.0;
  bs::ros_layer::FoldOnRobotTask task(config.task, config.reward, robot);
  const bs::rollout::RolloutResult first = task.run(task.initialParameters(), 1);
  EXPECT_TRUE(first.ok) << first.outcome << ": " << first.reason;
  std::printf(
      "the demonstration through ROS: R = %.4f, q = %.3f, tracking error %.4f rad, %.2f s of the robot's clock in "
      "%.2f s (%.1fx real time)\n",
      first.reward, first.terms[7], task.lastTrackingError(), task.lastRobotSeconds(), first.wall_seconds,
      task.lastRobotSeconds() / first.wall_seconds);
  EXPECT_GT(task.lastRobotSeconds(), 5.0);  // the move to the start, the fold and the settling

  // Kill the simulator the moment the fold's goal (many points) is on its way, from the goal's own callback: the fold
  // and the settling last well under a second of wall time at this machine's real-time factor, and a kill after the
  // last image would leave nothing to fail.
  const pid_t simulator = static_cast<pid_t>(bimanual_skills::test::nodePid("/bullet_sim"));
  ASSERT_GT(simulator, 0) << "no /bullet_sim node answers getPid";
  ros::NodeHandle node;
  std::atomic<bool> folding{false};
  const auto goal_sub = node.subscribe<bimanual_skills::FollowJointTrajectoryActionGoal>(
      "/left/follow_joint_trajectory/goal", 10, [&](const bimanual_skills::FollowJointTrajectoryActionGoalConstPtr& m) {
        if (m->goal.trajectory.points.size() > 10 && !folding.exchange(true)) ::kill(simulator, SIGKILL);
      });
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const auto start = std::chrono::steady_clock::now();
  std::future<bs::rollout::RolloutResult> killed =
      std::async(std::launch::async, [&] { return task.run(task.initialParameters(), 2); });
  while (!folding && std::chrono::steady_clock::now() - start < std::chrono::seconds(30)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_TRUE(folding) << "the fold's goal never came";
  ASSERT_EQ(killed.wait_for(std::chrono::seconds(30)), std::future_status::ready) << "the rollout hangs";
  const bs::rollout::RolloutResult result = killed.get();
  std::printf("bullet_sim killed mid-rollout: %s: %s (%.1f s)\n", result.outcome.c_str(), result.reason.c_str(),
              result.wall_seconds);
  EXPECT_FALSE(result.ok);
  EXPECT_FALSE(result.reason.empty());
  EXPECT_TRUE(std::isfinite(result.reward));
  EXPECT_EQ(result.reward, config.reward.failure_reward);

  // Without a simulator, the next rollout fails as well, within the timeouts.
  std::future<bs::rollout::RolloutResult> next =
      std::async(std::launch::async, [&] { return task.run(task.initialParameters(), 3); });
  ASSERT_EQ(next.wait_for(std::chrono::seconds(30)), std::future_status::ready) << "the rollout hangs";
  const bs::rollout::RolloutResult after = next.get();
  std::printf("no simulator: %s: %s\n", after.outcome.c_str(), after.reason.c_str());
  EXPECT_FALSE(after.ok);
  EXPECT_EQ(after.outcome, "RobotFailed");
  EXPECT_FALSE(after.reason.empty());
}

TEST(FoldOnRobot, TheOperatorPromptWithoutAnOperatorRefuses) {
  ASSERT_TRUE(ros::service::waitForService("/operator_prompt/reset", ros::Duration(10.0)));
  std_srvs::Trigger trigger;
  const auto start = std::chrono::steady_clock::now();
  ASSERT_TRUE(ros::service::call("/operator_prompt/reset", trigger));
  std::printf("operator_prompt without an operator: %s\n", trigger.response.message.c_str());
  EXPECT_FALSE(trigger.response.success);
  EXPECT_FALSE(trigger.response.message.empty());
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));  // ~timeout 2 s
}

TEST(FoldOnRobot, BadInterfaceSettingsAreRefusedByName) {
  using Robot = bs::ros_layer::FoldRobotInterfaces;
  EXPECT_NO_THROW(Robot{}.validate());
  const std::vector<std::pair<std::string, std::function<void(Robot&)>>> bad = {
      {"move_time", [](Robot& r) { r.move_time = std::nan(""); }},
      {"approach_height", [](Robot& r) { r.approach_height = -0.1; }},
      {"trajectory_rate", [](Robot& r) { r.trajectory_rate = 1e6; }},
      {"start_delay", [](Robot& r) { r.start_delay = -1.0; }},
      {"start_delay", [](Robot& r) { r.start_delay = INFINITY; }},
      {"timeout", [](Robot& r) { r.timeout = 0.0; }},
      {"reset_timeout", [](Robot& r) { r.reset_timeout = INFINITY; }},
      {"two arms", [](Robot& r) { r.arms = {"left"}; }},
  };
  for (const auto& [name, spoil] : bad) {
    Robot robot;
    spoil(robot);
    try {
      robot.validate();
      ADD_FAILURE() << name << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
}

// ------------------------------------------------------------------------------------ fold_perspective.test

// fold_learner scores through bullet_sim's perspective RGB-D camera (rgbd/...), its depth re-projected into the
// reward's map; a task that takes either camera for the other model is refused at once with the reason.
TEST(FoldThroughAPerspectiveCamera, LearnsOnTheReprojectedDepthAndRefusesTheWrongModel) {
  // The refusals first, while the learner runs and the simulator publishes (after the learning its clock may stand
  // still, and a camera of a clock that stands still sends nothing).
  const bs::rollout::FoldLearningConfig config = bs::rollout::FoldLearningConfig::fromYamlFile(configPath());
  bs::ros_layer::FoldRobotInterfaces robot;
  robot.timeout = 10.0;
  robot.camera = "rgbd";
  robot.camera_model = "orthographic";
  try {
    bs::ros_layer::FoldOnRobotTask task(config.task, config.reward, robot);
    ADD_FAILURE() << "a perspective camera taken for the orthographic map";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("set the camera model to perspective"), std::string::npos) << e.what();
  }
  robot.camera = "camera";
  robot.camera_model = "perspective";
  try {
    bs::ros_layer::FoldOnRobotTask task(config.task, config.reward, robot);
    ADD_FAILURE() << "the orthographic map taken for a perspective camera";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("set the camera model to orthographic"), std::string::npos) << e.what();
  }
  const std::string out = learnerOutput();
  ASSERT_FALSE(out.empty()) << "fold_learner did not finish in 240 s";
  const Rollouts rollouts = readRollouts(out);
  const std::size_t outcome = rollouts.column("outcome"), mismatch = rollouts.column("fold_mismatch");
  ASSERT_LT(mismatch, rollouts.header.size());
  int rows = 0, ok = 0;
  for (const std::vector<std::string>& cells : rollouts.rows) {
    const std::string line = cells.empty() ? "" : cells.front() + ", ...";
    ++rows;
    if (cells[outcome] != "Ok") continue;
    ++ok;
    EXPECT_GT(std::stod(cells[mismatch]), 0.02) << line;  // a fold, seen: neither the ideal nor the flat cloth
    EXPECT_LT(std::stod(cells[mismatch]), 0.9) << line;
  }
  EXPECT_EQ(rows, 10);
  EXPECT_GE(ok, 8);
  // The pictures are the reward's map (320 x 240), not the camera's 640 x 480 view.
  const cv::Mat final_image = cv::imread(out + "/final.png", cv::IMREAD_COLOR);
  ASSERT_FALSE(final_image.empty());
  EXPECT_EQ(final_image.cols, 320);
  EXPECT_EQ(final_image.rows, 240);
}

// ------------------------------------------------------------------------------------------ second_robot.test

/// An arm's controller state, collected over a window of the robot's clock.
struct StateWindow {
  std::mutex mutex;
  std::vector<std::string> joints;
  std::vector<double> actual;
  double max_error = 0.0, max_velocity = 0.0;
  int messages = 0;
  void add(const bimanual_skills::JointTrajectoryControllerState& s) {
    const std::lock_guard<std::mutex> lock(mutex);
    joints = s.joint_names;
    actual = s.actual.positions;
    for (const double e : s.error.positions) max_error = std::max(max_error, std::abs(e));
    for (const double v : s.actual.velocities) max_velocity = std::max(max_velocity, std::abs(v));
    ++messages;
  }
  void restart() {
    const std::lock_guard<std::mutex> lock(mutex);
    max_error = max_velocity = 0.0;
    messages = 0;
  }
};

/// Waits `seconds` of the robot's clock (bounded in wall time).
void waitRobot(double seconds) {
  const ros::Time until = ros::Time::now() + ros::Duration(seconds);
  const ros::WallTime limit = ros::WallTime::now() + ros::WallDuration(60.0 + 10.0 * seconds);
  while (ros::ok() && ros::Time::now() < until && ros::WallTime::now() < limit) ros::WallDuration(0.01).sleep();
}

// The second robot learns through ROS as the WAM does (its fold's start, gains, braking and payload derived from its
// model), then holds still and tracks a trajectory goal on both arms.
TEST(SecondRobot, LearnsThroughROSThenHoldsAndTracksAGoal) {
  const std::string out = learnerOutput();
  ASSERT_FALSE(out.empty()) << "fold_learner did not finish in 240 s";
  const Rollouts rollouts = readRollouts(out);
  const std::size_t outcome = rollouts.column("outcome"), reason = rollouts.column("reason"),
                    mismatch = rollouts.column("fold_mismatch");
  ASSERT_LT(mismatch, rollouts.header.size());
  int rows = 0, ok = 0;
  for (const std::vector<std::string>& cells : rollouts.rows) {
    const std::string line = cells.empty() ? "" : cells.front() + ", ... " + cells[reason];
    ++rows;
    if (cells[outcome] != "Ok") continue;
    ++ok;
    EXPECT_GT(std::stod(cells[mismatch]), 0.02) << line;
    EXPECT_LT(std::stod(cells[mismatch]), 0.9) << line;
  }
  EXPECT_EQ(rows, 10);
  EXPECT_GE(ok, 8);

  ros::NodeHandle node;
  std::map<std::string, StateWindow> windows;
  std::vector<ros::Subscriber> subscriptions;
  for (const std::string arm : {"left", "right"}) {
    StateWindow& window = windows[arm];
    subscriptions.push_back(node.subscribe<bimanual_skills::JointTrajectoryControllerState>(
        "/" + arm + "/state", 100,
        [&window](const bimanual_skills::JointTrajectoryControllerState::ConstPtr& s) { window.add(*s); }));
  }
  ros::AsyncSpinner spinner(2);
  spinner.start();
  waitRobot(0.5);
  // Holding: the reference stays, the arms do not drift from it (the error is what the joints' friction leaves at
  // the derived gains without friction compensation: the wrist's static friction over its stiffness, ~0.03 rad).
  for (auto& [arm, window] : windows) window.restart();
  waitRobot(2.0);
  for (auto& [arm, window] : windows) {
    const std::lock_guard<std::mutex> lock(window.mutex);
    ASSERT_GT(window.messages, 10) << arm << ": no controller states";
    EXPECT_LT(window.max_error, 0.05) << arm << " does not hold";
    EXPECT_LT(window.max_velocity, 0.05) << arm << " moves while holding";
    std::printf("%s holds: max error %.5f rad, max speed %.4f rad/s\n", arm.c_str(), window.max_error,
                window.max_velocity);
  }
  // A goal on both arms: from the fold's end back to the robot file's start posture (the tools lift off the table)
  // over 3 s, through the middle.
  std::string robot_path;
  ASSERT_TRUE(ros::param::get("/bullet_sim/robot", robot_path));
  const bs::sim::RobotFile robot = bs::sim::RobotFile::fromYamlFile(robot_path);
  std::map<std::string, std::unique_ptr<actionlib::SimpleActionClient<bimanual_skills::FollowJointTrajectoryAction>>>
      clients;
  std::map<std::string, std::vector<double>> goals;
  for (auto& [arm, window] : windows) {
    clients[arm] = std::make_unique<actionlib::SimpleActionClient<bimanual_skills::FollowJointTrajectoryAction>>(
        node, "/" + arm + "/follow_joint_trajectory", false);
    ASSERT_TRUE(clients[arm]->waitForServer(ros::Duration(30.0))) << arm;
    bimanual_skills::FollowJointTrajectoryGoal goal;
    const std::lock_guard<std::mutex> lock(window.mutex);
    goal.trajectory.joint_names = window.joints;
    const std::vector<double> from = window.actual;
    const Eigen::VectorXd& start = robot.arm(arm)->start;
    ASSERT_EQ(static_cast<std::size_t>(start.size()), from.size());
    for (const double s : {0.5, 1.0}) {
      trajectory_msgs::JointTrajectoryPoint point;
      for (std::size_t i = 0; i < from.size(); ++i) {
        point.positions.push_back(from[i] + s * (start[static_cast<Eigen::Index>(i)] - from[i]));
      }
      point.time_from_start = ros::Duration(3.0 * s);
      goal.trajectory.points.push_back(point);
    }
    goals[arm] = goal.trajectory.points.back().positions;
    window.max_error = 0.0;
    clients[arm]->sendGoal(goal);
  }
  for (auto& [arm, client] : clients) {
    ASSERT_TRUE(client->waitForResult(ros::Duration(120.0))) << arm << ": the goal did not end";
    EXPECT_EQ(client->getState(), actionlib::SimpleClientGoalState::SUCCEEDED)
        << arm << ": " << client->getState().text_;
    const auto result = client->getResult();
    ASSERT_TRUE(result);
    EXPECT_EQ(result->error_code, 0) << arm << ": " << result->error_string;
  }
  waitRobot(0.5);
  for (auto& [arm, window] : windows) {
    const std::lock_guard<std::mutex> lock(window.mutex);
    EXPECT_LT(window.max_error, 0.05) << arm << " tracks the goal badly";
    for (std::size_t i = 0; i < goals[arm].size(); ++i) {
      EXPECT_NEAR(window.actual[i], goals[arm][i], 0.05) << arm << " joint " << i + 1;
    }
    std::printf("%s tracks the goal: max tracking error %.4f rad\n", arm.c_str(), window.max_error);
    RecordProperty(arm + "_max_tracking_error_rad", std::to_string(window.max_error));
  }
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_fold_on_robot");
  ros::NodeHandle keep_alive;
  return RUN_ALL_TESTS();
}
