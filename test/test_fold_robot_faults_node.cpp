// rostest (test/fold_robot_faults.test): the fold through the ROS backend when the robot misbehaves, against
// sim.launch, with a fault injector in this node between the task and bullet_sim's gripper service and camera:
// 1. a gripper service that takes a call and never answers fails the rollout within the task's timeout (RobotFailed,
//    naming the call), and the next rollout, with the service answering again, succeeds;
// 2. bullet_sim stopped with SIGSTOP, before a rollout (its first service call hangs) and in the middle of the fold
//    (its actions and clock stand still): each rollout fails in time, and after SIGCONT the next one succeeds;
// 3. a camera that stops in the middle of a rollout fails it (no images in time), the next one succeeds;
// 4. a fault storm in a learning: a gripper that drops every fourth closing call and its retry fails those rollouts,
//    which are run again (never learned from, logged to robot_faults.csv), and a gripper that is down stops the
//    learning after robot_fault_limit faults with the reason.
#include "bimanual_skills/ClothGrasp.h"
#include "bimanual_skills/FollowJointTrajectoryActionGoal.h"
#include "bimanual_skills/rollout/fold_learning.hpp"
#include "bimanual_skills/ros_layer/bounded_call.hpp"
#include "bimanual_skills/ros_layer/robot/fold_on_robot.hpp"
#include "cli/pinned_numerics.hpp"
#include "node_pid.hpp"

#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include <gtest/gtest.h>

#include <signal.h>
#include <sys/types.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace bs = bimanual_skills;

namespace {

using Clock = std::chrono::steady_clock;

std::string configPath() {
  std::string path;
  ros::param::get("~config", path);
  return path;
}

/// Between the task and bullet_sim: the gripper service /faulty/grasp and the camera under /faulty/camera, each
/// passed on or broken on demand. Its callbacks run on a queue and threads of their own, so that a call it holds
/// does not hold the camera.
class FaultInjector {
 public:
  /// DropEveryFourthGraspTwice: every fourth call that closes a gripper fails, and so does the caller's retry of it
  /// at once on a new connection (a single dropped call is retried there and never reaches the learner).
  enum class Gripper { Pass, Hang, DropEveryFourthGraspTwice, Down };

  /// Relays the camera under `source` (bullet_sim's top-down camera, or its RGB-D camera) to /faulty/camera.
  explicit FaultInjector(const std::string& source = "/camera") : source_(source) {
    node_.setCallbackQueue(&queue_);
    grasp_ = node_.advertiseService<bs::ClothGrasp::Request, bs::ClothGrasp::Response>(
        "/faulty/grasp", [this](bs::ClothGrasp::Request& request, bs::ClothGrasp::Response& response) {
          return onGrasp(request, response);
        });
    relay("image_raw", image_sub_, image_pub_);
    relay("depth/image_raw", depth_sub_, depth_pub_);
    relayInfo("camera_info", info_sub_, info_pub_);
    relayInfo("depth/camera_info", depth_info_sub_, depth_info_pub_);
    spinner_.start();
  }
  ~FaultInjector() {
    setGripper(Gripper::Pass);  // lets a hanging call go
    spinner_.stop();
  }

  void setGripper(Gripper mode) {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      gripper_ = mode;
      grasps_ = 0;
      dropped_ = false;
    }
    changed_.notify_all();
  }
  void setCamera(bool on) { camera_on_ = on; }

 private:
  bool onGrasp(bs::ClothGrasp::Request& request, bs::ClothGrasp::Response& response) {
    std::unique_lock<std::mutex> lock(mutex_);
    if (request.grasp) ++grasps_;
    if (gripper_ == Gripper::Hang) {  // until told otherwise (or a minute): the caller must not wait for it
      changed_.wait_for(lock, std::chrono::seconds(60), [this] { return gripper_ != Gripper::Hang; });
      return false;
    }
    if (gripper_ == Gripper::DropEveryFourthGraspTwice && request.grasp) {
      const bool drop = grasps_ % 4 == 0 || dropped_;
      dropped_ = drop && !dropped_;
      if (drop) return false;
    }
    if (gripper_ == Gripper::Down) return false;
    lock.unlock();
    bs::ClothGrasp forwarded;
    forwarded.request = request;
    if (caller_.call("/bullet_sim/grasp", forwarded, 10.0) != bs::ros_layer::CallOutcome::Answered) {
      return false;
    }
    response = forwarded.response;
    return true;
  }

  void relay(const std::string& topic, ros::Subscriber& sub, ros::Publisher& pub) {
    pub = node_.advertise<sensor_msgs::Image>("/faulty/camera/" + topic, 2);
    sub = node_.subscribe<sensor_msgs::Image>(source_ + "/" + topic, 2,
                                              [this, &pub](const sensor_msgs::ImageConstPtr& m) {
                                                if (camera_on_) pub.publish(m);
                                              });
  }
  void relayInfo(const std::string& topic, ros::Subscriber& sub, ros::Publisher& pub) {
    pub = node_.advertise<sensor_msgs::CameraInfo>("/faulty/camera/" + topic, 2);
    sub = node_.subscribe<sensor_msgs::CameraInfo>(source_ + "/" + topic, 2,
                                                   [this, &pub](const sensor_msgs::CameraInfoConstPtr& m) {
                                                     if (camera_on_) pub.publish(m);
                                                   });
  }

  std::string source_;
  ros::CallbackQueue queue_;
  ros::NodeHandle node_;
  bs::ros_layer::ServiceCaller caller_{ros::NodeHandle()};
  ros::AsyncSpinner spinner_{4, &queue_};
  ros::ServiceServer grasp_;
  ros::Subscriber image_sub_, depth_sub_, info_sub_, depth_info_sub_;
  ros::Publisher image_pub_, depth_pub_, info_pub_, depth_info_pub_;
  std::mutex mutex_;
  std::condition_variable changed_;
  Gripper gripper_ = Gripper::Pass;
  int grasps_ = 0;        ///< Calls that close a gripper since the mode was set.
  bool dropped_ = false;  ///< The last call that closes a gripper was dropped (its retry is dropped too).
  std::atomic<bool> camera_on_{true};
};

/// The task through the injector, with short timeouts.
bs::ros_layer::FoldRobotInterfaces faultyRobot() {
  bs::ros_layer::FoldRobotInterfaces robot;
  robot.grasp_service = "/faulty/grasp";
  robot.camera = "/faulty/camera";
  robot.timeout = 5.0;
  robot.reset_timeout = 5.0;
  return robot;
}

/// A rollout and the wall-clock time it took [s].
struct Timed {
  bs::rollout::RolloutResult result;
  double seconds = 0.0;
};

/// Runs a rollout of `task` on a thread and waits at most `limit` for it: a hang fails the test instead of holding it.
Timed runWithin(bs::ros_layer::FoldOnRobotTask& task, std::uint32_t seed, double limit) {
  const auto start = Clock::now();
  auto result = std::async(std::launch::async, [&] { return task.run(task.initialParameters(), seed); });
  if (result.wait_for(std::chrono::duration<double>(limit)) != std::future_status::ready) {
    ADD_FAILURE() << "the rollout hangs (" << limit << " s)";
    std::abort();  // a thread still inside the task: nothing sane is left to do
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return {result.get(), seconds};
}

/// Calls `hook` once, when the fold's trajectory goal (many points) of the left arm is on its way.
class OnFoldGoal {
 public:
  explicit OnFoldGoal(std::function<void()> hook) : hook_(std::move(hook)) {
    sub_ = node_.subscribe<bs::FollowJointTrajectoryActionGoal>(
        "/left/follow_joint_trajectory/goal", 10, [this](const bs::FollowJointTrajectoryActionGoalConstPtr& m) {
          if (m->goal.trajectory.points.size() > 10 && !fired_.exchange(true)) hook_();
        });
    spinner_.start();
  }
  bool fired() const { return fired_; }

 private:
  ros::NodeHandle node_;
  std::function<void()> hook_;
  std::atomic<bool> fired_{false};
  ros::Subscriber sub_;
  ros::AsyncSpinner spinner_{1};
};

void expectRobotFailed(const Timed& run, const std::string& says, double limit) {
  const bs::rollout::RolloutResult& r = run.result;
  std::printf("  -> %s after %.1f s: %s\n", r.outcome.c_str(), run.seconds, r.reason.c_str());
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.outcome, "RobotFailed");
  EXPECT_NE(r.reason.find(says), std::string::npos) << r.reason;
  EXPECT_LT(run.seconds, limit);
}

void expectOk(const Timed& run) {
  const bs::rollout::RolloutResult& r = run.result;
  std::printf("  -> %s after %.1f s, R = %.4f %s\n", r.outcome.c_str(), run.seconds, r.reward, r.reason.c_str());
  EXPECT_TRUE(r.ok) << r.outcome << ": " << r.reason;
}

}  // namespace

TEST(FoldRobotFaults, AStuckGripperServiceFailsTheRolloutInTime) {
  FaultInjector injector;
  const auto config = bs::rollout::FoldLearningConfig::fromYamlFile(configPath());
  bs::ros_layer::FoldOnRobotTask task(config.task, config.reward, faultyRobot());
  std::printf("the gripper service takes the call and never answers:\n");
  injector.setGripper(FaultInjector::Gripper::Hang);
  // Everything before the grasp (reset, images, the move to the start) and the 5 s the call may take.
  expectRobotFailed(runWithin(task, 1, 60.0), "closing left's gripper (/faulty/grasp): no answer in time", 40.0);
  injector.setGripper(FaultInjector::Gripper::Pass);
  std::printf("the gripper service answers again:\n");
  expectOk(runWithin(task, 2, 60.0));
}

TEST(FoldRobotFaults, AStoppedSimulatorFailsTheRolloutInTime) {
  FaultInjector injector;
  const auto config = bs::rollout::FoldLearningConfig::fromYamlFile(configPath());
  bs::ros_layer::FoldOnRobotTask task(config.task, config.reward, faultyRobot());
  const pid_t simulator = static_cast<pid_t>(bs::test::nodePid("/bullet_sim"));
  ASSERT_GT(simulator, 0) << "no /bullet_sim node answers getPid";

  std::printf("bullet_sim stopped (SIGSTOP) before the rollout: its first service call hangs\n");
  ASSERT_EQ(::kill(simulator, SIGSTOP), 0);
  const Timed before = runWithin(task, 1, 60.0);
  ::kill(simulator, SIGCONT);
  expectRobotFailed(before, "no answer in time within 5 s", 15.0);
  std::printf("after SIGCONT:\n");
  expectOk(runWithin(task, 2, 60.0));

  std::printf("bullet_sim stopped (SIGSTOP) the moment the fold's goals go out:\n");
  {
    OnFoldGoal stop([simulator] { ::kill(simulator, SIGSTOP); });
    const Timed during = runWithin(task, 3, 60.0);
    ::kill(simulator, SIGCONT);
    ASSERT_TRUE(stop.fired()) << "the fold's goal never came";
    expectRobotFailed(during, "within 5 s", 40.0);
  }
  std::printf("after SIGCONT:\n");
  expectOk(runWithin(task, 4, 60.0));
}

TEST(FoldRobotFaults, ACameraThatStopsMidRolloutFailsIt) {
  FaultInjector injector;
  const auto config = bs::rollout::FoldLearningConfig::fromYamlFile(configPath());
  bs::ros_layer::FoldOnRobotTask task(config.task, config.reward, faultyRobot());
  std::printf("the camera stops the moment the fold's goals go out:\n");
  {
    OnFoldGoal stop([&injector] { injector.setCamera(false); });
    const Timed r = runWithin(task, 1, 60.0);
    ASSERT_TRUE(stop.fired()) << "the fold's goal never came";
    expectRobotFailed(r, "no answer from the camera /faulty/camera", 40.0);
  }
  injector.setCamera(true);
  std::printf("the camera is back:\n");
  expectOk(runWithin(task, 2, 60.0));
}

TEST(FoldRobotFaults, AFaultStormIsRetriedAndADownRobotStopsTheLearning) {
  FaultInjector injector;
  bs::rollout::FoldLearningConfig config = bs::rollout::FoldLearningConfig::fromYamlFile(configPath());
  config.robot_retries = 3;
  config.robot_fault_limit = 4;
  const auto robot = [&config] {
    const bs::ros_layer::FoldRobotInterfaces interfaces = faultyRobot();
    return std::make_unique<bs::rollout::ParallelEvaluator>(
        [config, interfaces] {
          return std::make_unique<bs::ros_layer::FoldOnRobotTask>(config.task, config.reward, interfaces);
        },
        1);
  };
  const std::string dir = ::testing::TempDir() + "/fold_robot_faults";
  std::filesystem::remove_all(dir);
  int printed = 0;
  bs::rollout::FoldLearningObserver observer;
  observer.robot_fault = [&](const bs::rollout::FoldRolloutRecord& r, int attempt, const std::string& reason,
                             bool retry) {
    std::printf("  robot fault: %s epoch %d %s %d, attempt %d: %s%s\n", r.algorithm.c_str(), r.epoch,
                bs::rollout::toString(r.kind), r.index, attempt, reason.c_str(), retry ? "; running it again" : "");
    ++printed;
  };

  std::printf("a gripper that drops every fourth call that closes it, and its retry (k = 3, m = 4):\n");
  injector.setGripper(FaultInjector::Gripper::DropEveryFourthGraspTwice);
  const bs::rollout::FoldLearningResult storm = bs::rollout::FoldLearner(config, dir, observer, robot()).learn();
  std::printf("  %d rollouts, %d robot faults, each run again\n", storm.simulated, storm.robot_faults);
  EXPECT_GT(storm.robot_faults, 0);
  EXPECT_EQ(printed, storm.robot_faults);
  EXPECT_EQ(storm.simulated, (config.updates + 1) * (config.rollouts + 1));
  int lines = -1;  // the header
  std::ifstream rollouts(dir + "/rollouts.csv");
  for (std::string line; std::getline(rollouts, line); ++lines) {
    EXPECT_EQ(line.find("RobotFailed"), std::string::npos) << "a robot's fault was learned from: " << line;
  }
  EXPECT_EQ(lines, storm.simulated);

  std::printf("a gripper that is down:\n");
  injector.setGripper(FaultInjector::Gripper::Down);
  config.seed += 1;
  const std::string down = dir + "_down";
  std::filesystem::remove_all(down);
  printed = 0;
  try {
    bs::rollout::FoldLearner(config, down, observer, robot()).learn();
    ADD_FAILURE() << "the learning went on with a robot that is down";
  } catch (const bs::rollout::RobotFaults& e) {
    std::printf("  the learning stopped: %s\n", e.what());
    EXPECT_NE(std::string(e.what()).find("4 times in a row (robot_fault_limit 4)"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("the call failed"), std::string::npos) << e.what();
  }
  EXPECT_EQ(printed, 4);
}

// fold_slow_clock.test: bullet_sim at half real time, a task with a 1.5 s timeout: the move to the start (2 s of the
// robot's clock, 4 s of wall time) is a wait for the robot's motion, counted from its clock's last step, so the
// rollout succeeds; a wait for an interface that does not answer still ends after 1.5 s.
TEST(FoldRobotSlowClock, WaitsForTheRobotsMotionScaleWithItsClock) {
  const auto config = bs::rollout::FoldLearningConfig::fromYamlFile(configPath());
  bs::ros_layer::FoldRobotInterfaces robot;
  robot.timeout = 1.5;
  robot.reset_timeout = 10.0;
  bs::ros_layer::FoldOnRobotTask task(config.task, config.reward, robot);
  const Timed slow = runWithin(task, 1, 120.0);
  std::printf("at half real time with a 1.5 s timeout: %s after %.1f s (%.1f s of the robot's clock) %s\n",
              slow.result.outcome.c_str(), slow.seconds, task.lastRobotSeconds(), slow.result.reason.c_str());
  EXPECT_TRUE(slow.result.ok) << slow.result.reason;
  // The move to the start alone, at least 2 s of the robot's clock, took 4 s of wall time: beyond the timeout (the
  // fold itself is one ~step, as fast as the simulator goes).
  EXPECT_GT(slow.seconds, 4.0);
  robot.grasp_service = "/no_gripper_here";
  bs::ros_layer::FoldOnRobotTask broken(config.task, config.reward, robot);
  const Timed missing = runWithin(broken, 2, 120.0);
  expectRobotFailed(missing, "no server within 1.5 s", 60.0);
}

// fold_hardware.test: sim.launch hardware:=true (the wall clock, each arm's controller in a process of its own that
// roslaunch restarts, no pause or step, a Kinect's raw images with the arms in view, a few ms of transport). One
// learning (1 update x 4 rollouts) through the camera's relay, with three faults on the way, each when a fold's goals
// go out: the left controller stopped (SIGSTOP) for 30 s while the robot's clock runs on, the camera stopped for 25 s,
// the left controller killed (roslaunch starts it again). Each fault fails its rollout within the task's timeout as
// the robot's, the rollout runs again, nothing of it is learned, and the learning ends with all its rollouts.
namespace {

/// Calls the k-th hook when the k-th fold goal (many points) of the left arm is on its way, on a thread of its own.
class OnFoldGoals {
 public:
  explicit OnFoldGoals(std::map<int, std::function<void()>> hooks) : hooks_(std::move(hooks)) {
    sub_ = node_.subscribe<bs::FollowJointTrajectoryActionGoal>(
        "/left/follow_joint_trajectory/goal", 10, [this](const bs::FollowJointTrajectoryActionGoalConstPtr& m) {
          if (m->goal.trajectory.points.size() <= 10) return;
          const int k = ++goals_;
          const auto hook = hooks_.find(k);
          if (hook != hooks_.end()) threads_.emplace_back(hook->second);
        });
    spinner_.start();
  }
  ~OnFoldGoals() {
    spinner_.stop();
    for (std::thread& t : threads_) t.join();
  }
  int goals() const { return goals_; }

 private:
  ros::NodeHandle node_;
  std::map<int, std::function<void()>> hooks_;
  std::atomic<int> goals_{0};
  std::vector<std::thread> threads_;
  ros::Subscriber sub_;
  ros::AsyncSpinner spinner_{1};
};

}  // namespace

TEST(FoldHardware, ControllersThatStallOrDieAndACameraThatStopsAreTheRobotsFaultsNeverLearned) {
  FaultInjector injector("/rgbd");
  bs::rollout::FoldLearningConfig config = bs::rollout::FoldLearningConfig::fromYamlFile(configPath());
  config.robot_retries = 8;
  config.robot_fault_limit = 10;
  bs::ros_layer::FoldRobotInterfaces robot;
  robot.pause_service = robot.step_service = "";  // a robot's clock is the wall's
  robot.camera = "/faulty/camera";
  robot.camera_model = "perspective";
  robot.register_depth = true;
  robot.clear_view = true;  // the camera sees the arms
  robot.timeout = 8.0;
  robot.reset_timeout = 30.0;
  const std::string dir = ::testing::TempDir() + "/fold_hardware";
  std::filesystem::remove_all(dir);
  std::mutex mutex;
  std::vector<std::pair<double, std::string>> faults;  // when (s since the learning's start), why
  const auto start = Clock::now();
  const auto since = [&start] { return std::chrono::duration<double>(Clock::now() - start).count(); };
  std::map<std::string, double> injected;  // what, when
  bs::rollout::FoldLearningObserver observer;
  observer.robot_fault = [&](const bs::rollout::FoldRolloutRecord& r, int attempt, const std::string& reason,
                             bool retry) {
    std::printf("  %.1f s: robot fault, %s %d attempt %d: %s%s\n", since(), bs::rollout::toString(r.kind), r.index,
                attempt, reason.c_str(), retry ? "; running it again" : "");
    const std::lock_guard<std::mutex> lock(mutex);
    faults.emplace_back(since(), reason);
  };
  observer.rollout = [&](const bs::rollout::FoldRolloutRecord& r, const bs::tasks::FoldRollout&,
                         const bs::tasks::FoldReward&) {
    std::printf("  %.1f s: %s %d: %s, q %.3f\n", since(), bs::rollout::toString(r.kind), r.index,
                bs::tasks::toString(r.terms.outcome), r.terms.fold_quality);
  };
  const auto mark = [&](const std::string& what) {
    const std::lock_guard<std::mutex> lock(mutex);
    injected[what] = since();
    std::printf("  %.1f s: %s\n", since(), what.c_str());
  };
  bs::rollout::FoldLearningResult result;
  {
    OnFoldGoals hooks({{2,
                        [&] {
                          const pid_t left = static_cast<pid_t>(bs::test::nodePid("/left/ctc_controller"));
                          ASSERT_GT(left, 0);
                          mark("left controller stopped (SIGSTOP) for 30 s");
                          ::kill(left, SIGSTOP);
                          std::this_thread::sleep_for(std::chrono::seconds(30));
                          ::kill(left, SIGCONT);
                          mark("left controller continued (SIGCONT)");
                        }},
                       {5,
                        [&] {
                          mark("camera stopped for 25 s");
                          injector.setCamera(false);
                          std::this_thread::sleep_for(std::chrono::seconds(25));
                          injector.setCamera(true);
                          mark("camera back");
                        }},
                       {8, [&] {
                          mark("left controller killed (roslaunch starts it again)");
                          EXPECT_EQ(std::system("rosnode kill /left/ctc_controller > /dev/null 2>&1"), 0);
                        }}});
    const auto robotBackend = [&] {
      return std::make_unique<bs::rollout::ParallelEvaluator>(
          [config, robot] {
            return std::make_unique<bs::ros_layer::FoldOnRobotTask>(config.task, config.reward, robot);
          },
          1);
    };
    result = bs::rollout::FoldLearner(config, dir, observer, robotBackend()).learn();
  }
  std::printf("%d rollouts, %d robot faults, in %.1f s\n", result.simulated, result.robot_faults, since());
  EXPECT_EQ(result.simulated, (config.updates + 1) * (config.rollouts + 1)) << "the learning did not end whole";
  EXPECT_EQ(injected.size(), 5u) << "not every fault was injected (fewer fold goals?)";
  // Each fault failed its rollout within the timeout (and the move's length) of its injection, as the robot's.
  for (const auto& [what, when] : injected) {
    if (what.find("continued") != std::string::npos || what.find("back") != std::string::npos) continue;
    const auto first = std::find_if(faults.begin(), faults.end(), [&](const auto& f) { return f.first >= when; });
    ASSERT_NE(first, faults.end()) << what << ": no robot fault after it";
    std::printf("%s: the rollout failed %.1f s later: %s\n", what.c_str(), first->first - when, first->second.c_str());
    // The timeout (a stalled controller's silence, a camera's), the start's delay and the recovery's bounded steps
    // (the grippers, the move: 3 s each at most).
    EXPECT_LT(first->first - when, robot.timeout + 10.0) << what;
  }
  // Nothing of a failed rollout was learned: every recorded rollout ran as the policy asked.
  std::ifstream rollouts(dir + "/rollouts.csv");
  int lines = -1;
  for (std::string line; std::getline(rollouts, line); ++lines) {
    EXPECT_EQ(line.find("RobotFailed"), std::string::npos) << "a robot's fault was learned from: " << line;
  }
  EXPECT_EQ(lines, result.simulated);
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_fold_robot_faults");
  ros::NodeHandle keep_alive;
  return RUN_ALL_TESTS();
}
