// rostests of the simulated robot over ROS, as a user drives it: bullet_sim hosting both arms' controllers (or
// separate ctc_controller processes), commanded through the trajectory topic and action and the simulator's
// services. One executable; each .test file runs the suite that fits its launch:
//   sim_control.test   (hosted, lockstep, as fast as possible)  HostedControl.*
//   sim_pacing.test    (hosted, free-running at real time)       Pacing.*
//   sim_external.test  (ctc_controller processes, real time)     ExternalControllers.*
//   sim_500hz.test     (hosted, a 2 ms step, lockstep)           Rate500.*
//   sim_external_lockstep.test (ctc_controller processes, lockstep) ExternalLockstep.*
//   jtc_scenarios.test (ctc_controller processes, real time)     JtcScenarios.*
#include "bimanual_skills/ApplyWrench.h"
#include "bimanual_skills/ClothGrasp.h"
#include "bimanual_skills/FollowJointTrajectoryAction.h"
#include "bimanual_skills/JointTrajectoryControllerState.h"
#include "bimanual_skills/SetPayload.h"
#include "bimanual_skills/SimStep.h"
#include "bimanual_skills/realtime/clock.hpp"
#include "cli/pinned_numerics.hpp"

#include <actionlib/client/simple_action_client.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/WrenchStamped.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/JointState.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace {

using Action = bimanual_skills::FollowJointTrajectoryAction;
using Client = actionlib::SimpleActionClient<Action>;
using Result = bimanual_skills::FollowJointTrajectoryResult;
using Goal = bimanual_skills::FollowJointTrajectoryGoal;
using State = actionlib::SimpleClientGoalState;

const std::vector<std::string> kArms = {"left", "right"};
constexpr double kWeight = 1.5 * 9.81;  ///< Of the payload the tests hang on the left tool [N].

std::vector<std::string> jointNames(const std::string& arm) {
  std::vector<std::string> names;
  for (int i = 1; i <= 7; ++i) names.push_back(arm + "_wam_joint" + std::to_string(i));
  return names;
}

/// Everything a user of the simulated robot sees: joint states, /clock, each arm's controller state, estimated
/// wrench and trajectory action, /diagnostics, the simulator's services.
class SimFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    spinner_.start();
    states_ = node_.subscribe("/joint_states", 100, &SimFixture::onState, this);
    clock_ = node_.subscribe("/clock", 100, &SimFixture::onClock, this);
    diagnostics_ = node_.subscribe("/diagnostics", 100, &SimFixture::onDiagnostics, this);
    for (const std::string& arm : kArms) {
      controller_states_[arm] = node_.subscribe<bimanual_skills::JointTrajectoryControllerState>(
          "/" + arm + "/state", 100, [this, arm](const bimanual_skills::JointTrajectoryControllerState::ConstPtr& m) {
            double worst = 0.0;
            for (double e : m->error.positions) worst = std::max(worst, std::abs(e));
            const std::lock_guard<std::mutex> lock(mutex_);
            if (recording_) max_error_[arm] = std::max(max_error_[arm], worst);
            ++controller_state_count_[arm];
          });
      wrenches_[arm] = node_.subscribe<geometry_msgs::WrenchStamped>(
          "/" + arm + "/estimated_wrench", 1000, [this, arm](const geometry_msgs::WrenchStamped::ConstPtr& m) {
            const std::lock_guard<std::mutex> lock(mutex_);
            force_z_[arm].emplace_back(m->header.stamp.toSec(), m->wrench.force.z);
          });
      commands_[arm] = node_.advertise<trajectory_msgs::JointTrajectory>("/" + arm + "/command", 1, true);
      clients_[arm] = std::make_unique<Client>(node_, "/" + arm + "/follow_joint_trajectory", false);
    }
    // Persistent clients throughout: a non-persistent roscpp call fails now and then although the server answered
    // (ros/ros_comm#1976: the server's close after its answer can reach the client first; 1 run in 12 of this suite).
    pause_ = node_.serviceClient<std_srvs::SetBool>("/bullet_sim/pause", true);
    reset_ = node_.serviceClient<std_srvs::Trigger>("/bullet_sim/reset", true);
    step_ = node_.serviceClient<bimanual_skills::SimStep>("/bullet_sim/step", true);
    payload_ = node_.serviceClient<bimanual_skills::SetPayload>("/bullet_sim/set_payload", true);
    ASSERT_TRUE(step_.waitForExistence(ros::Duration(60.0))) << "bullet_sim did not come up";
    ASSERT_TRUE(waitWall([this] { return positions().size() == 14; }, 60.0)) << "no joint states";
    for (const std::string& arm : kArms) {
      ASSERT_TRUE(waitWall([&] { return clients_[arm]->isServerConnected(); }, 60.0))
          << arm << ": no trajectory action";
      // The subscriptions of this fixture connected (a loaded machine takes a while, and a test's window of a few
      // simulated seconds is a fraction of a second of wall time).
      ASSERT_TRUE(waitWall(
          [&] {
            const std::lock_guard<std::mutex> lock(mutex_);
            return !force_z_[arm].empty() && controller_state_count_[arm] > 0;
          },
          60.0))
          << arm << ": no estimated_wrench or state";
    }
  }

  void TearDown() override { spinner_.stop(); }

  void onState(const sensor_msgs::JointState::ConstPtr& m) {
    if (m->name.size() != 14) return;
    const std::lock_guard<std::mutex> lock(mutex_);
    ++joint_state_count_;
    last_stamp_ = m->header.stamp.toSec();
    for (std::size_t i = 0; i < m->name.size(); ++i) positions_[m->name[i]] = m->position[i];
  }

  void onClock(const rosgraph_msgs::Clock::ConstPtr& m) {
    const std::lock_guard<std::mutex> lock(mutex_);
    clock_samples_.emplace_back(bimanual_skills::realtime::monotonicSeconds(), m->clock.toSec());
    if (clock_samples_.size() > 200000) clock_samples_.erase(clock_samples_.begin(), clock_samples_.begin() + 100000);
  }

  void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
    const std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& status : m->status) {
      for (const auto& kv : status.values) diagnostics_values_[status.name][kv.key] = kv.value;
      diagnostics_values_[status.name]["(message)"] = status.message;
      diagnostics_values_[status.name]["(level)"] = std::to_string(static_cast<int>(status.level));
    }
  }

  long jointStateCount() {
    const std::lock_guard<std::mutex> lock(mutex_);
    return joint_state_count_;
  }
  double lastStamp() {
    const std::lock_guard<std::mutex> lock(mutex_);
    return last_stamp_;
  }

  std::map<std::string, double> positions() {
    const std::lock_guard<std::mutex> lock(mutex_);
    return positions_;
  }

  /// Waits until `done` or `seconds` of wall time.
  static bool waitWall(const std::function<bool()>& done, double seconds) {
    const double end = bimanual_skills::realtime::monotonicSeconds() + seconds;
    while (ros::ok() && bimanual_skills::realtime::monotonicSeconds() < end) {
      if (done()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return done();
  }

  /// Waits for `seconds` of simulated time (at most 30× that in wall time); a clock that does not get there is a
  /// failure that says where the simulated clock and this process' callbacks stood.
  void waitSim(double seconds) {
    const ros::Time end = ros::Time::now() + ros::Duration(seconds);
    if (waitWall([&] { return ros::Time::now() >= end; }, 30.0 * seconds + 10.0)) return;
    const std::lock_guard<std::mutex> lock(mutex_);
    const double now = bimanual_skills::realtime::monotonicSeconds();
    ADD_FAILURE() << "the simulated clock did not reach " << end.toSec() << " s: this process' clock stands at "
                  << ros::Time::now().toSec() << " s; the last /clock message ("
                  << (clock_samples_.empty() ? -1.0 : clock_samples_.back().second) << " s) came "
                  << (clock_samples_.empty() ? -1.0 : now - clock_samples_.back().first)
                  << " s of wall time ago; the last joint state is stamped " << last_stamp_ << " s";
  }

  std::vector<double> armPositions(const std::string& arm) {
    const auto p = positions();
    std::vector<double> q;
    for (const std::string& name : jointNames(arm)) q.push_back(p.at(name));
    return q;
  }

  static trajectory_msgs::JointTrajectory trajectory(const std::string& arm,
                                                     const std::vector<std::vector<double>>& points, double period) {
    trajectory_msgs::JointTrajectory t;
    t.joint_names = jointNames(arm);
    for (std::size_t p = 0; p < points.size(); ++p) {
      trajectory_msgs::JointTrajectoryPoint point;
      point.positions = points[p];
      point.time_from_start = ros::Duration(period * static_cast<double>(p + 1));
      t.points.push_back(point);
    }
    return t;
  }

  /// Sends a goal and waits (bounded) for its end; the result and the final state.
  std::pair<State, Result> follow(const std::string& arm, const Goal& goal, double wall_timeout = 60.0) {
    clients_[arm]->sendGoal(goal);
    const bool finished = clients_[arm]->waitForResult(ros::Duration(wall_timeout));
    EXPECT_TRUE(finished) << arm << ": the goal did not end within " << wall_timeout << " s";
    const auto result = clients_[arm]->getResult();
    return {clients_[arm]->getState(), result ? *result : Result()};
  }

  /// A swing of the left arm's joints 1, 2 and 4 (a 4 s period) for 10 s from q0, as one trajectory.
  static trajectory_msgs::JointTrajectory swing(const std::vector<double>& q0) {
    std::vector<std::vector<double>> points;
    for (int p = 1; p <= 100; ++p) {
      std::vector<double> q = q0;
      const double phase = std::sin(2.0 * M_PI * 0.1 * p / 4.0);
      q[0] += 0.3 * phase;
      q[1] += 0.15 * phase;
      q[3] -= 0.2 * phase;
      points.push_back(q);
    }
    return trajectory("left", points, 0.1);
  }

  /// Mean vertical force the left controller estimates over [2, 10] s of a swing (two periods), by the estimates'
  /// stamps (the robot's clock: however late this process takes them).
  double meanForceWhileSwinging() {
    const std::vector<double> q0 = armPositions("left");
    const double start = ros::Time::now().toSec();
    commands_["left"].publish(swing(q0));
    const bool swung = waitWall(
        [&] {
          const std::lock_guard<std::mutex> lock(mutex_);
          return !force_z_["left"].empty() && force_z_["left"].back().first >= start + 10.5;
        },
        30.0 * 10.5 + 10.0);
    EXPECT_TRUE(swung) << "no estimated wrench stamped 10.5 s after the swing's start (" << start << " s)";
    double sum = 0.0;
    std::size_t count = 0;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      for (const auto& [stamp, force] : force_z_["left"]) {
        if (stamp < start + 2.0 || stamp > start + 10.0) continue;
        sum += force;
        ++count;
      }
    }
    EXPECT_GT(count, 400u);  // publish_rate (100 Hz) of the robot's clock over 8 s
    return count == 0 ? std::nan("") : sum / static_cast<double>(count);
  }

  bool setPayload(double mass) {
    bimanual_skills::SetPayload set;
    set.request.arm = "left";
    set.request.mass = mass;
    return payload_.call(set) && set.response.success;
  }

  /// The left controller's observer restarts and stale states so far, from its diagnostics `name` after a report
  /// newer than this call; -1 where it reports none.
  long disturbances(const std::string& name) {
    const long steps = diagnosticCount(name, "control_steps");
    if (steps < 0) return -1;
    waitWall([&] { return diagnosticCount(name, "control_steps") != steps; }, 5.0);
    const long restarts = diagnosticCount(name, "observer_restarts"), stale = diagnosticCount(name, "stale_states");
    return restarts < 0 || stale < 0 ? -1 : restarts + stale;
  }

  /// The payload the left controller estimates: the difference of the mean vertical force over a swing without and
  /// with 1.5 kg (the friction model's bias cancels), against the weight. Prints and records it. With the
  /// controller's diagnostics `name`, a measurement during which its observer restarted or it held a stale state (a
  /// gap longer than 20 ms in the states it got: the machine, not what is measured) is said and made again from a
  /// reset, up to three times.
  double payloadError(const std::string& label, const std::string& name = "") {
    double error = 0.0;
    for (int attempt = 1; attempt <= 3; ++attempt) {
      const long before = name.empty() ? -1 : disturbances(name);
      const double without = meanForceWhileSwinging();
      EXPECT_TRUE(setPayload(1.5));
      const double with = meanForceWhileSwinging();
      EXPECT_TRUE(setPayload(0.0));
      const double estimate = without - with;
      error = (estimate - kWeight) / kWeight;
      std::printf(
          "%s: estimated payload weight %.3f N (mean vertical force %.3f N without, %.3f N with 1.5 kg; "
          "true %.3f N): error %.2f %%\n",
          label.c_str(), estimate, without, with, kWeight, 100.0 * error);
      const long during = before < 0 ? 0 : disturbances(name) - before;
      if (before >= 0) {
        std::printf("  %ld observer restarts and stale states during it (gaps in the states the controller got)%s\n",
                    during, during > 0 && attempt < 3 ? ": measuring again from the initial pose" : "");
      }
      if (during <= 0 || attempt == 3) break;
      // The controller held the arm where a gap left it: a reset starts the next measurement where the first began.
      std_srvs::Trigger reset;
      EXPECT_TRUE(reset_.call(reset) && reset.response.success);
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        force_z_["left"].clear();  // the clock went back: the old timeline's stamps come again
      }
      waitSim(1.0);
    }
    RecordProperty(label + "_payload_error_percent", std::to_string(100.0 * error));
    return error;
  }

  /// Pauses the simulation; `at`: the time it stopped at, from the answer (this node's clock may lag the
  /// simulator's by more than 0.5 s of it at many times real time on a loaded machine).
  bool pauseAt(double& at) {
    std_srvs::SetBool pause;
    pause.request.data = true;
    if (!pause_.call(pause) || !pause.response.success) {
      ADD_FAILURE() << "pause: " << pause.response.message;
      return false;
    }
    const auto where = pause.response.message.find("at t = ");
    if (where == std::string::npos) {
      ADD_FAILURE() << "no time in the answer to ~pause: " << pause.response.message;
      return false;
    }
    at = std::stod(pause.response.message.substr(where + 7));
    return true;
  }

  std::string diagnostic(const std::string& name, const std::string& key) {
    const std::lock_guard<std::mutex> lock(mutex_);
    const auto status = diagnostics_values_.find(name);
    if (status == diagnostics_values_.end()) return "";
    const auto it = status->second.find(key);
    return it == status->second.end() ? "" : it->second;
  }
  long diagnosticCount(const std::string& name, const std::string& key) {
    const std::string v = diagnostic(name, key);
    return v.empty() ? -1 : std::stol(v);
  }

  /// Two lockstep runs from a reset (paused, stepped): each arm sent 0.4 rad on joint 1 and −0.3 on joint 4 in 1 s,
  /// stepped to t = 0.8 s (a reset less than a second after the timeline's start, which a controller must tell from a
  /// reordered state); both arms' positions must be equal bit for bit and the left arm must have moved.
  void expectRepeatableLockstepRuns() {
    std_srvs::SetBool paused;
    paused.request.data = true;
    ASSERT_TRUE(pause_.call(paused));
    std::vector<double> start;
    const auto run = [&]() {
      std_srvs::Trigger trigger;
      EXPECT_TRUE(reset_.call(trigger) && trigger.response.success);
      EXPECT_TRUE(waitWall([this] { return lastStamp() == 0.0; }, 5.0));
      bimanual_skills::SimStep steps;
      steps.request.steps = 1;  // the controllers restart on the first state of the new timeline
      EXPECT_TRUE(step_.call(steps) && steps.response.success) << steps.response.message;
      EXPECT_TRUE(waitWall([this] { return lastStamp() > 0.0; }, 5.0));
      start = armPositions("left");
      for (const std::string& arm : kArms) {
        std::vector<double> target = armPositions(arm);
        target[0] += 0.4;
        target[3] -= 0.3;
        // Stamped to start at 0.05 s of simulated time: the start does not depend on the step at which a
        // controller process, however loaded, took the message.
        trajectory_msgs::JointTrajectory t = trajectory(arm, {target}, 1.0);
        t.header.stamp = ros::Time(0.05);
        commands_[arm].publish(t);
      }
      waitWall([] { return false; }, 1.0);  // the controllers hold the trajectories until their start
      steps.request.steps = 799;
      EXPECT_TRUE(step_.call(steps) && steps.response.success) << steps.response.message;
      // The state where the steps ended (t = 0.8 s): the one before it may come first, and read then, a run would
      // end a step short of the other.
      EXPECT_TRUE(waitWall([&] { return lastStamp() > 0.8 - 1e-9; }, 5.0));
      std::vector<double> q = armPositions("left"), right = armPositions("right");
      q.insert(q.end(), right.begin(), right.end());
      return q;
    };
    const std::vector<double> first = run(), second = run();
    paused.request.data = false;
    ASSERT_TRUE(pause_.call(paused));
    ASSERT_EQ(first.size(), 14u);
    double moved = 0.0;
    for (int i = 0; i < 14; ++i) {
      EXPECT_EQ(first[i], second[i]) << "joint " << i;
      if (i < 7) moved = std::max(moved, std::abs(first[i] - start[i]));
    }
    EXPECT_GT(moved, 0.1) << "the arms did not move: the trajectories were not taken";
  }

  /// Simulated seconds per wall second over the next `seconds` of wall time, from /clock.
  double measuredRealtimeFactor(double seconds) {
    std::size_t first;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      first = clock_samples_.size();
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    const std::lock_guard<std::mutex> lock(mutex_);
    if (clock_samples_.size() < first + 10) return 0.0;
    const auto& a = clock_samples_[first];
    const auto& b = clock_samples_.back();
    return (b.second - a.second) / (b.first - a.first);
  }

  template <typename Service>
  bool call(ros::ServiceClient& client, Service& service) {
    return client.call(service);
  }

  ros::NodeHandle node_;
  ros::AsyncSpinner spinner_{2};
  ros::Subscriber states_, clock_, diagnostics_;
  std::map<std::string, ros::Subscriber> controller_states_, wrenches_;
  std::map<std::string, ros::Publisher> commands_;
  std::map<std::string, std::unique_ptr<Client>> clients_;
  ros::ServiceClient pause_, reset_, step_, payload_;
  std::mutex mutex_;
  std::map<std::string, double> positions_, max_error_;
  std::map<std::string, long> controller_state_count_;
  std::map<std::string, std::vector<std::pair<double, double>>> force_z_;  ///< (stamp [s], force z [N])
  std::map<std::string, std::map<std::string, std::string>> diagnostics_values_;
  std::vector<std::pair<double, double>> clock_samples_;  ///< (wall, simulated) seconds
  double last_stamp_ = -1.0;
  long joint_state_count_ = 0;
  bool recording_ = false;
};

// ------------------------------------------------------------------------------------------- sim_control.test

using HostedControl = SimFixture;

/// Resumes the simulation when a test that paused it ends, however it ends (a failed assertion included), after
/// cancelling the goals of `client` if given: the next test of the same simulator expects it running and still.
class Resume {
 public:
  explicit Resume(ros::ServiceClient& pause, Client* client = nullptr) : pause_(pause), client_(client) {}
  ~Resume() {
    if (client_ != nullptr) client_->cancelAllGoals();
    std_srvs::SetBool resume;
    resume.request.data = false;
    EXPECT_TRUE(pause_.call(resume) && resume.response.success) << resume.response.message;
  }
  Resume(const Resume&) = delete;
  Resume& operator=(const Resume&) = delete;

 private:
  ros::ServiceClient& pause_;
  Client* client_;
};

TEST_F(HostedControl, TracksTrajectoriesOnBothArms) {
  std::map<std::string, std::vector<double>> goal;
  for (const std::string& arm : kArms) {
    const std::vector<double> start = armPositions(arm);
    goal[arm] = start;
    std::vector<double> via = start;
    for (int i = 0; i < 7; ++i) via[i] += (i % 2 == 0 ? 0.3 : -0.2);
    goal[arm][0] += arm == "left" ? 0.2 : -0.2;
    goal[arm][3] -= 0.3;
    max_error_[arm] = 0.0;
    commands_[arm].publish(trajectory(arm, {via, goal[arm]}, 1.5));
  }
  recording_ = true;
  waitSim(3.5);
  recording_ = false;
  for (const std::string& arm : kArms) {
    const std::vector<double> q = armPositions(arm);
    for (int i = 0; i < 7; ++i) EXPECT_NEAR(q[i], goal[arm][i], 0.05) << arm << " joint " << i + 1;
    EXPECT_GT(max_error_[arm], 0.0) << arm << ": no controller state received";
    EXPECT_LT(max_error_[arm], 0.1) << arm;
    RecordProperty(arm + "_max_tracking_error_rad", std::to_string(max_error_[arm]));
    std::printf("%s: max tracking error %.4f rad\n", arm.c_str(), max_error_[arm]);
  }
}

TEST_F(HostedControl, TrajectoryActionAnswersWithControlMsgsCodes) {
  const std::vector<double> start = armPositions("left");
  std::vector<double> target = start;
  target[0] += 0.3;
  target[3] -= 0.2;
  Goal goal;
  goal.trajectory = trajectory("left", {target}, 1.0);
  // A good goal: succeeded, with feedback on the way.
  long feedback = 0;
  clients_["left"]->sendGoal(
      goal, Client::SimpleDoneCallback(), Client::SimpleActiveCallback(),
      [&feedback](const bimanual_skills::FollowJointTrajectoryFeedbackConstPtr&) { ++feedback; });
  ASSERT_TRUE(clients_["left"]->waitForResult(ros::Duration(60.0)));
  EXPECT_EQ(clients_["left"]->getState(), State::SUCCEEDED) << clients_["left"]->getState().getText();
  EXPECT_EQ(clients_["left"]->getResult()->error_code, Result::SUCCESSFUL);
  EXPECT_GT(feedback, 5);
  EXPECT_NEAR(armPositions("left")[0], target[0], 0.05);

  // Wrong joints: rejected with INVALID_JOINTS.
  Goal wrong = goal;
  wrong.trajectory.joint_names[2] = "right_wam_joint3";
  auto [state, result] = follow("left", wrong);
  EXPECT_EQ(state, State::REJECTED);
  EXPECT_EQ(result.error_code, Result::INVALID_JOINTS) << result.error_string;

  // NaN, and more points than the controller holds: INVALID_GOAL, before anything is allocated for the points.
  Goal nan = goal;
  nan.trajectory.points[0].positions[1] = std::nan("");
  std::tie(state, result) = follow("left", nan);
  EXPECT_EQ(result.error_code, Result::INVALID_GOAL) << result.error_string;
  Goal huge = goal;
  huge.trajectory = trajectory("left", std::vector<std::vector<double>>(2001, start), 0.01);
  std::tie(state, result) = follow("left", huge);
  EXPECT_EQ(result.error_code, Result::INVALID_GOAL);
  EXPECT_NE(result.error_string.find("capacity"), std::string::npos) << result.error_string;
  Goal outside = goal;
  outside.trajectory.points[0].positions[1] = 5.0;
  std::tie(state, result) = follow("left", outside);
  EXPECT_EQ(result.error_code, Result::INVALID_GOAL) << result.error_string;

  // Every point in the past: OLD_HEADER_TIMESTAMP.
  Goal old = goal;
  old.trajectory.header.stamp = ros::Time::now() - ros::Duration(5.0);
  std::tie(state, result) = follow("left", old);
  EXPECT_EQ(result.error_code, Result::OLD_HEADER_TIMESTAMP) << result.error_string;

  // A path tolerance no arm keeps: aborted with PATH_TOLERANCE_VIOLATED, the arm stops where it is.
  Goal tight;
  tight.trajectory = trajectory("left", {start}, 1.0);
  bimanual_skills::JointTolerance tolerance;
  tolerance.name = "left_wam_joint1";
  tolerance.position = 1e-4;
  tight.path_tolerance.push_back(tolerance);
  std::tie(state, result) = follow("left", tight);
  EXPECT_EQ(state, State::ABORTED);
  EXPECT_EQ(result.error_code, Result::PATH_TOLERANCE_VIOLATED) << result.error_string;
  const double stopped = armPositions("left")[0];
  waitSim(1.0);
  EXPECT_NEAR(armPositions("left")[0], stopped, 0.02) << "the arm went on after a path violation";
  EXPECT_GT(std::abs(stopped - start[0]), 0.05);

  // A goal tolerance not met within the goal time: GOAL_TOLERANCE_VIOLATED.
  Goal precise;
  precise.trajectory = trajectory("left", {start}, 1.0);
  tolerance.position = 1e-7;
  precise.goal_tolerance.push_back(tolerance);
  precise.goal_time_tolerance = ros::Duration(0.2);
  std::tie(state, result) = follow("left", precise);
  EXPECT_EQ(state, State::ABORTED);
  EXPECT_EQ(result.error_code, Result::GOAL_TOLERANCE_VIOLATED) << result.error_string;

  // A new goal preempts the running one; an empty trajectory stops the arm and succeeds.
  // The second client connects first: in wall time (waitForServer counts the simulator's clock, which runs many
  // times faster than the wall here at realtime_factor 0), and before the goal it preempts runs, which would
  // otherwise end before a loaded machine connects.
  Client other(node_, "/left/follow_joint_trajectory", false);
  ASSERT_TRUE(waitWall([&] { return other.isServerConnected(); }, 30.0));
  Goal slow;
  slow.trajectory = trajectory("left", {target}, 30.0);
  clients_["left"]->sendGoal(slow);
  waitSim(0.5);
  Goal stop;
  stop.trajectory.joint_names = jointNames("left");
  other.sendGoal(stop);
  ASSERT_TRUE(other.waitForResult(ros::Duration(30.0)));
  EXPECT_EQ(other.getState(), State::SUCCEEDED);
  ASSERT_TRUE(clients_["left"]->waitForResult(ros::Duration(30.0)));
  EXPECT_EQ(clients_["left"]->getState(), State::PREEMPTED);
}

// control_msgs' timing: a goal starts at its header.stamp. Both arms given the same future stamp begin in the same
// cycle of the loop (their results say when), no earlier than the stamp and within one cycle of it. The goals are
// sent while the simulation is paused, as the fold's are: the loop, standing still, has them and they are accepted;
// a paused simulation holds a running goal, it does not abort it.
TEST_F(HostedControl, ACommonFutureStartBeginsBothArmsInTheSameCycle) {
  double paused_at = 0.0;
  ASSERT_TRUE(pauseAt(paused_at));
  std_srvs::SetBool pause;
  std::map<std::string, Goal> goals;
  const ros::Time start(paused_at + 0.5);
  for (const std::string& arm : kArms) {
    std::vector<double> target = armPositions(arm);
    target[0] += arm == "left" ? 0.2 : -0.2;
    goals[arm].trajectory = trajectory(arm, {target}, 1.0);
    goals[arm].trajectory.header.stamp = start;
  }
  for (const std::string& arm : kArms) clients_[arm]->sendGoal(goals[arm]);
  EXPECT_TRUE(waitWall(
      [&] { return clients_["left"]->getState() == State::ACTIVE && clients_["right"]->getState() == State::ACTIVE; },
      10.0))
      << "the paused loop did not take the goals";
  pause.request.data = false;
  ASSERT_TRUE(pause_.call(pause) && pause.response.success) << pause.response.message;
  std::map<std::string, double> started;
  for (const std::string& arm : kArms) {
    ASSERT_TRUE(clients_[arm]->waitForResult(ros::Duration(60.0)));
    EXPECT_EQ(clients_[arm]->getState(), State::SUCCEEDED) << clients_[arm]->getState().getText();
    const std::string text = clients_[arm]->getResult()->error_string;
    const auto at = text.find("started at t = ");
    ASSERT_NE(at, std::string::npos) << text;
    started[arm] = std::stod(text.substr(at + 15));
    std::printf("%s: %s (stamp %.6f s)\n", arm.c_str(), text.c_str(), start.toSec());
  }
  EXPECT_EQ(started["left"], started["right"]);
  EXPECT_GE(started["left"], start.toSec() - 1e-9);
  EXPECT_LT(started["left"], start.toSec() + 0.001 + 1e-6);

  // Paused with a goal running: the goal waits with the clock (no abort), and succeeds after the resume.
  std::vector<double> back = armPositions("left");
  back[0] -= 0.2;
  Goal goal;
  goal.trajectory = trajectory("left", {back}, 5.0);  // long: this clock lags the simulator's
  clients_["left"]->sendGoal(goal);
  waitSim(0.3);
  pause.request.data = true;
  ASSERT_TRUE(pause_.call(pause) && pause.response.success) << pause.response.message;
  waitWall([] { return false; }, 1.5);
  EXPECT_EQ(clients_["left"]->getState(), State::ACTIVE) << clients_["left"]->getState().getText();
  pause.request.data = false;
  ASSERT_TRUE(pause_.call(pause) && pause.response.success) << pause.response.message;
  ASSERT_TRUE(clients_["left"]->waitForResult(ros::Duration(60.0)));
  EXPECT_EQ(clients_["left"]->getState(), State::SUCCEEDED) << clients_["left"]->getState().getText();
}

// The fold's release is a ClothGrasp with a stamp (control_msgs has no gripper action): the loop does it in the cycle
// of its stamp, not when the call is served, and says when on /diagnostics (ARM_gripper_scheduled_done_at). Both arms'
// releases are scheduled for one stamp while the simulation is paused, then it is stepped past it.
TEST_F(HostedControl, AStampedReleaseIsDoneInTheCycleOfItsStamp) {
  double paused_at = 0.0;
  ASSERT_TRUE(pauseAt(paused_at));
  const Resume resume(pause_);
  const double due = paused_at + 0.2504;
  ros::ServiceClient grasp = node_.serviceClient<bimanual_skills::ClothGrasp>("/bullet_sim/grasp", true);
  for (const std::string& arm : kArms) {
    bimanual_skills::ClothGrasp release;
    release.request.arm = arm;
    release.request.grasp = false;
    release.request.stamp = ros::Time(due);
    ASSERT_TRUE(grasp.call(release));
    EXPECT_TRUE(release.response.success) << release.response.message;
    EXPECT_NE(release.response.message.find("release scheduled at t = "), std::string::npos)
        << release.response.message;
  }
  bimanual_skills::SimStep steps;
  steps.request.steps = 500;
  ASSERT_TRUE(step_.call(steps) && steps.response.success) << steps.response.message;
  std::map<std::string, double> done;
  for (const std::string& arm : kArms) {
    const std::string key = arm + "_gripper_scheduled_done_at";
    ASSERT_TRUE(waitWall(
        [&] {
          const std::string value = diagnostic("bullet_sim", key);
          return !value.empty() && std::stod(value) > due - 0.01;
        },
        10.0))
        << key << ": '" << diagnostic("bullet_sim", key) << "'";
    const std::string value = diagnostic("bullet_sim", key);
    EXPECT_EQ(value.find("failed"), std::string::npos) << value;
    done[arm] = std::stod(value);
  }
  std::printf("releases stamped %.6f s done at %.6f s (left) and %.6f s (right)\n", due, done["left"], done["right"]);
  EXPECT_EQ(done["left"], done["right"]);
  EXPECT_GE(done["left"], due - 1e-6);  // written to the microsecond
  EXPECT_LT(done["left"], due + 0.001 + 1e-6);
}

// A cancelled goal ends PREEMPTED and the arm stops from where its reference was, smoothly (a quintic to rest: no
// step in the desired position or velocity), as joint_trajectory_controller's stop trajectory does. Stepped 10 ms at
// a time while paused, each step waited for on the state topic (published at 100 Hz of the states' time, so about
// one state per step: the differences are taken over the states' own stamps).
TEST_F(HostedControl, ACancelledGoalStopsTheArmSmoothly) {
  struct Desired {
    double stamp, position, velocity;  // of joint 1 [s, rad, rad/s]
  };
  std::mutex mutex;
  std::vector<Desired> desired;
  const ros::Subscriber state = node_.subscribe<bimanual_skills::JointTrajectoryControllerState>(
      "/left/state", 1000, [&](const bimanual_skills::JointTrajectoryControllerState::ConstPtr& m) {
        if (m->desired.velocities.empty() || m->desired.positions.empty()) return;
        const std::lock_guard<std::mutex> lock(mutex);
        desired.push_back({m->header.stamp.toSec(), m->desired.positions[0], m->desired.velocities[0]});
      });
  const auto newest = [&] {
    const std::lock_guard<std::mutex> lock(mutex);
    return desired.empty() ? -1.0 : desired.back().stamp;
  };
  ASSERT_TRUE(waitWall([&] { return newest() >= 0.0; }, 10.0)) << "no state of the left arm";
  double paused_at = 0.0;
  ASSERT_TRUE(pauseAt(paused_at));
  const Resume resume(pause_, clients_["left"].get());
  std::vector<double> target = armPositions("left");
  target[0] += 0.8;
  Goal goal;
  goal.trajectory = trajectory("left", {target}, 2.0);
  clients_["left"]->sendGoal(goal);
  ASSERT_TRUE(waitWall([&] { return clients_["left"]->getState() == State::ACTIVE; }, 10.0))
      << clients_["left"]->getState().toString();
  const auto stepTo = [&](int count) {  // `count` steps of 10 ms, each waited for on the state topic
    for (int k = 0; k < count; ++k) {
      bimanual_skills::SimStep steps;
      steps.request.steps = 10;
      if (!step_.call(steps) || !steps.response.success) {
        ADD_FAILURE() << "step: " << steps.response.message;
        return false;
      }
      // A state of these 10 ms (states 10 ms apart: which one depends on when the last one went out).
      if (!waitWall([&] { return newest() > steps.response.time - 0.010 + 1e-9; }, 10.0)) {
        ADD_FAILURE() << "no state of the 10 ms to " << steps.response.time << " s; the newest " << newest() << " s";
        return false;
      }
    }
    return true;
  };

  ASSERT_TRUE(stepTo(100));  // 1 s: mid-motion
  const std::size_t before = [&] {
    const std::lock_guard<std::mutex> lock(mutex);
    return desired.size();
  }();
  clients_["left"]->cancelGoal();
  EXPECT_TRUE(waitWall([&] { return clients_["left"]->getState() == State::PREEMPTED; }, 10.0))
      << clients_["left"]->getState().toString();
  ASSERT_TRUE(stepTo(150));
  const std::lock_guard<std::mutex> lock(mutex);
  ASSERT_GT(before, 2u);
  const double moving = desired[before - 1].velocity;
  double largest_acceleration = 0.0, largest_jump = 0.0;
  for (std::size_t k = before - 1; k + 1 < desired.size(); ++k) {
    const Desired &a = desired[k], &b = desired[k + 1];
    const double dt = b.stamp - a.stamp;
    ASSERT_GT(dt, 0.0) << "states out of order";
    largest_acceleration = std::max(largest_acceleration, std::abs(b.velocity - a.velocity) / dt);
    // The position against its velocity's integral over the interval (trapezoid): a jump shows, a smooth stop not.
    largest_jump = std::max(largest_jump, std::abs(b.position - a.position - 0.5 * (a.velocity + b.velocity) * dt));
  }
  std::printf(
      "cancelled at %.3f rad/s: the desired acceleration at most %.2f rad/s^2 on the way to rest, the position off "
      "its velocity's integral by at most %.1e rad; %.2e rad/s at the end\n",
      moving, largest_acceleration, largest_jump, desired.back().velocity);
  EXPECT_GT(std::abs(moving), 0.3) << "the arm was not moving when cancelled";
  EXPECT_LT(largest_acceleration, 10.0) << "a step in the desired velocity (stop_deceleration is 5 rad/s^2)";
  EXPECT_LT(largest_jump, 1e-3) << "a step in the desired position";
  EXPECT_LT(std::abs(desired.back().velocity), 1e-6);
}

TEST_F(HostedControl, EstimatesAPayloadWhileMoving) {
  waitSim(0.5);
  EXPECT_LT(std::abs(payloadError("1kHz")), 0.03);
}

TEST_F(HostedControl, ServicesRefuseAbsurdInputWithTheReason) {
  bimanual_skills::SetPayload set;
  set.request.arm = "left";
  for (const double mass : {1e12, -1.0, std::nan("")}) {
    set.request.mass = mass;
    ASSERT_TRUE(payload_.call(set));
    EXPECT_FALSE(set.response.success) << mass;
    EXPECT_NE(set.response.message.find("max_payload"), std::string::npos) << set.response.message;
  }
  set.request.arm = "middle";
  set.request.mass = 0.0;
  ASSERT_TRUE(payload_.call(set));
  EXPECT_FALSE(set.response.success);
  EXPECT_NE(set.response.message.find("unknown arm"), std::string::npos);

  ros::ServiceClient wrench = node_.serviceClient<bimanual_skills::ApplyWrench>("/bullet_sim/apply_wrench", true);
  bimanual_skills::ApplyWrench w;
  w.request.link = "left_wam_tool";
  w.request.wrench.force.x = 1e9;
  ASSERT_TRUE(wrench.call(w));
  EXPECT_FALSE(w.response.success);
  EXPECT_NE(w.response.message.find("max_force"), std::string::npos) << w.response.message;
  w.request.link = "nowhere";
  w.request.wrench.force.x = 1.0;
  ASSERT_TRUE(wrench.call(w));
  EXPECT_FALSE(w.response.success);

  // The tools start 0.25 m above the table: a grasp there catches no cloth node and says so.
  ros::ServiceClient grasp = node_.serviceClient<bimanual_skills::ClothGrasp>("/bullet_sim/grasp", true);
  bimanual_skills::ClothGrasp g;
  g.request.arm = "left";
  g.request.grasp = true;
  ASSERT_TRUE(grasp.call(g));
  EXPECT_FALSE(g.response.success);
  EXPECT_EQ(g.response.nodes, 0);
  EXPECT_NE(g.response.message.find("grasped nothing"), std::string::npos) << g.response.message;
  // A gripper command scheduled absurdly far ahead (a stamp in wall-clock seconds, say) is refused with the reason.
  g.request.stamp = ros::Time(1.7e9);
  ASSERT_TRUE(grasp.call(g));
  EXPECT_FALSE(g.response.success);
  EXPECT_NE(g.response.message.find("ahead of the simulation's clock; at most 600 s"), std::string::npos)
      << g.response.message;

  bimanual_skills::SimStep steps;
  steps.request.steps = 4000000000u;
  ASSERT_TRUE(step_.call(steps));
  EXPECT_FALSE(steps.response.success);
  EXPECT_NE(steps.response.message.find("max_step_duration"), std::string::npos) << steps.response.message;

  // A NaN trajectory on the command topic is rejected; the arm stays where it is.
  const std::vector<double> hold = armPositions("left");
  ASSERT_TRUE(
      waitWall([&] { return diagnosticCount("bullet_sim: left controller", "rejected_trajectories") >= 0; }, 15.0));
  const long rejected = diagnosticCount("bullet_sim: left controller", "rejected_trajectories");
  std::vector<double> bad = hold;
  bad[2] = std::nan("");
  commands_["left"].publish(trajectory("left", {bad}, 1.0));
  waitSim(0.5);
  for (int i = 0; i < 7; ++i) EXPECT_NEAR(armPositions("left")[i], hold[i], 0.01) << "joint " << i + 1;
  EXPECT_TRUE(waitWall(
      [&] { return diagnosticCount("bullet_sim: left controller", "rejected_trajectories") == rejected + 1; }, 15.0));
}

// sim_control.test raises ~max_force so that a wrench can make the arms diverge: a running goal is aborted with the
// reason, the states keep coming with their stamp frozen, /diagnostics says why, and ~reset brings the simulation
// back.
TEST_F(HostedControl, ADivergenceIsReportedAndResetRecovers) {
  // A goal running when the simulation diverges ends: aborted with the reason, not left active for good.
  std::vector<double> far = armPositions("left");
  far[0] += 0.3;
  Goal slow;
  slow.trajectory = trajectory("left", {far}, 30.0);
  clients_["left"]->sendGoal(slow);
  ASSERT_TRUE(waitWall([&] { return clients_["left"]->getState() == State::ACTIVE; }, 10.0));
  ros::ServiceClient wrench = node_.serviceClient<bimanual_skills::ApplyWrench>("/bullet_sim/apply_wrench", true);
  bimanual_skills::ApplyWrench w;
  w.request.link = "left_wam_tool";
  w.request.wrench.force.z = 5e6;
  ASSERT_TRUE(wrench.call(w));
  ASSERT_TRUE(w.response.success) << w.response.message;
  ASSERT_TRUE(waitWall([&] { return diagnostic("bullet_sim", "(level)") == "2"; }, 20.0))
      << "no divergence reported: " << diagnostic("bullet_sim", "(message)");
  EXPECT_NE(diagnostic("bullet_sim", "(message)").find("diverged"), std::string::npos);
  ASSERT_TRUE(clients_["left"]->waitForResult(ros::Duration(10.0))) << "the goal outlived the divergence";
  EXPECT_EQ(clients_["left"]->getState(), State::ABORTED);
  EXPECT_NE(clients_["left"]->getResult()->error_string.find("the control loop stopped: the simulation diverged"),
            std::string::npos)
      << clients_["left"]->getResult()->error_string;
  const long before = jointStateCount();
  const double frozen = lastStamp();
  waitWall([] { return false; }, 1.0);
  EXPECT_GE(jointStateCount(), before + 5) << "the joint states stopped after the divergence";
  EXPECT_EQ(lastStamp(), frozen);
  std_srvs::Trigger reset;
  ASSERT_TRUE(reset_.call(reset) && reset.response.success) << reset.response.message;
  EXPECT_TRUE(waitWall([&] { return lastStamp() > 0.5; }, 30.0)) << "the simulation did not run again";
  EXPECT_TRUE(waitWall([&] { return diagnostic("bullet_sim", "(level)") == "0"; }, 10.0));
}

TEST_F(HostedControl, LockstepRunsAreRepeatableBitForBit) {
  expectRepeatableLockstepRuns();
}

// ------------------------------------------------------------------------------ sim_external_lockstep.test

using ExternalLockstep = SimFixture;

TEST_F(ExternalLockstep, RunsWithExternalControllersAreRepeatableBitForBit) {
  ASSERT_TRUE(waitWall([&] { return diagnosticCount("bullet_sim", "lockstep_timeouts") >= 0; }, 30.0));
  const long timeouts = diagnosticCount("bullet_sim", "lockstep_timeouts");
  expectRepeatableLockstepRuns();
  waitWall([] { return false; }, 1.5);  // the next /diagnostics
  // Each step waited for the answer to its own state: none went on without one.
  EXPECT_EQ(diagnosticCount("bullet_sim", "lockstep_timeouts"), timeouts);
  EXPECT_EQ(diagnosticCount("bullet_sim", "rejected_external_commands"), 0);
}

// -------------------------------------------------------------------------------------------- sim_pacing.test

using Pacing = SimFixture;

TEST_F(Pacing, KeepsTheRealtimeFactorAfterPauseResetAndStep) {
  std_srvs::SetBool pause;
  std_srvs::Trigger reset;
  bimanual_skills::SimStep steps;
  const auto within = [this](const std::string& when) {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    const double factor = measuredRealtimeFactor(2.0);
    std::printf("real-time factor %s: %.4f\n", when.c_str(), factor);
    RecordProperty("realtime_factor_" + when, std::to_string(factor));
    EXPECT_NEAR(factor, 1.0, 0.1) << when;
  };
  within("at_start");
  pause.request.data = true;
  ASSERT_TRUE(pause_.call(pause) && pause.response.success);
  std::this_thread::sleep_for(std::chrono::seconds(2));
  pause.request.data = false;
  ASSERT_TRUE(pause_.call(pause) && pause.response.success);
  within("after_pause");
  ASSERT_TRUE(reset_.call(reset) && reset.response.success);
  within("after_reset");
  pause.request.data = true;
  ASSERT_TRUE(pause_.call(pause));
  steps.request.steps = 5000;  // 5 s of simulated time, as fast as the loop goes
  ASSERT_TRUE(step_.call(steps) && steps.response.success) << steps.response.message;
  pause.request.data = false;
  ASSERT_TRUE(pause_.call(pause));
  within("after_step");
}

TEST_F(Pacing, ServicesAnswerWhileALongStepRuns) {
  std_srvs::SetBool pause;
  pause.request.data = true;
  ASSERT_TRUE(pause_.call(pause));
  bimanual_skills::SimStep too_long;
  too_long.request.steps = 1000000;  // 1000 s
  ASSERT_TRUE(step_.call(too_long));
  EXPECT_FALSE(too_long.response.success);
  EXPECT_NE(too_long.response.message.find("max_step_duration allows 60 s"), std::string::npos)
      << too_long.response.message;
  // 60 s of simulated time, the most one call may ask for, takes several wall seconds: pause and reset answer
  // meanwhile, and the reset ends the step.
  auto stepping = std::async(std::launch::async, [this] {
    bimanual_skills::SimStep s;
    s.request.steps = 60000;
    ros::ServiceClient client = node_.serviceClient<bimanual_skills::SimStep>("/bullet_sim/step", true);
    EXPECT_TRUE(client.call(s));
    return s.response;
  });
  // Meanwhile the camera (30 images per simulated second) sends at most ~max_scene_rate (10 in sim_pacing.test) per
  // wall second, not one per 1/30 s of a clock faster than real time.
  double scene_rate = 0.0;
  ASSERT_TRUE(ros::param::get("/bullet_sim/max_scene_rate", scene_rate));
  std::atomic<int> images{0};
  ros::Subscriber camera = node_.subscribe<sensor_msgs::Image>(
      "/camera/image_raw", 100, [&images](const sensor_msgs::ImageConstPtr&) { ++images; });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const int images_before = images;
  const double simulated_before = lastStamp(), wall_before = bimanual_skills::realtime::monotonicSeconds();
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));
  const int sent = images - images_before;
  const double simulated = lastStamp() - simulated_before,
               wall = bimanual_skills::realtime::monotonicSeconds() - wall_before;
  std::printf("during the step: %.2f simulated s in %.2f wall s, %d camera images (%.0f at 30 per simulated s)\n",
              simulated, wall, sent, 30.0 * simulated);
  EXPECT_GT(sent, 0);
  EXPECT_LE(sent, 1.1 * scene_rate * wall + 2.0);
  EXPECT_GT(30.0 * simulated, 2.0 * (scene_rate * wall + 2.0)) << "the step ran too slowly to tell";
  // The images stop coming here before the answers are timed: on 2 cores, receiving them beside a
  // loop running flat out delays this process's own service calls, which is not what is measured.
  camera.shutdown();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  double start = bimanual_skills::realtime::monotonicSeconds();
  ASSERT_TRUE(pause_.call(pause) && pause.response.success);
  const double pause_answer = bimanual_skills::realtime::monotonicSeconds() - start;
  start = bimanual_skills::realtime::monotonicSeconds();
  std_srvs::Trigger reset;
  ASSERT_TRUE(reset_.call(reset) && reset.response.success);
  const double reset_answer = bimanual_skills::realtime::monotonicSeconds() - start;
  std::printf("during a 60 s step: ~pause answered in %.3f s, ~reset in %.3f s\n", pause_answer, reset_answer);
  EXPECT_LT(pause_answer, 1.0);
  EXPECT_LT(reset_answer, 1.0);
  ASSERT_EQ(stepping.wait_for(std::chrono::seconds(10)), std::future_status::ready);
  const auto response = stepping.get();
  EXPECT_FALSE(response.success);
  EXPECT_NE(response.message.find("interrupted"), std::string::npos) << response.message;
  pause.request.data = false;
  ASSERT_TRUE(pause_.call(pause));
}

// ------------------------------------------------------------------------------------------ sim_external.test

/// The left ctc_controller process reads /relay/joint_states, which this test feeds from /joint_states: dropping a
/// tenth of them (seeded), or adding a reordered copy, a duplicate, or letting a second publisher in.
class ExternalControllers : public SimFixture {
 protected:
  void SetUp() override {
    relay_ = node_.advertise<sensor_msgs::JointState>("/relay/joint_states", 100);
    relay_in_ =
        node_.subscribe("/joint_states", 100, &ExternalControllers::onRelay, this, ros::TransportHints().tcpNoDelay());
    SimFixture::SetUp();
    // Until the relay ran, the left arm had no controller (the simulator brakes it): start again from the initial
    // pose, which the controllers take as a new start.
    std_srvs::Trigger reset;
    ASSERT_TRUE(reset_.call(reset) && reset.response.success);
    waitSim(1.0);
  }

  void onRelay(const sensor_msgs::JointState::ConstPtr& m) {
    const std::lock_guard<std::mutex> lock(relay_mutex_);
    if (drop_ > 0.0 && lost_(rng_)) return;
    relay_.publish(m);
    if (reorder_ && previous_) {
      reorder_ = false;
      relay_.publish(previous_);  // an older state after a newer one
    }
    if (duplicate_) {
      duplicate_ = false;
      relay_.publish(m);
    }
    previous_ = m;
  }

  void dropFraction(double p) {
    const std::lock_guard<std::mutex> lock(relay_mutex_);
    drop_ = p;
    lost_ = std::bernoulli_distribution(p);
  }

  ros::Publisher relay_;
  ros::Subscriber relay_in_;
  std::mutex relay_mutex_;
  std::mt19937 rng_{5};
  std::bernoulli_distribution lost_{0.0};
  double drop_ = 0.0;
  bool reorder_ = false, duplicate_ = false;
  sensor_msgs::JointState::ConstPtr previous_;
};

TEST_F(ExternalControllers, DropsReorderedAndDuplicateStatesAndIgnoresASecondPublisher) {
  const std::string name = "ctc_controller left";
  ASSERT_TRUE(waitWall([&] { return diagnosticCount(name, "dropped_reordered_states") >= 0; }, 30.0));
  // The relay sends a reordered and a duplicate state, again every 0.2 s until the controller counts both: on a
  // loaded machine the controller's queue of 10 states can overflow, and the oldest (these among them) go first.
  double armed = 0.0;
  const auto counted = [&] {
    if (diagnosticCount(name, "dropped_reordered_states") >= 1 &&
        diagnosticCount(name, "dropped_duplicate_states") >= 1)
      return true;
    if (bimanual_skills::realtime::monotonicSeconds() - armed > 0.2) {
      armed = bimanual_skills::realtime::monotonicSeconds();
      const std::lock_guard<std::mutex> lock(relay_mutex_);
      reorder_ = duplicate_ = true;
    }
    return false;
  };
  EXPECT_TRUE(waitWall(counted, 20.0)) << "reordered " << diagnosticCount(name, "dropped_reordered_states")
                                       << ", duplicates " << diagnosticCount(name, "dropped_duplicate_states");
  EXPECT_EQ(diagnosticCount(name, "stale_states"), 0) << "a reordered state was taken";

  // A second node publishes the left arm at zero on the same topic: ignored; the arm follows its goal.
  const std::vector<double> start = armPositions("left");
  std::vector<double> target = start;
  target[0] += 0.3;
  ASSERT_EQ(std::system("rostopic pub -r 200 /relay/joint_states sensor_msgs/JointState "
                        "'{name: [left_wam_joint1, left_wam_joint2, left_wam_joint3, left_wam_joint4, left_wam_joint5, "
                        "left_wam_joint6, left_wam_joint7], position: [0, 0, 0, 0, 0, 0, 0], "
                        "velocity: [0, 0, 0, 0, 0, 0, 0]}' __name:=intruder > /dev/null 2>&1 &"),
            0);
  EXPECT_TRUE(waitWall([&] { return diagnosticCount(name, "ignored_other_publishers") > 0; }, 20.0));
  Goal goal;
  goal.trajectory = trajectory("left", {target}, 1.5);
  const auto [state, result] = follow("left", goal);
  EXPECT_EQ(state, State::SUCCEEDED) << result.error_string;
  EXPECT_NEAR(armPositions("left")[0], target[0], 0.05);
  std::system("rosnode kill /intruder > /dev/null 2>&1");
}

TEST_F(ExternalControllers, EstimatesAPayloadWithStatesLost) {
  dropFraction(0.1);
  waitSim(1.0);
  const long irregular_before = diagnosticCount("ctc_controller left", "observer_irregular_steps");
  EXPECT_LT(std::abs(payloadError("external_1kHz_10pct_lost", "ctc_controller left")), 0.03);
  EXPECT_GT(diagnosticCount("ctc_controller left", "observer_irregular_steps"), irregular_before + 100)
      << "the relay lost no states";
  dropFraction(0.0);
}

// ------------------------------------------------------------------------------------------ jtc_scenarios.test

/// The scenarios of ros_controllers' joint_trajectory_controller test suite (and a few it leaves out) against the
/// left arm's ctc_controller process, each printed as "scenario: ...: ours ..." for docs/NODES.md's table. The left
/// controller reads the relay, which the test can stop (the robot's loop stops while its clock goes on).
class JtcScenarios : public ExternalControllers {
 protected:
  void SetUp() override {
    ExternalControllers::SetUp();
    other_ = std::make_unique<Client>(node_, "/left/follow_joint_trajectory", false);
    ASSERT_TRUE(waitWall([&] { return other_->isServerConnected(); }, 30.0));
    start_ = armPositions("left");
    target_ = start_;
    target_[0] += 0.25;
    target_[3] -= 0.2;
  }
  void TearDown() override {
    clients_["left"]->cancelAllGoals();
    ExternalControllers::TearDown();
  }

  /// A goal of the left arm through `points` at `period` from a start stamped `stamp` (0: now).
  Goal goalThrough(const std::vector<std::vector<double>>& points, double period, ros::Time stamp = ros::Time()) {
    Goal goal;
    goal.trajectory = trajectory("left", points, period);
    goal.trajectory.header.stamp = stamp;
    return goal;
  }
  /// A goal's end as "STATE code 'message'", for the printed table.
  static std::string said(const State& state, const Result& result) {
    return state.toString() + " " + std::to_string(result.error_code) + " '" + result.error_string + "'";
  }
  void scenario(const std::string& name, const std::string& ours) {
    std::printf("scenario: %s: %s\n", name.c_str(), ours.c_str());
    RecordProperty(name, ours);
  }
  /// Whether the left arm's joint 1 stands still (moves less than 2 mrad over 0.3 s of simulated time).
  bool standsStill() {
    const double before = armPositions("left")[0];
    waitSim(0.3);
    return std::abs(armPositions("left")[0] - before) < 2e-3;
  }

  std::unique_ptr<Client> other_;
  std::vector<double> start_, target_;
};

TEST_F(JtcScenarios, StampsOldAndPartlyOldTrajectories) {
  waitSim(2.0);  // a clock with a past to stamp in (the reset set it back to 0)
  // Every point in the past: rejected (JTC: REJECTED INVALID_GOAL "Dropping all N trajectory point(s)").
  auto [state, result] = follow("left", goalThrough({target_}, 1.0, ros::Time::now() - ros::Duration(2.5)));
  EXPECT_EQ(state, State::REJECTED);
  EXPECT_EQ(result.error_code, Result::OLD_HEADER_TIMESTAMP) << result.error_string;
  scenario("whole trajectory in the past", said(state, result));
  // A single point at time_from_start 0, stamp 0: it is now, i.e. past (JTC: rejected, "Dropping all 1").
  Goal now = goalThrough({target_}, 1.0);
  now.trajectory.points[0].time_from_start = ros::Duration(0.0);
  std::tie(state, result) = follow("left", now);
  EXPECT_EQ(state, State::REJECTED);
  scenario("single point at t = 0, stamp 0", said(state, result));
  // Stamp 0, first point at -0.1 s (JTC's ignorePartiallyOldActionTraj): that point is dropped, the rest runs.
  Goal partly = goalThrough({start_, target_}, 1.0);
  partly.trajectory.points[0].time_from_start = ros::Duration(-0.1);
  std::tie(state, result) = follow("left", partly);
  EXPECT_EQ(state, State::SUCCEEDED) << result.error_string;
  EXPECT_NEAR(armPositions("left")[0], target_[0], 0.05);
  scenario("first point at t = -0.1 s, stamp 0", said(state, result));
  // Stamped 1.5 s ago with points at 1, 2, 3 s: the first is dropped, the others keep their times.
  const ros::Time earlier = ros::Time::now() - ros::Duration(1.5);
  std::tie(state, result) = follow("left", goalThrough({target_, start_, target_}, 1.0, earlier));
  EXPECT_EQ(state, State::SUCCEEDED) << result.error_string;
  const double ended = ros::Time::now().toSec() - earlier.toSec();
  EXPECT_GT(ended, 2.9) << "the points did not keep their times";
  EXPECT_LT(ended, 4.5);
  scenario("partly old (stamp 1.5 s ago, points at 1, 2, 3 s)", said(state, result));
  // Stamp 0, first point at t = 0 with others after it: the t = 0 point is now, dropped (as JTC).
  Goal zero = goalThrough({target_, start_}, 1.0);
  zero.trajectory.points[0].time_from_start = ros::Duration(0.0);
  std::tie(state, result) = follow("left", zero);
  EXPECT_EQ(state, State::SUCCEEDED) << result.error_string;
  scenario("first point at t = 0, stamp 0, more after", said(state, result));
}

TEST_F(JtcScenarios, FutureStampsPreemptAtOnceAndStartOnTime) {
  // A goal running, then one stamped 1 s ahead: the first is preempted when the second is accepted; the arm goes on
  // with the first motion until the stamp (JTC keeps the old trajectory until the stamp too).
  clients_["left"]->sendGoal(goalThrough({target_}, 4.0));
  waitSim(0.5);
  const ros::Time stamp = ros::Time::now() + ros::Duration(1.0);
  other_->sendGoal(goalThrough({start_}, 1.0, stamp));
  ASSERT_TRUE(clients_["left"]->waitForResult(ros::Duration(10.0)));
  EXPECT_EQ(clients_["left"]->getState(), State::PREEMPTED);
  EXPECT_LT(ros::Time::now().toSec(), stamp.toSec()) << "the old goal was preempted late";
  const double before = armPositions("left")[0];
  waitSim(0.4);
  EXPECT_GT(armPositions("left")[0], before + 1e-3) << "the old motion stopped before the new one's stamp";
  ASSERT_TRUE(other_->waitForResult(ros::Duration(20.0)));
  EXPECT_EQ(other_->getState(), State::SUCCEEDED) << other_->getState().getText();
  scenario("future stamp preempts the running goal", "old " + clients_["left"]->getState().toString() +
                                                         " at acceptance, old motion on until the stamp, new " +
                                                         other_->getState().toString());
  // A future stamp with the first point at t = 0 (where the arm is, as the fold's goals begin): JTC steps the
  // reference to it; ours drops it when the loop begins (the start's own point) and goes on to the next.
  Goal at_start = goalThrough({start_, target_}, 1.0, ros::Time::now() + ros::Duration(0.5));
  at_start.trajectory.points[0].time_from_start = ros::Duration(0.0);
  auto [state, result] = follow("left", at_start);
  EXPECT_EQ(state, State::SUCCEEDED) << result.error_string;
  EXPECT_NEAR(armPositions("left")[0], target_[0], 0.05);
  scenario("future stamp, first point at t = 0", said(state, result));
  // ... at t < 0 (stamp + t still ahead): refused, as JTC (its bridge cannot be built).
  Goal early = goalThrough({target_, start_}, 1.0, ros::Time::now() + ros::Duration(1.0));
  early.trajectory.points[0].time_from_start = ros::Duration(-0.5);
  std::tie(state, result) = follow("left", early);
  EXPECT_EQ(state, State::REJECTED);
  EXPECT_EQ(result.error_code, Result::INVALID_GOAL) << result.error_string;
  scenario("future stamp, first point at t = -0.5 s (stamp + t ahead)", said(state, result));
}

TEST_F(JtcScenarios, JointNamesOrderAndPointSizes) {
  // Reordered joints are mapped by name (JTC's jointReordering).
  Goal reordered = goalThrough({target_}, 1.0);
  std::reverse(reordered.trajectory.joint_names.begin(), reordered.trajectory.joint_names.end());
  std::reverse(reordered.trajectory.points[0].positions.begin(), reordered.trajectory.points[0].positions.end());
  auto [state, result] = follow("left", reordered);
  EXPECT_EQ(state, State::SUCCEEDED) << result.error_string;
  const std::vector<double> q = armPositions("left");
  for (int j = 0; j < 7; ++j) EXPECT_NEAR(q[j], target_[j], 0.05) << "joint " << j + 1;
  scenario("joints in another order", said(state, result));
  const auto refused = [&](const std::string& name, Goal goal, int code) {
    const auto [s, r] = follow("left", goal);
    EXPECT_EQ(s, State::REJECTED) << name;
    EXPECT_EQ(r.error_code, code) << name << ": " << r.error_string;
    scenario(name, said(s, r));
  };
  Goal unknown = goalThrough({target_}, 1.0);
  unknown.trajectory.joint_names[2] = "left_wam_joint9";
  refused("an unknown joint", unknown, Result::INVALID_JOINTS);
  Goal partial = goalThrough({target_}, 1.0);
  partial.trajectory.joint_names.pop_back();
  partial.trajectory.points[0].positions.pop_back();
  refused("6 of the 7 joints (no partial goals)", partial, Result::INVALID_JOINTS);
  Goal twice = goalThrough({target_}, 1.0);
  twice.trajectory.joint_names[1] = twice.trajectory.joint_names[0];
  refused("a joint named twice", twice, Result::INVALID_JOINTS);
  Goal nameless;
  refused("empty goal without joint names", nameless, Result::INVALID_JOINTS);
  Goal sizes = goalThrough({target_}, 1.0);
  sizes.trajectory.points[0].velocities.assign(3, 0.0);
  refused("velocities of another size than positions", sizes, Result::INVALID_GOAL);
  Goal short_point = goalThrough({target_}, 1.0);
  short_point.trajectory.points[0].positions.resize(5);
  refused("a point shorter than joint_names", short_point, Result::INVALID_GOAL);
  Goal no_positions = goalThrough({target_}, 1.0);
  no_positions.trajectory.points[0].positions.clear();
  refused("a point without positions", no_positions, Result::INVALID_GOAL);
  Goal equal = goalThrough({target_, start_}, 1.0);
  equal.trajectory.points[1].time_from_start = equal.trajectory.points[0].time_from_start;
  refused("times not strictly increasing", equal, Result::INVALID_GOAL);
}

TEST_F(JtcScenarios, PreemptionCancelAndEmptyTrajectories) {
  // A new goal preempts the running one (JTC's actionReplacesActionTraj).
  clients_["left"]->sendGoal(goalThrough({target_}, 3.0));
  waitSim(0.5);
  other_->sendGoal(goalThrough({start_}, 1.5));
  ASSERT_TRUE(clients_["left"]->waitForResult(ros::Duration(10.0)));
  EXPECT_EQ(clients_["left"]->getState(), State::PREEMPTED);
  ASSERT_TRUE(other_->waitForResult(ros::Duration(20.0)));
  EXPECT_EQ(other_->getState(), State::SUCCEEDED);
  scenario("a goal preempts the running goal",
           "old " + clients_["left"]->getState().toString() + ", new " + other_->getState().toString());
  // A topic command preempts a goal (topicReplacesActionTraj).
  clients_["left"]->sendGoal(goalThrough({target_}, 3.0));
  waitSim(0.5);
  commands_["left"].publish(trajectory("left", {start_}, 1.5));
  ASSERT_TRUE(clients_["left"]->waitForResult(ros::Duration(10.0)));
  EXPECT_EQ(clients_["left"]->getState(), State::PREEMPTED);
  waitSim(2.0);
  EXPECT_NEAR(armPositions("left")[0], start_[0], 0.05) << "the topic's trajectory did not run";
  scenario("a topic trajectory preempts a goal", "goal " + clients_["left"]->getState().toString());
  // An empty trajectory on the topic, without joint names (JTC's "stop here"): the goal ends and the arm stops.
  clients_["left"]->sendGoal(goalThrough({target_}, 3.0));
  waitSim(0.8);
  trajectory_msgs::JointTrajectory empty;
  commands_["left"].publish(empty);
  ASSERT_TRUE(clients_["left"]->waitForResult(ros::Duration(10.0)));
  EXPECT_EQ(clients_["left"]->getState(), State::PREEMPTED);
  waitSim(0.3);
  EXPECT_TRUE(standsStill()) << "the arm did not stop on an empty trajectory";
  EXPECT_GT(std::abs(armPositions("left")[0] - start_[0]), 0.02) << "the arm went back instead of stopping";
  scenario("empty trajectory on the topic while a goal runs",
           "goal " + clients_["left"]->getState().toString() + ", the arm stops smoothly and holds");
  // The same while a topic trajectory runs (emptyTopicCancelsTopicTraj).
  commands_["left"].publish(trajectory("left", {start_}, 3.0));
  waitSim(0.8);
  commands_["left"].publish(empty);
  waitSim(0.3);
  EXPECT_TRUE(standsStill()) << "the arm did not stop on an empty trajectory";
  scenario("empty trajectory on the topic while a topic trajectory runs", "the arm stops smoothly and holds");
  // An empty goal with the joint names: accepted, the arm holds, SUCCEEDED; the running goal PREEMPTED.
  clients_["left"]->sendGoal(goalThrough({target_}, 3.0));
  waitSim(0.5);
  Goal hold;
  hold.trajectory.joint_names = jointNames("left");
  const auto [state, result] = follow("left", hold);
  EXPECT_EQ(state, State::SUCCEEDED) << result.error_string;
  EXPECT_TRUE(standsStill());
  scenario("empty goal with the joint names", said(state, result));
  // Cancel: PREEMPTED, the arm ramps down and holds (JTC with stop_trajectory_duration > 0).
  clients_["left"]->sendGoal(goalThrough({target_}, 3.0));
  waitSim(0.8);
  clients_["left"]->cancelGoal();
  ASSERT_TRUE(clients_["left"]->waitForResult(ros::Duration(10.0)));
  EXPECT_EQ(clients_["left"]->getState(), State::PREEMPTED);
  waitSim(0.3);
  EXPECT_TRUE(standsStill()) << "the arm did not stop on a cancel";
  scenario("cancel", "goal " + clients_["left"]->getState().toString() + ", the arm stops smoothly and holds");
  // A topic command that is refused leaves the running goal alone.
  clients_["left"]->sendGoal(goalThrough({target_}, 2.0));
  waitSim(0.3);
  trajectory_msgs::JointTrajectory bad = trajectory("left", {start_}, 1.0);
  bad.joint_names[0] = "nobody";
  commands_["left"].publish(bad);
  ASSERT_TRUE(clients_["left"]->waitForResult(ros::Duration(20.0)));
  EXPECT_EQ(clients_["left"]->getState(), State::SUCCEEDED);
  scenario("a refused topic command while a goal runs", "goal " + clients_["left"]->getState().toString());
}

TEST_F(JtcScenarios, TolerancesAndResultCodes) {
  bimanual_skills::JointTolerance tight;
  tight.name = "left_wam_joint1";
  tight.position = 1e-4;
  // A path tolerance no arm keeps: ABORTED, PATH_TOLERANCE_VIOLATED.
  Goal path = goalThrough({target_}, 1.0);
  path.path_tolerance.push_back(tight);
  auto [state, result] = follow("left", path);
  EXPECT_EQ(state, State::ABORTED);
  EXPECT_EQ(result.error_code, Result::PATH_TOLERANCE_VIOLATED) << result.error_string;
  scenario("path tolerance violated", said(state, result));
  // The same with -1: unchecked.
  Goal unchecked = goalThrough({start_}, 1.0);
  bimanual_skills::JointTolerance off = tight;
  off.position = -1.0;
  unchecked.path_tolerance.push_back(off);
  std::tie(state, result) = follow("left", unchecked);
  EXPECT_EQ(state, State::SUCCEEDED) << result.error_string;
  scenario("path tolerance -1 (unchecked)", said(state, result));
  // A tolerance of 0 keeps the default (path 0: unchecked): succeeds.
  Goal defaults = goalThrough({target_}, 1.0);
  bimanual_skills::JointTolerance zero = tight;
  zero.position = 0.0;
  defaults.path_tolerance.push_back(zero);
  std::tie(state, result) = follow("left", defaults);
  EXPECT_EQ(state, State::SUCCEEDED) << result.error_string;
  scenario("path tolerance 0 (the default)", said(state, result));
  // A tolerance naming a joint of another controller: ignored (a goal for a whole group).
  Goal group = goalThrough({start_}, 1.0);
  bimanual_skills::JointTolerance theirs = tight;
  theirs.name = "right_wam_joint1";
  group.path_tolerance.push_back(theirs);
  std::tie(state, result) = follow("left", group);
  EXPECT_EQ(state, State::SUCCEEDED) << result.error_string;
  scenario("tolerance naming another controller's joint", said(state, result));
  // A goal tolerance not met within goal_time_tolerance: ABORTED, GOAL_TOLERANCE_VIOLATED.
  Goal goal = goalThrough({target_}, 1.0);
  bimanual_skills::JointTolerance precise = tight;
  precise.position = 1e-7;
  goal.goal_tolerance.push_back(precise);
  goal.goal_time_tolerance = ros::Duration(0.2);
  std::tie(state, result) = follow("left", goal);
  EXPECT_EQ(state, State::ABORTED);
  EXPECT_EQ(result.error_code, Result::GOAL_TOLERANCE_VIOLATED) << result.error_string;
  scenario("goal tolerance violated", said(state, result));
  // goal_time_tolerance -1: no time after the end (JTC's 0), so the same goal aborts at its end.
  goal.trajectory = goalThrough({start_}, 1.0).trajectory;
  goal.goal_time_tolerance = ros::Duration(-1.0);
  const ros::Time sent = ros::Time::now();
  std::tie(state, result) = follow("left", goal);
  EXPECT_EQ(state, State::ABORTED);
  EXPECT_EQ(result.error_code, Result::GOAL_TOLERANCE_VIOLATED) << result.error_string;
  EXPECT_LT(ros::Time::now().toSec() - sent.toSec(), 1.5) << "a goal_time_tolerance of -1 waited after the end";
  scenario("goal_time_tolerance -1", said(state, result));
  // NaN in a tolerance: refused (JTC keeps the default).
  Goal nan = goalThrough({start_}, 1.0);
  bimanual_skills::JointTolerance bad = tight;
  bad.position = std::nan("");
  nan.path_tolerance.push_back(bad);
  std::tie(state, result) = follow("left", nan);
  EXPECT_EQ(state, State::REJECTED);
  EXPECT_EQ(result.error_code, Result::INVALID_GOAL) << result.error_string;
  scenario("NaN tolerance", said(state, result));
}

TEST_F(JtcScenarios, GoalsWhenTheLoopStops) {
  // The left controller's states stop (the relay), the robot's clock goes on: the running goal is aborted within
  // loop_timeout, and a goal sent meanwhile is rejected at once (JTC: a controller not running rejects goals).
  clients_["left"]->sendGoal(goalThrough({target_}, 3.0));
  waitSim(0.5);
  dropFraction(1.0);
  ASSERT_TRUE(clients_["left"]->waitForResult(ros::Duration(10.0)));
  EXPECT_EQ(clients_["left"]->getState(), State::ABORTED);
  const Result aborted = *clients_["left"]->getResult();
  EXPECT_NE(aborted.error_string.find("the control loop stopped"), std::string::npos) << aborted.error_string;
  scenario("the loop stops during a goal", said(clients_["left"]->getState(), aborted));
  const auto [state, result] = follow("left", goalThrough({start_}, 1.0), 5.0);
  EXPECT_EQ(state, State::REJECTED);
  EXPECT_EQ(result.error_code, Result::INVALID_GOAL) << result.error_string;
  scenario("a goal after the loop stopped", said(state, result));
  // The states come again: once the controller has sent its own, it takes goals again.
  const auto states = [this] {
    const std::lock_guard<std::mutex> lock(mutex_);
    return controller_state_count_["left"];
  };
  const long before = states();
  dropFraction(0.0);
  ASSERT_TRUE(waitWall([&] { return states() > before + 5; }, 10.0)) << "the controller did not come back";
  const auto [again, answer] = follow("left", goalThrough({start_}, 1.0));
  EXPECT_EQ(again, State::SUCCEEDED) << answer.error_string;
  scenario("a goal after the loop came back", said(again, answer));
}

// -------------------------------------------------------------------------------------------- sim_500hz.test

using Rate500 = SimFixture;

TEST_F(Rate500, EstimatesAPayloadAt500Hz) {
  ASSERT_TRUE(waitWall([&] { return !diagnostic("bullet_sim: left controller", "control_period_s").empty(); }, 30.0));
  EXPECT_NEAR(std::stod(diagnostic("bullet_sim: left controller", "control_period_s")), 0.002, 1e-9);
  EXPECT_LT(std::abs(payloadError("500Hz")), 0.03);
}

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_sim_control");
  return RUN_ALL_TESTS();
}
