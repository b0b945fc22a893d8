// rostest (test/sim_control.test): bullet_sim and both ctc_controllers running headless. Commands a trajectory
// to each arm and checks the tracking; puts a payload on the left tool and checks the estimated force; sends NaN
// commands and stale joint states and checks the safe reactions.
#include "bimanual_skills/SetPayload.h"
#include "bimanual_skills/SimStep.h"

#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/WrenchStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <std_msgs/Float64MultiArray.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <functional>
#include <map>
#include <string>
#include <thread>
#include <vector>

namespace {

const std::vector<std::string> kArms = {"left", "right"};

std::vector<std::string> jointNames(const std::string& arm) {
  std::vector<std::string> names;
  for (int i = 1; i <= 7; ++i) names.push_back(arm + "_wam_joint" + std::to_string(i));
  return names;
}

class SimControl : public ::testing::Test {
 protected:
  void SetUp() override {
    states_ = node_.subscribe("/joint_states", 10, &SimControl::onState, this);
    for (const std::string& arm : kArms) {
      errors_[arm] = node_.subscribe<sensor_msgs::JointState>("/" + arm + "/tracking_error", 10,
                                                              [this, arm](const sensor_msgs::JointState::ConstPtr& m) {
                                                                double worst = 0.0;
                                                                for (double e : m->position)
                                                                  worst = std::max(worst, std::abs(e));
                                                                if (recording_)
                                                                  max_error_[arm] = std::max(max_error_[arm], worst);
                                                              });
      wrenches_[arm] = node_.subscribe<geometry_msgs::WrenchStamped>(
          "/" + arm + "/estimated_wrench", 10,
          [this, arm](const geometry_msgs::WrenchStamped::ConstPtr& m) { force_z_[arm].push_back(m->wrench.force.z); });
      commands_[arm] = node_.advertise<trajectory_msgs::JointTrajectory>("/" + arm + "/command", 1, true);
      efforts_[arm] = node_.advertise<std_msgs::Float64MultiArray>("/" + arm + "/effort_command", 1);
    }
    diagnostics_ = node_.subscribe("/diagnostics", 10, &SimControl::onDiagnostics, this);
    fake_states_ = node_.advertise<sensor_msgs::JointState>("/joint_states", 1);
    ASSERT_TRUE(waitWall([this] { return positions_.size() == 14 && force_z_["left"].size() > 5; }, 60.0))
        << "no joint states or estimates from the simulation";
  }

  void onState(const sensor_msgs::JointState::ConstPtr& m) {
    if (m->name.size() != 14) return;  // our own fake messages
    last_stamp_ = m->header.stamp.toSec();
    for (std::size_t i = 0; i < m->name.size(); ++i) positions_[m->name[i]] = m->position[i];
  }

  void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
    for (const auto& status : m->status) {
      for (const auto& kv : status.values) diagnostics_values_[status.hardware_id][kv.key] = kv.value;
    }
  }

  /// Spins until `done` or `seconds` of wall time.
  bool waitWall(const std::function<bool()>& done, double seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (ros::ok() && std::chrono::steady_clock::now() < end) {
      ros::spinOnce();
      if (done()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return false;
  }

  /// Spins for `seconds` of simulated time (at most 20× that in wall time).
  void waitSim(double seconds) {
    const ros::Time end = ros::Time::now() + ros::Duration(seconds);
    waitWall([&] { return ros::Time::now() >= end; }, 20.0 * seconds + 5.0);
  }

  std::vector<double> armPositions(const std::string& arm) {
    std::vector<double> q;
    for (const std::string& name : jointNames(arm)) q.push_back(positions_[name]);
    return q;
  }

  trajectory_msgs::JointTrajectory trajectory(const std::string& arm, const std::vector<std::vector<double>>& points,
                                              double period) {
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

  double meanForceZ(const std::string& arm, double seconds) {
    force_z_[arm].clear();
    waitSim(seconds);
    double sum = 0.0;
    for (double f : force_z_[arm]) sum += f;
    return force_z_[arm].empty() ? std::nan("") : sum / static_cast<double>(force_z_[arm].size());
  }

  long diagnostic(const std::string& arm, const std::string& key) {
    const auto it = diagnostics_values_[arm].find(key);
    return it == diagnostics_values_[arm].end() ? -1 : std::stol(it->second);
  }

  ros::NodeHandle node_;
  ros::Subscriber states_, diagnostics_;
  std::map<std::string, ros::Subscriber> errors_, wrenches_;
  std::map<std::string, ros::Publisher> commands_, efforts_;
  ros::Publisher fake_states_;
  std::map<std::string, double> positions_;
  std::map<std::string, double> max_error_;
  std::map<std::string, std::vector<double>> force_z_;
  std::map<std::string, std::map<std::string, std::string>> diagnostics_values_;
  double last_stamp_ = -1.0;  ///< Of the last joint states from the simulator [s].
  bool recording_ = false;
};

TEST_F(SimControl, TracksTrajectoriesOnBothArms) {
  std::map<std::string, std::vector<double>> start, goal;
  for (const std::string& arm : kArms) {
    start[arm] = armPositions(arm);
    goal[arm] = start[arm];
    std::vector<double> via = start[arm];
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
    EXPECT_GT(max_error_[arm], 0.0) << arm << ": no tracking error received";
    EXPECT_LT(max_error_[arm], 0.1) << arm;
    RecordProperty(arm + "_max_tracking_error_rad", std::to_string(max_error_[arm]));
    std::printf("%s: max tracking error %.4f rad\n", arm.c_str(), max_error_[arm]);
  }
}

TEST_F(SimControl, EstimatesAnUnknownPayload) {
  ros::ServiceClient payload = node_.serviceClient<bimanual_skills::SetPayload>("/bullet_sim/set_payload");
  ASSERT_TRUE(payload.waitForExistence(ros::Duration(10.0)));
  waitSim(0.5);
  const double before = meanForceZ("left", 1.0);
  bimanual_skills::SetPayload set;
  set.request.arm = "left";
  set.request.mass = 1.5;
  ASSERT_TRUE(payload.call(set));
  ASSERT_TRUE(set.response.success) << set.response.message;
  waitSim(2.0);
  const double after = meanForceZ("left", 1.0);
  const double weight = 1.5 * 9.81;
  std::printf("left: estimated vertical force %.3f N without, %.3f N with a 1.5 kg payload (weight %.3f N)\n", before,
              after, weight);
  EXPECT_NEAR(after - before, -weight, 0.1 * weight);
  set.request.mass = -1.0;
  ASSERT_TRUE(payload.call(set));
  EXPECT_FALSE(set.response.success);
  set.request.arm = "middle";
  set.request.mass = 0.0;
  ASSERT_TRUE(payload.call(set));
  EXPECT_FALSE(set.response.success);
  EXPECT_NE(set.response.message.find("unknown arm"), std::string::npos);
  set.request.arm = "left";
  ASSERT_TRUE(payload.call(set));
  EXPECT_TRUE(set.response.success);
}

TEST_F(SimControl, RejectsNanCommandsAndHoldsOnStaleStates) {
  const std::vector<double> hold = armPositions("left");
  // A NaN trajectory is rejected by the controller, a NaN torque by the simulator: the arm stays where it is.
  ASSERT_TRUE(waitWall([this] { return diagnostic("left", "rejected_trajectories") >= 0; }, 10.0));
  const long rejected = diagnostic("left", "rejected_trajectories");
  std::vector<double> bad = hold;
  bad[2] = std::nan("");
  commands_["left"].publish(trajectory("left", {bad}, 1.0));
  std_msgs::Float64MultiArray nan_torque;
  nan_torque.data.assign(7, std::nan(""));
  ASSERT_TRUE(waitWall([this] { return efforts_["left"].getNumSubscribers() >= 1; }, 10.0));
  for (int k = 0; k < 20; ++k) {
    efforts_["left"].publish(nan_torque);
    waitSim(0.01);
  }
  waitSim(0.5);
  for (int i = 0; i < 7; ++i) EXPECT_NEAR(armPositions("left")[i], hold[i], 0.01) << "joint " << i + 1;
  EXPECT_TRUE(waitWall([&] { return diagnostic("left", "rejected_trajectories") == rejected + 1; }, 15.0));

  // While a slow trajectory runs, a joint state 1 s old arrives: the controller sends no torque for it and, from
  // the next fresh state on, holds where the arm is instead of going on with the trajectory.
  std::vector<double> far = hold;
  far[0] += 0.5;
  commands_["left"].publish(trajectory("left", {far}, 4.0));
  waitSim(1.0);
  const long stale_before = diagnostic("left", "stale_states");
  sensor_msgs::JointState old;
  old.header.stamp = ros::Time::now() - ros::Duration(1.0);
  old.name = jointNames("left");
  old.position = armPositions("left");
  old.velocity.assign(7, 0.0);
  // robot_state_publisher, both controllers and this node subscribe; a new connection may still be settling, so the
  // old state goes out a few times.
  ASSERT_TRUE(waitWall([this] { return fake_states_.getNumSubscribers() >= 4; }, 10.0));
  for (int k = 0; k < 3; ++k) {
    fake_states_.publish(old);
    waitWall([] { return false; }, 0.02);
  }
  waitSim(0.2);
  const double q_at_stale = armPositions("left")[0];
  waitSim(3.5);
  const double q_end = armPositions("left")[0];
  EXPECT_LT(std::abs(q_end - q_at_stale), 0.05) << "the arm went on with the trajectory after stale states";
  EXPECT_GT(std::abs(q_end - far[0]), 0.1);
  EXPECT_TRUE(waitWall([&] { return diagnostic("left", "stale_states") > stale_before; }, 15.0));
  EXPECT_TRUE(waitWall([&] { return diagnostics_values_["left"]["mode"] == "hold"; }, 15.0));
}

TEST_F(SimControl, LockstepRunsAreRepeatableBitForBit) {
  ros::ServiceClient pause = node_.serviceClient<std_srvs::SetBool>("/bullet_sim/pause");
  ros::ServiceClient reset = node_.serviceClient<std_srvs::Trigger>("/bullet_sim/reset");
  ros::ServiceClient step = node_.serviceClient<bimanual_skills::SimStep>("/bullet_sim/step");
  ASSERT_TRUE(step.waitForExistence(ros::Duration(10.0)));
  std_srvs::SetBool paused;
  paused.request.data = true;
  ASSERT_TRUE(pause.call(paused));
  // Each run: reset (the controllers restart when time goes back), a trajectory per arm, 1500 steps.
  std::vector<double> start;
  const auto run = [&]() {
    std_srvs::Trigger trigger;
    last_stamp_ = -1.0;
    EXPECT_TRUE(reset.call(trigger) && trigger.response.success);
    EXPECT_TRUE(waitWall([this] { return last_stamp_ == 0.0; }, 5.0));
    bimanual_skills::SimStep steps;
    steps.request.steps = 1;  // the controllers restart on the first state of the new timeline
    EXPECT_TRUE(step.call(steps) && steps.response.success) << steps.response.message;
    start = armPositions("left");
    for (const std::string& arm : kArms) {
      std::vector<double> target = armPositions(arm);
      target[0] += 0.4;
      target[3] -= 0.3;
      commands_[arm].publish(trajectory(arm, {target}, 1.0));
    }
    waitWall([] { return false; }, 1.0);  // the paused controllers take the trajectories
    steps.request.steps = 1499;
    EXPECT_TRUE(step.call(steps) && steps.response.success) << steps.response.message;
    EXPECT_TRUE(waitWall([&] { return last_stamp_ > 1.499 - 1e-9; }, 5.0));
    std::vector<double> q = armPositions("left"), right = armPositions("right");
    q.insert(q.end(), right.begin(), right.end());
    return q;
  };
  const std::vector<double> first = run(), second = run();
  paused.request.data = false;
  ASSERT_TRUE(pause.call(paused));
  ASSERT_EQ(first.size(), 14u);
  double moved = 0.0;
  for (int i = 0; i < 14; ++i) {
    EXPECT_EQ(first[i], second[i]) << "joint " << i;
    if (i < 7) moved = std::max(moved, std::abs(first[i] - start[i]));
  }
  EXPECT_GT(moved, 0.1) << "the arms did not move: the trajectories were not taken";
}

}  // namespace

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_sim_control");
  return RUN_ALL_TESTS();
}
