// rostest (test/scarf_on_robot.test): the scarf through the ROS backend against sim.launch's scarf scene.
// 1. The demonstration as a ScarfOnRobotTask rollout: it finishes, its cost is the sum of its terms, c_t is the
//    in-process task's to the bit (the same plan), c_torque comes from the arm's controller's observer, c_cam from
//    the RGB-D camera's colour image (640 x 480), the scarf's truth from bullet_sim's cloud.
// 2. Settings that cannot work are refused with the reason: two arms, a camera that is not the task's.
// 3. A short learning (PI2-CMA, 2 epochs x 3 rollouts) through ROS with bullet_sim killed (SIGKILL) after its second
//    rollout: the rollout that meets the dead simulator fails with the reason (its service by name), is retried, and
//    the learning stops after robot_fault_limit faults in a row, saying why; nothing the dead robot did is learned
//    from.
#include "bimanual_skills/rollout/dmp_learning.hpp"
#include "bimanual_skills/rollout/parallel_evaluator.hpp"
#include "bimanual_skills/rollout/scarf_learning.hpp"
#include "bimanual_skills/ros_layer/robot/scarf_on_robot.hpp"
#include "cli/pinned_numerics.hpp"
#include "node_pid.hpp"

#include <ros/ros.h>
#include <std_srvs/SetBool.h>

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/types.h>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace bs = bimanual_skills;
namespace br = bimanual_skills::rollout;

namespace {

br::ScarfLearningConfig shipped() {
  std::string path;
  ros::param::get("~config", path);
  return br::ScarfLearningConfig::fromYamlFile(path);
}

/// The robot's interfaces as a user has them (timeout 30 s: on 2 busy cores the simulator, running as fast as it
/// goes, took up to 13 s to take up a new client's action subscriptions), the reset's wait short enough for a test.
bs::ros_layer::ScarfRobotInterfaces robot() {
  bs::ros_layer::ScarfRobotInterfaces r;
  r.reset_timeout = 10.0;
  return r;
}

double term(const br::RolloutResult& result, const std::string& name) {
  const std::vector<std::string> names = br::ScarfRolloutTask::names();
  return result.terms[std::find(names.begin(), names.end(), name) - names.begin()];
}

}  // namespace

TEST(ScarfOnRobot, RunsTheDemonstrationAsTheTaskDoesInProcess) {
  const br::ScarfLearningConfig config = shipped();
  bs::ros_layer::ScarfOnRobotTask task(config.task, robot());
  const br::RolloutResult r = task.run(task.initialParameters(), 1);
  ASSERT_TRUE(r.ok) << r.outcome << ": " << r.reason;
  const bs::tasks::ScarfRollout& last = task.lastRollout();
  br::ScarfRolloutTask local(config.task);
  const br::RolloutResult in_process = local.run(local.initialParameters(), 1);
  std::printf(
      "the demonstration through ROS: cost %.3f (c_t %.3f, c_cam %.3f with d %.1f px, c_torque %.3f), winding %.2f "
      "rad, tracking error %.3f rad, in %.2f s; in-process: cost %.3f (c_cam %.3f with d %.1f px, c_torque %.3f), "
      "winding %.2f rad\n",
      last.cost, last.c_acceleration, last.c_cam, last.camera.d, last.c_torque, last.truth.winding,
      last.max_tracking_error, r.wall_seconds, -in_process.reward, term(in_process, "c_cam"), term(in_process, "d"),
      term(in_process, "c_torque"), term(in_process, "winding"));
  EXPECT_NEAR(last.cost, last.c_acceleration + last.c_cam + last.c_torque, 1e-12);
  EXPECT_EQ(last.c_acceleration, term(in_process, "c_acceleration")) << "the same plan, the same c_t";
  EXPECT_GT(last.mean_abs_torque, 0.0);
  EXPECT_GE(last.peak_abs_torque, last.mean_abs_torque);
  // The controller's observer (its FIR filtered) against the task's own: the same order of magnitude.
  EXPECT_GT(last.mean_abs_torque, 0.3 * term(in_process, "mean_abs_torque"));
  EXPECT_LT(last.mean_abs_torque, 3.0 * term(in_process, "mean_abs_torque"));
  EXPECT_TRUE(std::isnan(last.mean_tool_force)) << "the simulator's inside is not the robot's to tell";
  EXPECT_EQ(last.bgr.cols, 640);
  EXPECT_EQ(last.bgr.rows, 480);
  EXPECT_TRUE(last.camera.nose_seen);
  EXPECT_TRUE(last.camera.scarf_seen);
  EXPECT_EQ(last.cloth_vertices.cols(), 180) << "bullet_sim's scarf cloud";
  EXPECT_LT(last.max_tracking_error, 0.2);
  EXPECT_GT(last.path_times.size(), 100);
  EXPECT_NEAR(last.simulated_seconds, 10.3, 1e-9);
  EXPECT_EQ(r.trajectory.rows(), 3);
  // The tool's measured path ends where the in-process one does (the same references and controller; another timeline).
  EXPECT_LT((r.trajectory.rightCols(1) - in_process.trajectory.rightCols(1)).norm(), 0.02);
}

TEST(ScarfOnRobot, SettingsThatCannotWorkAreRefusedWithTheReason) {
  const br::ScarfLearningConfig config = shipped();
  const auto refused = [&](bs::ros_layer::ScarfRobotInterfaces interfaces, const std::string& expected) {
    try {
      bs::ros_layer::ScarfOnRobotTask task(config.task, interfaces);
      ADD_FAILURE() << "accepted; expected a refusal naming " << expected;
    } catch (const std::exception& e) {
      std::printf("refused: %s\n", e.what());
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  };
  bs::ros_layer::ScarfRobotInterfaces r = robot();
  r.arms = {"left", "right"};
  refused(r, "one arm");
  r = robot();
  r.trajectory_rate = 0.0;
  refused(r, "trajectory_rate");
  // bullet_sim's top-down camera: an orthographic map, not the task's perspective camera.
  r = robot();
  r.camera = "camera";
  refused(r, "the camera /camera cannot be used: it is an orthographic camera");
  // The task's camera elsewhere: the cost's pixel thresholds would be another camera's.
  bs::tasks::ScarfTaskConfig moved = config.task;
  const std::string start = ::testing::TempDir() + "/scarf_start_moved.yaml";
  {
    std::ifstream in(config.task.start);
    std::ofstream out(start);
    for (std::string line; std::getline(in, line);) {
      out << (line.rfind("rgbd_eye:", 0) == 0 ? "rgbd_eye: [-0.45, 0.45, 0.62]" : line) << '\n';
    }
  }
  moved.start = start;
  try {
    bs::ros_layer::ScarfOnRobotTask task(moved, robot());
    ADD_FAILURE() << "a camera 5 cm from the task's was accepted";
  } catch (const std::runtime_error& e) {
    std::printf("refused: %s\n", e.what());
    EXPECT_NE(std::string(e.what()).find("from the task's camera"), std::string::npos) << e.what();
  }
}

// A learner stopped while the simulator stood still leaves it paused; a paused simulator's trajectory actions publish
// no status (actionlib's status timer runs on its clock), so no new client could connect: the task resumes it first.
TEST(ScarfOnRobot, ATaskBuiltWhileTheSimulatorIsPausedConnects) {
  const br::ScarfLearningConfig config = shipped();
  std_srvs::SetBool pause;
  pause.request.data = true;
  ASSERT_TRUE(ros::service::call("/bullet_sim/pause", pause) && pause.response.success) << pause.response.message;
  const ros::Time paused_at = ros::Time::now();
  ros::WallDuration(1.0).sleep();  // longer than the actions' status period: their last status is old
  try {
    bs::ros_layer::ScarfOnRobotTask task(config.task, robot());
  } catch (const std::exception& e) {
    ADD_FAILURE() << e.what();
  }
  EXPECT_GT(ros::Time::now(), paused_at) << "the simulator was not resumed";
}

// Last: it kills the simulator.
TEST(ScarfOnRobot, ALearningWithAKilledSimulatorStopsWithTheReason) {
  br::ScarfLearningConfig config = shipped();
  br::DmpLearningConfig& l = config.learning;
  l.algorithms = {"PI2-CMA"};
  l.runs = 1;
  l.updates = 1;
  l.rollouts = 3;
  l.robot_retries = 1;
  l.robot_fault_limit = 2;
  const std::string dir = ::testing::TempDir() + "/scarf_on_robot";
  std::filesystem::remove_all(dir);
  const pid_t simulator = static_cast<pid_t>(bs::test::nodePid("/bullet_sim"));
  ASSERT_GT(simulator, 0) << "no /bullet_sim node answers getPid";
  // A dead simulator's faults within 10 s each.
  bs::ros_layer::ScarfRobotInterfaces interfaces = robot();
  interfaces.timeout = 10.0;
  const bs::tasks::ScarfTaskConfig task = config.task;
  int finished = 0, faults = 0, faults_after_kill = 0;
  bool killed = false;
  br::DmpLearningObserver observer;
  observer.rollout = [&](const br::DmpRolloutRecord& record, br::RolloutTask*) {
    std::printf("  rollout %s %d: %s, cost %.3f\n", br::toString(record.kind), record.index,
                record.result.outcome.c_str(), -record.result.reward);
    if (++finished == 2) {
      std::printf("  bullet_sim killed (SIGKILL)\n");
      ::kill(simulator, SIGKILL);
      killed = true;
    }
  };
  observer.robot_fault = [&](const br::DmpRolloutRecord&, int attempt, const std::string& reason, bool retry) {
    std::printf("  robot fault, attempt %d: %s%s\n", attempt, reason.c_str(), retry ? "; running it again" : "");
    ++faults;
    faults_after_kill += killed ? 1 : 0;
  };
  const auto start = std::chrono::steady_clock::now();
  try {
    br::DmpLearner(
        br::scarfTaskModel(bs::tasks::ScarfTask(task)), l, dir,
        std::make_unique<br::ParallelEvaluator>(
            [task, interfaces] { return std::make_unique<bs::ros_layer::ScarfOnRobotTask>(task, interfaces); }, 1),
        observer)
        .learn();
    ADD_FAILURE() << "the learning went on with a dead simulator";
  } catch (const br::RobotFaults& e) {
    std::printf("the learning stopped after %.1f s: %s\n",
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), e.what());
    EXPECT_NE(std::string(e.what()).find("2 times in a row (robot_fault_limit 2)"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("within 10 s"), std::string::npos) << e.what();
  }
  EXPECT_EQ(finished, 2);
  // The dead simulator: robot_fault_limit faults in a row. (A loaded machine may give a live one a fault before the
  // kill too: retried, and not learned from, as the file below shows.)
  EXPECT_EQ(faults_after_kill, 2) << faults << " faults in all";
  int lines = -1;  // the header
  std::ifstream rollouts(dir + "/rollouts.csv");
  for (std::string line; std::getline(rollouts, line); ++lines) {
    EXPECT_EQ(line.find("RobotFailed"), std::string::npos) << "a robot's fault was learned from: " << line;
  }
  EXPECT_EQ(lines, 2);
  // The dead simulator's faults are the last ones (a live one's, on a loaded machine, may come before).
  std::ifstream faults_csv(dir + "/robot_faults.csv");
  std::string line, last;
  std::getline(faults_csv, line);  // the header
  while (std::getline(faults_csv, line)) last = line;
  EXPECT_NE(last.find("/bullet_sim/"), std::string::npos) << "the simulator's interface by name: " << last;
}

namespace {

/// A rollout of scarf.launch's learning as rollouts.csv has it.
struct Row {
  std::string outcome, kind, epoch;
  double c_t = 0.0, d = 0.0, cost = 0.0;
  bool fallen = false;  ///< The scarf's truth: on the floor.
};

/// Waits up to `seconds` for scarf.launch's learner to finish and reads its rollouts; `config` its learning file.
std::vector<Row> learnedRollouts(double seconds, br::ScarfLearningConfig& config) {
  std::string out, config_path;
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(seconds);
  while (ros::ok() && ros::WallTime::now() < deadline &&
         !(ros::param::get("/scarf_learner/out", out) && std::filesystem::exists(out + "/summary.json"))) {
    ros::WallDuration(0.2).sleep();
  }
  if (!std::filesystem::exists(out + "/summary.json")) {
    ADD_FAILURE() << "scarf_learner did not finish in " << seconds << " s";
    return {};
  }
  EXPECT_TRUE(ros::param::get("/scarf_learner/config", config_path));
  config = br::ScarfLearningConfig::fromYamlFile(config_path);
  std::ifstream csv(out + "/rollouts.csv");
  std::string line;
  if (!std::getline(csv, line)) {
    ADD_FAILURE() << "no header in " << out << "/rollouts.csv";
    return {};
  }
  const auto cells = [](const std::string& text) {
    std::vector<std::string> out;
    std::stringstream stream(text);
    for (std::string cell; std::getline(stream, cell, ',');) out.push_back(cell);
    return out;
  };
  const std::vector<std::string> header = cells(line);
  const auto column = [&](const std::string& name) {
    return static_cast<std::size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  };
  const std::size_t outcome = column("outcome"), kind = column("kind"), epoch = column("epoch"),
                    c_t = column("c_acceleration"), d = column("d"), cost = column("cost"), fallen = column("fallen");
  std::vector<Row> rows;
  while (std::getline(csv, line)) {
    const std::vector<std::string> row = cells(line);
    if (row.size() <= std::max({outcome, kind, epoch, c_t, d, cost, fallen})) {
      ADD_FAILURE() << "a short row: " << line;
      continue;
    }
    rows.push_back({row[outcome], row[kind], row[epoch], std::stod(row[c_t]), std::stod(row[d]), std::stod(row[cost]),
                    row[fallen] == "1"});
  }
  return rows;
}

}  // namespace

// test/scarf_offset_wrist.test: scarf.launch robot:=config/robots/offset_wrist.yaml backend:=ros learns through ROS
// on the Panda-like pair (its learning files placed for it by scarf_learner _write_scarf_files): every rollout is
// the robot's to the end, the noise-free policy's c_t is the in-process task's on that pair (the same plan), and its
// camera sees the scarf and the mannequin.
TEST(OtherPair, ScarfLaunchLearnsThroughROSOnTheOffsetWristPair) {
  br::ScarfLearningConfig config;
  const std::vector<Row> rows = learnedRollouts(400.0, config);
  ASSERT_FALSE(rows.empty());
  EXPECT_NE(config.task.sim_config.find("offset_wrist"), std::string::npos) << config.task.sim_config;
  br::ScarfRolloutTask local(config.task);
  EXPECT_EQ(local.task().jointNames()[static_cast<std::size_t>(local.task().arm())].front(), "left_joint1");
  const br::RolloutResult in_process = local.run(local.initialParameters(), 1);
  ASSERT_TRUE(in_process.ok) << in_process.reason;
  for (const Row& row : rows) {
    EXPECT_EQ(row.outcome, "Ok");
    EXPECT_TRUE(std::isfinite(row.cost));
    EXPECT_GT(row.d, 0.0) << "the camera saw the scarf and the nose mark";
    if (row.kind == "policy" && row.epoch == "0") {
      // The learner's first policy is its DMP's encoding of the demonstration: the same plan to rounding.
      EXPECT_NEAR(row.c_t, term(in_process, "c_acceleration"), 1e-9) << "the same plan, the same c_t";
      std::printf("the demonstration on the offset-wrist pair: cost %.3f through ROS, %.3f in-process\n", row.cost,
                  -in_process.reward);
    }
  }
  EXPECT_EQ(rows.size(), 8u) << "the noise-free policy and 3 rollouts of each of 2 epochs (1 update)";
}

// test/scarf_hardware.test: scarf.launch backend:=ros hardware:=true (the wall clock, the controller in a process of
// its own, a Kinect's raw images with the arm in view) learns with config/scarf_hardware_learning.yaml: the arm
// leaves the camera's view while the scarf settles, so that the scored image shows the scarf. Before that move the
// arm hid the scarf in 2 of 3 final images (d at the image's bottom, c_cam 162.6). Every rollout is the robot's to
// the end or the policy's failure; the demonstration's c_t is the in-process task's; the camera sees every scarf that
// its truth (bullet_sim's cloud) has on the mannequin rather than on the floor (d within the image).
TEST(Hardware, ScarfLaunchLearnsWithTheArmOutOfTheCamerasView) {
  br::ScarfLearningConfig config;
  const std::vector<Row> rows = learnedRollouts(600.0, config);
  ASSERT_FALSE(rows.empty());
  EXPECT_GT(config.task.clear_posture.size(), 0) << "the learning file of a camera that sees the arm";
  br::ScarfRolloutTask local(config.task);
  const br::RolloutResult in_process = local.run(local.initialParameters(), 1);
  ASSERT_TRUE(in_process.ok) << in_process.reason;
  int policies = 0, on_the_mannequin = 0;
  for (const Row& row : rows) {
    // The policy's failures count (the controller's 3.5 rad/s monitor stops a hard strike); the robot's would be
    // retried and are not rows.
    EXPECT_TRUE(row.outcome == "Ok" || row.outcome == "ControllerFailed") << row.outcome;
    if (row.outcome == "Ok" && !row.fallen) {
      ++on_the_mannequin;
      EXPECT_LT(row.d, 480.0) << "the arm hides the scarf below the nose mark (" << row.kind << ", epoch " << row.epoch
                              << ")";
    }
    if (row.kind != "policy") continue;
    ++policies;
    if (row.epoch == "0" && row.outcome == "Ok") {
      EXPECT_NEAR(row.c_t, term(in_process, "c_acceleration"), 1e-9) << "the same plan, the same c_t";
      std::printf("the demonstration on hardware:=true: cost %.3f, d %.1f px; in-process %.3f, d %.1f px\n", row.cost,
                  row.d, -in_process.reward, term(in_process, "d"));
    }
  }
  EXPECT_EQ(policies, 2);
  EXPECT_GT(on_the_mannequin, 0) << "no scarf stayed on the mannequin to look at";
  EXPECT_EQ(rows.size(), 8u) << "the noise-free policy and 3 rollouts of each of 2 epochs (1 update)";
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_scarf_on_robot");
  ros::NodeHandle keep_alive;
  return RUN_ALL_TESTS();
}
