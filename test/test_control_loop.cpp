// hosting::ControlLoop without ROS: a fake robot of two WAM arms integrated with the project's forward dynamics
// (known ground truth), hosted controllers and arms commanded from another thread, pause and step, a robot that
// stops, lockstep matched by stamps (repeatable bit for bit), bounded requests, bad input, the cycle's allocation
// count, states that cannot be read or are stale (the arm held against gravity), a driver that cannot be paused; and
// hosting::SimulatedRobot (the Bullet simulation as the loop's robot) doing scheduled gripper commands.
#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"
#include "bimanual_skills/hosting/control_loop.hpp"
#include "bimanual_skills/hosting/simulated_robot.hpp"
#include "test_support.hpp"
#include "testing/allocation_counter.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>

namespace bc = bimanual_skills::control;
namespace bd = bimanual_skills::dynamics;
namespace bh = bimanual_skills::hosting;
namespace bk = bimanual_skills::kinematics;
namespace sim = bimanual_skills::sim;

namespace {

constexpr double kDt = 0.001;

/// Two WAM arms (rotors, no friction) under their own forward dynamics; records the torques written per cycle.
class FakeRobot final : public bh::LoopRobot {
 public:
  explicit FakeRobot(double stop_at = 1e9) : stop_at_(stop_at) {
    for (int a = 0; a < 2; ++a) {
      q_[a] = (Eigen::VectorXd(7) << 0.0, 0.6, 0.0, 1.6, 0.0, 0.4, 0.0).finished();
      qd_[a] = qdd_[a] = tau_[a] = Eigen::VectorXd::Zero(7);
    }
    written_.reserve(100000);
  }
  int armCount() const noexcept override { return 2; }
  int jointCount(int arm) const noexcept override { return arm == 0 || arm == 1 ? 7 : 0; }
  /// Arm 0 faults (Fault, the state untouched) for steps in [fault_from, fault_to), and repeats its last sample
  /// (the stamp and values of step frozen_from − 1) for steps in [frozen_from, frozen_to): a driver's stale sample.
  sim::RobotStatus readJointState(int arm, sim::JointState& state) noexcept override {
    if (arm == 0 && steps_ >= fault_from && steps_ < fault_to) return sim::RobotStatus::Fault;
    if (arm == 0 && steps_ >= frozen_from && steps_ < frozen_to) return sim::RobotStatus::Ok;
    state.position = q_[arm];
    state.velocity = qd_[arm];
    state.effort = tau_[arm];
    state.time = time();
    if (arm == 0 && steps_ < positions_.cols()) positions_.col(steps_) = q_[0];
    return sim::RobotStatus::Ok;
  }
  sim::RobotStatus writeJointTorques(int arm, const Eigen::Ref<const Eigen::VectorXd>& torque) noexcept override {
    tau_[arm] = torque;
    if (arm == 1 && written_.size() < written_.capacity()) written_.push_back(torque[1]);
    if (arm == 0 && steps_ < torques_.cols()) torques_.col(steps_) = torque;
    return sim::RobotStatus::Ok;
  }
  double time() const noexcept override { return static_cast<double>(steps_) * kDt; }
  bool advance() noexcept override {
    for (int a = 0; a < 2; ++a) {
      (void)bd::forwardDynamics(model_, data_, q_[a], qd_[a], tau_[a], qdd_[a]);
      qd_[a] += kDt * qdd_[a];
      q_[a] += kDt * qd_[a];
    }
    ++steps_;
    return time() < stop_at_;
  }
  const char* stopReason() const noexcept override { return "the fake robot stopped"; }
  void reset() {
    steps_ = 0;
    stop_at_ = 1e9;
  }

  bk::ChainModel model_ = bimanual_skills::test_support::wamWithRotors();
  bd::DynamicsData data_{model_};
  Eigen::VectorXd q_[2], qd_[2], qdd_[2], tau_[2];
  std::vector<double> written_;                                 ///< Arm 1's second joint torque, per cycle.
  Eigen::MatrixXd positions_ = Eigen::MatrixXd::Zero(7, 1000);  ///< Arm 0's position read at each step.
  Eigen::MatrixXd torques_ = Eigen::MatrixXd::Zero(7, 1000);    ///< Arm 0's torque written at each step.
  long fault_from = -1, fault_to = -1, frozen_from = -1, frozen_to = -1;
  long steps_ = 0;
  double stop_at_;
};

/// Records the stamps handed out (preallocated: the cycle must not allocate); the newest one for other threads.
class RecordingSink final : public bh::StateSink {
 public:
  RecordingSink() { stamps_.reserve(100000); }
  void states(double t, const std::vector<sim::JointState>&, bool forced) noexcept override {
    if (stamps_.size() < stamps_.capacity()) stamps_.push_back({t, forced});
    latest_.store(t, std::memory_order_release);
    handed_.fetch_add(1, std::memory_order_release);
  }
  std::vector<std::pair<double, bool>> stamps_;
  std::atomic<double> latest_{-1.0};
  std::atomic<long> handed_{0};
};

using CountingProbe = bimanual_skills::realtime::ScopedCounterProbe<bimanual_skills::testing::AllocationCounter>;

bc::ArmControllerConfig controllerConfig() {
  return bimanual_skills::test_support::loopControllerConfig();
}
bd::FrictionModel noFriction() {
  return bimanual_skills::test_support::noFriction();
}

/// The loop on a thread of its own, stopped and joined on destruction.
struct Running {
  explicit Running(bh::ControlLoop& loop) : thread([this, &loop] { loop.run([this] { return !quit.load(); }); }) {}
  ~Running() {
    quit = true;
    thread.join();
  }
  std::atomic<bool> quit{false};
  std::thread thread;
};

/// Waits (bounded, 20 s) until `done`.
template <typename F>
bool waitFor(F done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

bh::LoopSettings fast() {
  bh::LoopSettings s;
  s.period = kDt;
  s.realtime_factor = 0.0;
  return s;
}

}  // namespace

TEST(ControlLoop, HostedControllersTrackATrajectoryAndTheCycleNeverAllocates) {
  FakeRobot robot;
  RecordingSink sink;
  CountingProbe probe;
  bh::ControlLoop loop(robot, sink, fast(), &probe);
  bc::RealtimeArmController left(robot.model_, noFriction(), controllerConfig());
  bc::RealtimeArmController right(robot.model_, noFriction(), controllerConfig());
  loop.host(0, left, [](const std::string&) {});
  loop.host(1, right, [](const std::string&) {});
  Running running(loop);
  bc::ControllerCommand command;
  command.kind = bc::ControllerCommand::Kind::Trajectory;
  command.waypoints.times = Eigen::VectorXd::Constant(1, 1.0);
  Eigen::VectorXd target = robot.q_[0];
  target[0] += 0.3;
  command.waypoints.positions = target;
  command.tolerances = bc::TrajectoryTolerances::none(7);
  command.goal_id = 1;
  ASSERT_TRUE(waitFor([&] { return loop.time() > 0.05; }));  // the controller starts on its first states
  left.command(command);
  const double sent = loop.time();
  ASSERT_TRUE(waitFor([&] { return loop.time() >= sent + 2.0; }));
  const bh::LoopCounts counts = loop.counts();
  EXPECT_GE(counts.cycles, 2000);
  EXPECT_EQ(counts.control_allocations, 0) << "the cycle (read, hand out, control, write) allocated";
  EXPECT_EQ(counts.control_cycles_that_allocated, 0);
  // Read on the loop thread, between cycles.
  const bh::LoopOutcome where = loop.call([&] {
    const double q0 = loop.states()[0].position[0];
    return bh::LoopOutcome{std::abs(q0 - target[0]) < 0.01, "q0 = " + std::to_string(q0), loop.time()};
  });
  EXPECT_TRUE(where.success) << "the left arm did not reach its target: " << where.message;
  const bc::ArmControllerState* state = left.latestState();
  ASSERT_NE(state, nullptr);
  EXPECT_EQ(state->status, bc::ControllerStatus::Ok) << bc::toString(state->status);
  EXPECT_EQ(state->goal, bc::GoalState::Succeeded)
      << bc::toString(state->goal) << " " << bc::toString(state->abort_reason);
  EXPECT_EQ(left.commandsTaken(), 1u);
}

TEST(ControlLoop, APausedLoopReceivesGoalsAndStepsExactlyWithoutRepeatingAStamp) {
  FakeRobot robot;
  RecordingSink sink;
  bh::LoopSettings settings = fast();
  settings.paused = true;
  bh::ControlLoop loop(robot, sink, settings);
  bc::RealtimeArmController left(robot.model_, noFriction(), controllerConfig());
  loop.host(0, left, [](const std::string&) {});
  Running running(loop);
  bc::ControllerCommand command;
  command.kind = bc::ControllerCommand::Kind::Trajectory;
  command.waypoints.times = Eigen::VectorXd::Constant(1, 1.0);
  command.waypoints.positions = robot.q_[0];
  command.tolerances = bc::TrajectoryTolerances::none(7);
  command.goal_id = 7;
  left.command(command);
  ASSERT_TRUE(waitFor([&] { return left.receivedGoal() == 7u; })) << "a paused loop did not receive the goal";
  EXPECT_EQ(loop.time(), 0.0);
  const bh::LoopOutcome stepped = loop.step(100);
  EXPECT_TRUE(stepped.success) << stepped.message;
  EXPECT_EQ(stepped.message, "stepped 100 of 100");
  EXPECT_NEAR(stepped.time, 0.1, 1e-12);
  EXPECT_EQ(robot.steps_, 100);
  const bh::LoopOutcome paused = loop.pause(true);
  EXPECT_EQ(paused.message, "paused at t = 0.100000 s");
  const bh::LoopOutcome resumed = loop.pause(false);
  EXPECT_TRUE(resumed.success);
  const bh::LoopOutcome refused = loop.step(10);
  EXPECT_FALSE(refused.success);
  EXPECT_NE(refused.message.find("pause it first"), std::string::npos) << refused.message;
  ASSERT_TRUE(loop.pause(true).success);
  const auto handed = [&] { return loop.call([] { return bh::LoopOutcome{true, "", 0.0}; }); };
  ASSERT_TRUE(handed().success);
  // Stamps: the first hand-out (forced) at 0, then every cycle once; the end of the step forced at 0.1.
  ASSERT_GE(sink.stamps_.size(), 101u);
  EXPECT_EQ(sink.stamps_[0], std::make_pair(0.0, true));
  for (std::size_t k = 1; k < sink.stamps_.size(); ++k) {
    if (sink.stamps_[k].second) continue;
    EXPECT_GT(sink.stamps_[k].first, sink.stamps_[k - 1].first) << "stamp " << sink.stamps_[k].first << " repeated";
  }
  EXPECT_NEAR(sink.stamps_[99].first, 0.099, 1e-12);
  EXPECT_FALSE(sink.stamps_[99].second);
  EXPECT_TRUE(sink.stamps_[100].second);
  EXPECT_NEAR(sink.stamps_[100].first, 0.1, 1e-12);
}

TEST(ControlLoop, AStepIsPacedWhenAnArmIsCommandedFromOutsideWithoutLockstep) {
  // A controller in another process follows the states at the pace it was given: a step that ran as fast as it goes
  // would leave it whole steps behind. The wall time of a paced step is at least its simulated time (a lower bound
  // the pacer guarantees, not a speed measurement).
  FakeRobot robot;
  RecordingSink sink;
  bh::LoopSettings settings;
  settings.period = kDt;
  settings.realtime_factor = 1.0;
  settings.paused = true;
  bh::ControlLoop loop(robot, sink, settings);
  loop.commandFromOutside(1, 0.05, Eigen::VectorXd::Constant(7, 1.0), false);
  Running running(loop);
  const auto start = std::chrono::steady_clock::now();
  const bh::LoopOutcome stepped = loop.step(200);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_TRUE(stepped.success) << stepped.message;
  EXPECT_NEAR(stepped.time, 0.2, 1e-12);
  EXPECT_GE(wall, 0.19) << "the step ran ahead of the real-time factor";
}

TEST(ControlLoop, ARobotThatStopsAbortsTheHostedGoalsOnceAndARestartClearsIt) {
  FakeRobot robot(0.05);
  RecordingSink sink;
  bh::ControlLoop loop(robot, sink, fast());
  bc::RealtimeArmController left(robot.model_, noFriction(), controllerConfig());
  std::atomic<int> told{0};
  std::string why;
  loop.host(0, left, [&](const std::string& reason) {
    why = reason;
    told.fetch_add(1);
  });
  Running running(loop);
  ASSERT_TRUE(waitFor([&] { return loop.stopped(); }));
  ASSERT_TRUE(waitFor([&] { return told.load() > 0; }));
  EXPECT_NEAR(loop.stopTime(), 0.05, 1e-9);
  std::this_thread::sleep_for(std::chrono::milliseconds(250));
  EXPECT_EQ(told.load(), 1) << "told more than once";
  EXPECT_EQ(why, "the fake robot stopped");
  EXPECT_NEAR(sink.latest_.load(), 0.05, 1e-9) << "a stopped robot's states go on with the stamp frozen";
  EXPECT_FALSE(loop.step(1).success);
  const bh::LoopOutcome restarted = loop.call([&] {
    robot.reset();
    loop.restart("reset");
    return bh::LoopOutcome{true, "restarted", robot.time()};
  });
  EXPECT_TRUE(restarted.success);
  EXPECT_FALSE(loop.stopped());
  ASSERT_TRUE(waitFor([&] { return loop.time() > 0.1; })) << "the loop did not go on after the restart";
}

namespace {

/// Runs 300 lockstep cycles with arm 1 commanded from another thread that answers each state with a torque
/// computed from its stamp (and, with `late`, also sends a command answering the previous state); returns the torques
/// the robot got.
std::vector<double> lockstepRun(bool late, bh::LoopCounts& counts) {
  FakeRobot robot;
  RecordingSink sink;
  bh::LoopSettings settings = fast();
  settings.lockstep = true;
  settings.lockstep_timeout = 5.0;
  bh::ControlLoop loop(robot, sink, settings);
  loop.commandFromOutside(1, 0.05, Eigen::VectorXd::Constant(7, 10.0), true);
  std::atomic<bool> quit{false};
  std::thread commander([&] {
    long answered = 0;
    double previous = -1.0;
    while (!quit) {
      if (sink.handed_.load(std::memory_order_acquire) == answered) {
        std::this_thread::yield();
        continue;
      }
      answered = sink.handed_.load(std::memory_order_acquire);
      const double t = sink.latest_.load(std::memory_order_acquire);
      Eigen::VectorXd torque = Eigen::VectorXd::Zero(7);
      torque[1] = 1.0 + t;
      if (late && previous >= 0.0) {
        Eigen::VectorXd wrong = Eigen::VectorXd::Constant(7, 99.0);
        loop.torqueCommand(1, previous, wrong.data(), 7);
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));  // a slow answer: lockstep waits
      loop.torqueCommand(1, t, torque.data(), 7);
      previous = t;
    }
  });
  {
    Running running(loop);
    waitFor([&] { return robot.steps_ >= 300; });
    loop.pause(true);
  }
  quit = true;
  commander.join();
  counts = loop.counts();
  return {robot.written_.begin(), robot.written_.begin() + 300};
}

}  // namespace

TEST(ControlLoop, LockstepAppliesEachCommandToTheStateItAnswersBitForBit) {
  bh::LoopCounts first_counts, second_counts;
  const std::vector<double> first = lockstepRun(false, first_counts);
  const std::vector<double> second = lockstepRun(true, second_counts);
  ASSERT_EQ(first.size(), 300u);
  for (std::size_t k = 0; k < first.size(); ++k) {
    ASSERT_EQ(first[k], 1.0 + static_cast<double>(k) * kDt) << "cycle " << k << " applied another state's command";
  }
  EXPECT_EQ(first, second) << "a late command changed the run";
  EXPECT_EQ(first_counts.lockstep_timeouts, 0);
  EXPECT_EQ(first_counts.late_commands, 0);
  EXPECT_GT(second_counts.late_commands, 100);
  EXPECT_EQ(second_counts.lockstep_timeouts, 0);
}

TEST(ControlLoop, LockstepWithoutAnAnswerBrakesAfterItsTimeout) {
  FakeRobot robot;
  robot.qd_[1][1] = 0.5;
  RecordingSink sink;
  bh::LoopSettings settings = fast();
  settings.lockstep = true;
  settings.lockstep_timeout = 0.01;
  settings.paused = true;
  bh::ControlLoop loop(robot, sink, settings);
  loop.commandFromOutside(1, 0.05, Eigen::VectorXd::Constant(7, 10.0), true);
  Running running(loop);
  const bh::LoopOutcome stepped = loop.step(5);
  EXPECT_TRUE(stepped.success) << stepped.message;
  EXPECT_EQ(loop.counts().lockstep_timeouts, 5);
  ASSERT_EQ(robot.written_.size(), 5u);
  EXPECT_NEAR(robot.written_[0], -10.0 * 0.5, 1e-12) << "no command: braking, tau = -D qd";
}

TEST(ControlLoop, ACommandsJointImpedanceIsClosedByTheRobotUntilTheNextCommand) {
  // One command with an impedance about the arm's posture, then none: each later cycle's torque on joint 2 is the
  // effort plus K (q_d + q̇_d t − q) + D (q̇_d − q̇) of that cycle's state, until the command is stale (50 ms). Bad
  // impedances (a negative gain) are rejected and counted; a stamped command's setpoint moves on from its stamp.
  FakeRobot robot;
  RecordingSink sink;
  bh::LoopSettings settings = fast();
  settings.paused = true;
  bh::ControlLoop loop(robot, sink, settings);
  loop.commandFromOutside(1, 0.05, Eigen::VectorXd::Constant(7, 10.0), false);
  const Eigen::VectorXd effort = Eigen::VectorXd::Constant(7, 1.0), q_d = robot.q_[1],
                        qd_d = Eigen::VectorXd::Constant(7, 0.1), k = Eigen::VectorXd::Constant(7, 50.0),
                        d = Eigen::VectorXd::Constant(7, 2.0);
  const bh::CommandImpedance impedance{q_d.data(), qd_d.data(), k.data(), d.data()};
  loop.torqueCommand(1, std::nan(""), effort.data(), 7, &impedance);
  Running running(loop);
  ASSERT_TRUE(loop.step(1).success);  // takes the command at t = 0 (the state: q_d, at rest)
  ASSERT_EQ(robot.written_.size(), 1u);
  EXPECT_NEAR(robot.written_[0], 1.0 + 2.0 * 0.1, 1e-12) << "at the setpoint, moving 0.1 rad/s short of it";
  for (int cycle = 1; cycle <= 10; ++cycle) {
    const double t = robot.time();
    const double q = robot.q_[1][1], qd = robot.qd_[1][1];
    ASSERT_TRUE(loop.step(1).success);
    EXPECT_NEAR(robot.written_.back(), 1.0 + 50.0 * (q_d[1] + 0.1 * t - q) + 2.0 * (0.1 - qd), 1e-9)
        << "cycle " << cycle;
  }
  const Eigen::VectorXd negative = Eigen::VectorXd::Constant(7, -1.0);
  const bh::CommandImpedance bad{q_d.data(), qd_d.data(), negative.data(), d.data()};
  loop.torqueCommand(1, std::nan(""), effort.data(), 7, &bad);
  ASSERT_TRUE(loop.step(1).success);
  EXPECT_EQ(loop.counts().rejected_commands, 1);
  // A command stamped with the state it answers, 10 ms before the cycle that takes it: the setpoint is that state's
  // and has moved on from its stamp (not from the cycle's time).
  const double answered = robot.time() - 0.01;
  loop.torqueCommand(1, answered, effort.data(), 7, &impedance);
  for (int cycle = 0; cycle < 3; ++cycle) {
    const double t = robot.time();
    const double q = robot.q_[1][1], qd = robot.qd_[1][1];
    ASSERT_TRUE(loop.step(1).success);
    EXPECT_NEAR(robot.written_.back(), 1.0 + 50.0 * (q_d[1] + 0.1 * (t - answered) - q) + 2.0 * (0.1 - qd), 1e-9)
        << "cycle " << cycle;
  }
}

TEST(ControlLoop, BadInputGetsAClearAnswer) {
  FakeRobot robot;
  RecordingSink sink;
  bh::LoopSettings bad = fast();
  bad.period = std::nan("");
  EXPECT_THROW(bh::ControlLoop(robot, sink, bad), std::invalid_argument);
  bad = fast();
  bad.lockstep_timeout = 0.0;
  EXPECT_THROW(bh::ControlLoop(robot, sink, bad), std::invalid_argument);
  bh::ControlLoop loop(robot, sink, fast());
  bc::RealtimeArmController controller(robot.model_, noFriction(), controllerConfig());
  EXPECT_THROW(loop.host(2, controller, nullptr), std::invalid_argument);
  EXPECT_THROW(loop.commandFromOutside(0, 0.05, Eigen::VectorXd::Constant(3, 1.0), false), std::invalid_argument);
  loop.commandFromOutside(1, 0.05, Eigen::VectorXd::Constant(7, 10.0), false);
  EXPECT_THROW(loop.host(1, controller, nullptr), std::invalid_argument);
  // A request the loop never takes (it does not run) ends within its wait.
  const auto start = std::chrono::steady_clock::now();
  const bh::LoopOutcome untaken = loop.call([] { return bh::LoopOutcome{true, "", 0.0}; }, 0.1);
  EXPECT_FALSE(untaken.success);
  EXPECT_NE(untaken.message.find("did not take the request within 0.100000 s"), std::string::npos) << untaken.message;
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 5.0);
  // Wrong sizes and NaN are rejected by the loop; the arm brakes meanwhile.
  const double three[3] = {1.0, 2.0, 3.0};
  loop.torqueCommand(1, std::nan(""), three, 3);
  Eigen::VectorXd nan = Eigen::VectorXd::Constant(7, std::nan(""));
  Running running(loop);
  ASSERT_TRUE(waitFor([&] { return loop.counts().rejected_commands == 1; }));
  loop.torqueCommand(1, std::nan(""), nan.data(), 7);
  ASSERT_TRUE(waitFor([&] { return loop.counts().rejected_commands == 2; }));
  loop.torqueCommand(7, 0.0, three, 3);  // no such arm: ignored
  EXPECT_EQ(loop.counts().rejected_commands, 2);
}

TEST(ControlLoop, AnArmWhoseStatesCannotBeReadOrAreStaleIsHeldAgainstGravityNotLetFall) {
  // A driver's read fails for 50 cycles, then it repeats one old sample for 100: the hosted controller never gets
  // them (or refuses them once older than its state_timeout, 0.05 s), and the arm gets the gravity torque of its last
  // valid posture (computed here independently from the model), counted, instead of zero torque.
  FakeRobot robot;
  RecordingSink sink;
  bh::LoopSettings settings = fast();
  settings.paused = true;
  CountingProbe probe;
  bh::ControlLoop loop(robot, sink, settings, &probe);
  bc::RealtimeArmController left(robot.model_, noFriction(), controllerConfig());
  loop.host(0, left, [](const std::string&) {});
  Running running(loop);
  ASSERT_TRUE(loop.step(100).success);
  EXPECT_EQ(loop.counts().faulted_states, 0);
  EXPECT_EQ(loop.counts().unusable_states, 0);
  robot.fault_from = 100;
  robot.fault_to = 150;
  robot.frozen_from = 200;
  robot.frozen_to = 300;
  ASSERT_TRUE(loop.step(250).success);
  const bh::LoopCounts counts = loop.counts();
  EXPECT_EQ(counts.faulted_states, 50);
  EXPECT_EQ(counts.control_allocations, 0) << "holding the arm allocated";
  bd::DynamicsData data(robot.model_);
  Eigen::VectorXd gravity(7);
  ASSERT_EQ(bd::gravityTorques(robot.model_, data, robot.positions_.col(99), gravity), bd::DynamicsStatus::Success);
  ASSERT_GT(gravity.norm(), 1.0);
  for (long k = 100; k < 150; ++k) {
    EXPECT_LT((robot.torques_.col(k) - gravity).norm(), 1e-9) << "cycle " << k << " while the read failed";
  }
  EXPECT_LT((robot.positions_.col(150) - robot.positions_.col(99)).cwiseAbs().maxCoeff(), 2e-3)
      << "the arm moved while its states could not be read";
  // The repeated sample (stamped 0.199 s): used while younger than the timeout, then refused as stale from about
  // t = 0.25 s on.
  EXPECT_GE(counts.unusable_states, 49);
  EXPECT_LE(counts.unusable_states, 51);
  ASSERT_EQ(bd::gravityTorques(robot.model_, data, robot.positions_.col(199), gravity), bd::DynamicsStatus::Success);
  for (long k = 252; k < 300; ++k) {
    EXPECT_LT((robot.torques_.col(k) - gravity).norm(), 1e-9) << "cycle " << k << " on a stale state";
  }
  EXPECT_LT((robot.positions_.col(300) - robot.positions_.col(199)).cwiseAbs().maxCoeff(), 5e-3);
  // Fresh states again: the controller holds where the arm is and goes on.
  const bc::ArmControllerState* state = left.latestState();
  ASSERT_NE(state, nullptr);
  EXPECT_EQ(state->status, bc::ControllerStatus::Ok) << bc::toString(state->status);
}

TEST(ControlLoop, ADriverThatCannotBePausedRefusesPauseAndStepAndRunsOn) {
  FakeRobot robot;
  RecordingSink sink;
  bh::LoopSettings settings = fast();
  settings.pausable = false;
  bh::ControlLoop loop(robot, sink, settings);
  Running running(loop);
  for (const bh::LoopOutcome& refused : {loop.pause(true), loop.step(10)}) {
    EXPECT_FALSE(refused.success);
    EXPECT_NE(refused.message.find("cannot be held or stepped"), std::string::npos) << refused.message;
  }
  EXPECT_TRUE(loop.pause(false).success);
  EXPECT_FALSE(loop.paused());
  const long before = loop.counts().cycles;
  EXPECT_TRUE(waitFor([&] { return loop.counts().cycles > before + 100; })) << "the loop stopped";
  settings.paused = true;
  EXPECT_THROW(bh::ControlLoop(robot, sink, settings), std::invalid_argument);
}

TEST(SimulatedRobot, DoesAScheduledGripperCommandInTheFirstCycleAtOrAfterItsTimeAndDropsItOnReset) {
  sim::SimConfig config = sim::SimConfig::fromYamlFile(BIMANUAL_SKILLS_SOURCE_DIR "/config/sim.yaml");
  ASSERT_TRUE(config.has_cloth);
  const auto run = [](sim::SimConfig c, double release_at, bool reset_before) {
    sim::BimanualSimulation simulation(c);
    bh::SimulatedRobot robot(simulation);
    RecordingSink sink;
    bh::LoopSettings settings = fast();
    settings.period = simulation.stepSize();
    settings.paused = true;
    bh::ControlLoop loop(robot, sink, settings);
    Running running(loop);
    EXPECT_TRUE(std::isnan(robot.done(0).at));
    EXPECT_TRUE(loop.call([&] {
                      robot.schedule(0, release_at, false);
                      if (reset_before) robot.reset();
                      return bh::LoopOutcome{true, "", 0.0};
                    })
                    .success);
    const bh::LoopOutcome stepped = loop.step(20);
    EXPECT_TRUE(stepped.success) << stepped.message;
    return std::make_pair(robot.done(0), robot.doneCount(0));
  };
  const double dt = sim::BimanualSimulation(config).stepSize();
  const double at = 10.5 * dt, first_cycle = 11 * dt;
  // With a cloth the release succeeds: done at the first cycle's time, for the time it was scheduled.
  const auto [done, count] = run(config, at, false);
  EXPECT_EQ(count, 1u);
  EXPECT_NEAR(done.at, first_cycle, 1e-12);
  EXPECT_EQ(done.due, at);
  // Without a cloth it fails in the same cycle: -t - 1.
  sim::SimConfig bare = config;
  bare.has_cloth = false;
  const auto [failed, failed_count] = run(bare, at, false);
  EXPECT_EQ(failed_count, 1u);
  EXPECT_NEAR(failed.at, -first_cycle - 1.0, 1e-12);
  // A reset drops it: it was scheduled on the old clock.
  const auto [dropped, dropped_count] = run(config, at, true);
  EXPECT_EQ(dropped_count, 0u);
  EXPECT_TRUE(std::isnan(dropped.at));
}
