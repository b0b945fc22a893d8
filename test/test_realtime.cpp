// The pieces of a real-time loop: the lock-free triple buffer (latest wins, whole values across threads), the period
// recorder, the loop pacer (absolute deadlines, re-anchoring instead of catch-up bursts, sleeps in slices), and the
// arm controller run by a loop and commanded from other threads (goals and their tolerances as control_msgs'
// FollowJointTrajectory defines them, no allocation in the loop).
#include "bimanual_skills/control/realtime_arm_controller.hpp"
#include "bimanual_skills/realtime/loop_pacer.hpp"
#include "bimanual_skills/realtime/period_recorder.hpp"
#include "bimanual_skills/realtime/seqlock.hpp"
#include "bimanual_skills/realtime/triple_buffer.hpp"
#include "test_support.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <chrono>
#include <thread>

namespace bc = bimanual_skills::control;
namespace bd = bimanual_skills::dynamics;
namespace bk = bimanual_skills::kinematics;
namespace rt = bimanual_skills::realtime;
using bimanual_skills::testing::NoAllocGuard;

namespace {

TEST(TripleBuffer, LatestWinsAndNothingIsReadTwice) {
  rt::TripleBuffer<int> buffer(-1);
  EXPECT_EQ(buffer.readNew(), nullptr);
  EXPECT_EQ(buffer.current(), -1);
  buffer.write(1);
  buffer.write(2);
  buffer.write(3);
  const int* value = buffer.readNew();
  ASSERT_NE(value, nullptr);
  EXPECT_EQ(*value, 3);
  EXPECT_EQ(buffer.readNew(), nullptr);
  EXPECT_EQ(buffer.current(), 3);
  buffer.writeSlot() = 4;
  EXPECT_EQ(buffer.readNew(), nullptr);  // not published yet
  buffer.publish();
  ASSERT_NE(buffer.readNew(), nullptr);
  EXPECT_EQ(buffer.current(), 4);
}

TEST(TripleBuffer, ReaderSeesWholeValuesInOrderAcrossThreads) {
  using Value = std::array<long, 64>;
  Value zero{};
  rt::TripleBuffer<Value> buffer(zero);
  constexpr long kWrites = 200000, kAhead = 1000;
  std::atomic<long> seen{0};
  // The writer never runs more than kAhead values ahead of what the reader has seen, so the two interleave even
  // when the scheduler would let the writer finish before the reader starts (a loaded machine).
  std::thread writer([&buffer, &seen] {
    for (long i = 1; i <= kWrites; ++i) {
      while (i - seen.load() > kAhead) std::this_thread::yield();
      Value& slot = buffer.writeSlot();
      for (std::size_t k = 0; k < slot.size(); ++k) slot[k] = i * static_cast<long>(k + 1);
      buffer.publish();
    }
  });
  long last = 0, reads = 0, torn = 0, backwards = 0;
  while (last < kWrites) {
    const Value* v = buffer.readNew();
    if (!v) continue;
    ++reads;
    const long i = (*v)[0];
    for (std::size_t k = 0; k < v->size(); ++k) torn += (*v)[k] != i * static_cast<long>(k + 1);
    backwards += i <= last;
    last = i;
    seen.store(i);
  }
  writer.join();
  EXPECT_EQ(torn, 0);
  EXPECT_EQ(backwards, 0);
  EXPECT_GE(reads, kWrites / kAhead);
  EXPECT_EQ(last, kWrites);  // the last value written always arrives
}

TEST(PeriodRecorder, KeepsTheLastSamplesAndSummarises) {
  rt::PeriodRecorder recorder(4);
  std::vector<double> out;
  recorder.snapshot(out);
  EXPECT_TRUE(out.empty());
  for (int i = 1; i <= 6; ++i) recorder.record(i);
  recorder.snapshot(out);
  EXPECT_EQ(out, (std::vector<double>{3, 4, 5, 6}));
  EXPECT_EQ(recorder.recorded(), 6u);
  std::vector<double> samples;
  for (int i = 1; i <= 1000; ++i) samples.push_back(i);
  const rt::PeriodSummary s = rt::summarize(samples);
  EXPECT_EQ(s.count, 1000u);
  EXPECT_EQ(s.median, 500);
  EXPECT_EQ(s.p99, 990);
  EXPECT_EQ(s.p999, 999);
  EXPECT_EQ(s.max, 1000);
  EXPECT_DOUBLE_EQ(s.mean, 500.5);
  EXPECT_THROW(rt::PeriodRecorder(0), std::invalid_argument);
}

TEST(SeqLock, ReadersSeeWholeWritesWhileTheWriterNeverWaits) {
  struct Pair {
    double at, due;
    std::uint64_t count;
  };
  rt::SeqLock<Pair> value(Pair{0.0, 0.0, 0});
  EXPECT_EQ(value.writes(), 0u);
  std::atomic<bool> done{false};
  std::thread writer([&] {
    for (std::uint64_t k = 1; k <= 200000; ++k) {
      value.write(Pair{static_cast<double>(k), 2.0 * static_cast<double>(k), k});
    }
    done = true;
  });
  long torn = 0, reads = 0;
  std::uint64_t last = 0;
  while (!done) {
    const Pair p = value.read();
    ++reads;
    if (p.due != 2.0 * p.at || p.count != static_cast<std::uint64_t>(p.at) || p.count < last) ++torn;
    last = p.count;
  }
  writer.join();
  EXPECT_EQ(torn, 0) << "of " << reads << " reads";
  EXPECT_EQ(value.read().count, 200000u);
  EXPECT_EQ(value.writes(), 200000u);
}

TEST(LoopPacer, ReanchorsInsteadOfCatchingUpAndSleepsInSlices) {
  EXPECT_THROW(rt::LoopPacer(0.0), std::invalid_argument);
  rt::LoopPacer pacer(0.002, 0.05);
  EXPECT_TRUE(pacer.waitUntilDue(0.01));  // due at once after construction
  pacer.advance();
  EXPECT_GT(pacer.untilDeadline(), 0.0);
  // Ten cycles keep the schedule: the deadlines are absolute.
  const auto start = std::chrono::steady_clock::now();
  for (int k = 0; k < 10; ++k) {
    while (!pacer.waitUntilDue(0.01)) {
    }
    pacer.advance();
  }
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GT(elapsed, 0.017);
  EXPECT_EQ(pacer.slips(), 0);
  // A stall of 0.2 s (more than the 0.05 s tolerated): the next deadline is not 100 periods in the past; the
  // schedule restarts now and the slip is counted.
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_TRUE(pacer.waitUntilDue(0.01));
  pacer.advance();
  EXPECT_EQ(pacer.slips(), 1);
  EXPECT_GT(pacer.untilDeadline(), -0.001);
  // A long period is waited for in slices: a 5 ms slice returns before the 0.5 s deadline.
  ASSERT_TRUE(pacer.setPeriod(0.5));
  EXPECT_TRUE(pacer.waitUntilDue(0.005));
  pacer.advance();
  const auto slice_start = std::chrono::steady_clock::now();
  EXPECT_FALSE(pacer.waitUntilDue(0.005));
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - slice_start).count(), 0.25);
  EXPECT_FALSE(pacer.setPeriod(-1.0));
}

// ---------------------------------------------------------------------------------------------------------------

/// The WAM model (with rotors, no friction) driven by a RealtimeArmController at 1 kHz through its own forward
/// dynamics.
struct Loop {
  bk::ChainModel model = bimanual_skills::test_support::wamWithRotors();
  bd::DynamicsData data{model};
  Eigen::VectorXd q = (Eigen::VectorXd(7) << 0.0, 0.6, 0.0, 1.6, 0.0, 0.4, 0.0).finished();
  Eigen::VectorXd qd = Eigen::VectorXd::Zero(7), qdd = Eigen::VectorXd::Zero(7), tau = Eigen::VectorXd::Zero(7);
  Eigen::VectorXd none;
  Eigen::VectorXd external = Eigen::VectorXd::Zero(7);  ///< Torques the world applies to the joints [N m].
  Eigen::VectorXd applied = Eigen::VectorXd::Zero(7);   ///< tau + external (no allocation per step).
  double t = 0.0;

  static bc::ArmControllerConfig config() { return bimanual_skills::test_support::loopControllerConfig(); }
  static bd::FrictionModel friction() { return bimanual_skills::test_support::noFriction(); }

  bc::ControllerStatus step(bc::RealtimeArmController& controller) {
    const bc::ControllerStatus status = controller.update(t, t, q, qd, none, tau);
    applied.noalias() = tau + external;
    (void)bd::forwardDynamics(model, data, q, qd, applied, qdd);
    qd += 0.001 * qdd;
    q += 0.001 * qd;
    t += 0.001;
    return status;
  }
};

bc::ControllerCommand trajectoryTo(const Eigen::VectorXd& target, double duration, std::uint64_t id) {
  bc::ControllerCommand c;
  c.kind = bc::ControllerCommand::Kind::Trajectory;
  c.waypoints.times = Eigen::VectorXd::Constant(1, duration);
  c.waypoints.positions = target;
  c.tolerances = bc::TrajectoryTolerances::none(7);
  c.goal_id = id;
  return c;
}

/// Runs `steps` steps and returns the newest state handed out.
bc::ArmControllerState run(Loop& loop, bc::RealtimeArmController& controller, int steps) {
  for (int k = 0; k < steps; ++k) loop.step(controller);
  const bc::ArmControllerState* state = controller.latestState();
  EXPECT_NE(state, nullptr);
  return state ? *state : bc::ArmControllerState(7);
}

// The state hands out the disturbance observer's joint torques (what ARM/estimated_external_torque publishes): held
// against a constant push on joints 2 and 4, they converge to it.
TEST(RealtimeArmController, ItsStateCarriesTheObserversExternalTorques) {
  Loop loop;
  bc::RealtimeArmController controller(loop.model, Loop::friction(), Loop::config());
  run(loop, controller, 50);
  loop.external << 0.0, 3.0, 0.0, -2.0, 0.0, 0.0, 0.0;
  const bc::ArmControllerState state = run(loop, controller, 2000);
  ASSERT_EQ(state.external_torque.size(), 7);
  EXPECT_LT((state.external_torque - loop.external).cwiseAbs().maxCoeff(), 0.1) << state.external_torque.transpose();
}

TEST(RealtimeArmController, GoalsSucceedOrReportTheViolatedTolerance) {
  Loop loop;
  bc::RealtimeArmController controller(loop.model, Loop::friction(), Loop::config());
  run(loop, controller, 50);
  const Eigen::VectorXd start = loop.q;
  Eigen::VectorXd target = start;
  target[0] += 0.4;

  // Within its tolerances: succeeded once the end is reached and the arm has stopped.
  bc::ControllerCommand good = trajectoryTo(target, 1.0, 1);
  good.tolerances.path_position.setConstant(0.05);
  good.tolerances.goal_position.setConstant(0.01);
  good.tolerances.goal_velocity.setConstant(0.05);
  controller.command(good);
  bc::ArmControllerState s = run(loop, controller, 500);
  EXPECT_EQ(s.goal_id, 1u);
  EXPECT_EQ(s.goal, bc::GoalState::Active);
  EXPECT_EQ(s.mode, bc::ControllerMode::Track);
  EXPECT_EQ(s.commands_taken, 1u);
  s = run(loop, controller, 1000);
  EXPECT_EQ(s.goal, bc::GoalState::Succeeded);
  EXPECT_LT(std::abs(loop.q[0] - target[0]), 0.01);

  // A path tolerance no real arm keeps: violated while running, the arm holds where it is.
  bc::ControllerCommand tight = trajectoryTo(start, 0.5, 2);
  tight.tolerances.path_position.setConstant(1e-6);
  controller.command(tight);
  s = run(loop, controller, 100);
  EXPECT_EQ(s.goal_id, 2u);
  EXPECT_EQ(s.goal, bc::GoalState::PathToleranceViolated);
  EXPECT_GE(s.goal_joint, 0);
  EXPECT_GT(std::abs(s.goal_error), 1e-6);
  EXPECT_EQ(s.mode, bc::ControllerMode::Hold);
  const double held = loop.q[0];
  run(loop, controller, 500);
  EXPECT_LT(std::abs(loop.q[0] - held), 0.02);

  // A goal tolerance not met within the goal time: violated after end + goal_time.
  bc::ControllerCommand precise = trajectoryTo(start, 1.0, 3);
  precise.tolerances.goal_position.setConstant(1e-12);
  precise.tolerances.goal_time = 0.2;
  controller.command(precise);
  s = run(loop, controller, 1150);
  EXPECT_EQ(s.goal, bc::GoalState::Active);  // past the end, within the goal time
  s = run(loop, controller, 100);
  EXPECT_EQ(s.goal, bc::GoalState::GoalToleranceViolated);
  EXPECT_GE(s.goal_joint, 0);

  // Waypoints outside the limits: rejected by the loop, nothing changes; validate() says so beforehand.
  bc::ControllerCommand outside = trajectoryTo(start, 1.0, 4);
  outside.waypoints.positions(1, 0) = 5.0;
  EXPECT_EQ(controller.validate(outside.waypoints), bc::TrajectoryStatus::OutOfLimits);
  controller.command(outside);
  s = run(loop, controller, 10);
  EXPECT_EQ(s.goal_id, 4u);
  EXPECT_EQ(s.goal, bc::GoalState::Rejected);
  EXPECT_EQ(s.rejection, bc::TrajectoryStatus::OutOfLimits);

  // Too many points for the capacity: refused by validate() and the loop alike.
  bc::ControllerCommand long_one = trajectoryTo(start, 1.0, 5);
  long_one.waypoints.times = Eigen::VectorXd::LinSpaced(11, 0.1, 1.1);
  long_one.waypoints.positions = start.replicate(1, 11);
  EXPECT_EQ(controller.validate(long_one.waypoints), bc::TrajectoryStatus::WrongSize);

  // A mode command preempts a running goal.
  controller.command(trajectoryTo(target, 2.0, 6));
  run(loop, controller, 100);
  bc::ControllerCommand hold;
  hold.kind = bc::ControllerCommand::Kind::Mode;
  hold.mode = bc::ControllerMode::Hold;
  controller.command(hold);
  s = run(loop, controller, 2);
  EXPECT_EQ(s.goal_id, 6u);
  EXPECT_EQ(s.goal, bc::GoalState::Preempted);
  EXPECT_EQ(s.mode, bc::ControllerMode::Hold);

  // States that stop arriving abort a running goal.
  controller.command(trajectoryTo(target, 2.0, 7));
  run(loop, controller, 100);
  Eigen::VectorXd torque(7);
  EXPECT_EQ(controller.update(loop.t + 1.0, loop.t, loop.q, loop.qd, loop.none, torque),
            bc::ControllerStatus::StaleState);
  s = run(loop, controller, 2);
  EXPECT_EQ(s.goal_id, 7u);
  EXPECT_EQ(s.goal, bc::GoalState::Aborted);
  EXPECT_EQ(s.abort_reason, bc::ControllerStatus::StaleState);
  EXPECT_EQ(s.mode, bc::ControllerMode::Hold);
  EXPECT_GT(s.status_counts[static_cast<int>(bc::ControllerStatus::StaleState)], 0);
}

// A velocity-limit stop says whether a gap in the states (the robot without this controller's torques) came just
// before it: the robot's fault then, the policy's otherwise.
TEST(RealtimeArmController, AVelocityLimitStopNamesAGapInTheStatesJustBeforeIt) {
  Loop loop;
  bc::ArmControllerConfig config = Loop::config();
  config.state_timeout = 0.05;
  bc::RealtimeArmController controller(loop.model, Loop::friction(), config);
  run(loop, controller, 50);
  Eigen::VectorXd target = loop.q;
  target[0] += 0.3;
  Eigen::VectorXd torque(7);
  // Runs a goal for 100 steps, then `gap` s without states and `after` s of states, then one state at 100 rad/s.
  const auto stopAfter = [&](std::uint64_t id, double gap, double after) {
    controller.command(trajectoryTo(target, 3.0, id));
    run(loop, controller, 100);
    loop.t += gap;
    run(loop, controller, static_cast<int>(after / 0.001));
    Eigen::VectorXd fast = loop.qd;
    fast[6] = 100.0;
    EXPECT_EQ(controller.update(loop.t, loop.t, loop.q, fast, loop.none, torque), bc::ControllerStatus::VelocityLimit);
    const bc::ArmControllerState* s = controller.latestState();
    EXPECT_NE(s, nullptr);
    EXPECT_EQ(s ? s->goal_id : 0u, id);
    EXPECT_EQ(s ? s->goal : bc::GoalState::None, bc::GoalState::Aborted);
    EXPECT_EQ(s ? s->abort_reason : bc::ControllerStatus::Ok, bc::ControllerStatus::VelocityLimit);
    const double abort_gap = s ? s->abort_gap : -1.0;
    loop.t += 0.001;
    run(loop, controller, 200);  // the arm holds again
    return abort_gap;
  };
  EXPECT_EQ(stopAfter(1, 0.0, 0.1), 0.0);             // states on time: the policy's
  EXPECT_NEAR(stopAfter(2, 0.08, 0.2), 0.081, 1e-9);  // 0.2 s after an 81 ms gap: the robot's
  EXPECT_EQ(stopAfter(3, 0.08, 0.7), 0.0);            // long after it: the policy's again
  EXPECT_EQ(stopAfter(4, 0.03, 0.1), 0.0);            // a gap within the state timeout: none
}

// control_msgs' timing: a trajectory runs from its own start (header.stamp), not from the cycle that takes it.
TEST(RealtimeArmController, ATrajectoryStartsAtItsOwnStampAheadOrBehind) {
  Loop left, right;
  bc::RealtimeArmController a(left.model, Loop::friction(), Loop::config());
  bc::RealtimeArmController b(right.model, Loop::friction(), Loop::config());
  const auto both = [&](int steps) {
    NoAllocGuard guard;  // holding, receiving and starting a trajectory do not allocate
    for (int k = 0; k < steps; ++k) {
      left.step(a);
      right.step(b);
    }
  };
  // The newest state of each (latestState() gives a state once).
  bc::ArmControllerState last_a(7), last_b(7);
  const auto state = [&](bc::RealtimeArmController& c) -> const bc::ArmControllerState& {
    bc::ArmControllerState& last = &c == &a ? last_a : last_b;
    if (const bc::ArmControllerState* fresh = c.latestState()) last = *fresh;
    return last;
  };
  both(50);
  const Eigen::VectorXd start = left.q;
  Eigen::VectorXd target = start;
  target[0] += 0.3;

  // A first motion (2 s), then both arms get a trajectory that starts 0.1234 s ahead, off the 1 ms grid: the first
  // motion goes on until then, and both begin in the first cycle at or after it, the same for both.
  a.command(trajectoryTo(target, 2.0, 1));
  both(300);
  const double t_start = left.t + 0.1234;
  for (auto* controller : {&a, &b}) {
    bc::ControllerCommand c = trajectoryTo(start, 0.5, 2);
    c.start = t_start;
    controller->command(c);
  }
  both(100);
  const bc::ArmControllerState before = state(a);
  EXPECT_EQ(a.receivedGoal(), 2u);  // handed over: the loop has it
  EXPECT_EQ(before.goal_id, 1u);    // and the first motion still runs
  EXPECT_EQ(before.goal, bc::GoalState::Active);
  EXPECT_GT(std::abs(before.desired_velocity[0]), 0.05);
  both(30);
  const bc::ArmControllerState sa = state(a), sb = state(b);
  EXPECT_EQ(sa.goal_id, 2u);
  EXPECT_EQ(sb.goal_id, 2u);
  EXPECT_EQ(sa.trajectory_start, sb.trajectory_start);
  EXPECT_GE(sa.trajectory_start, t_start);
  EXPECT_LT(sa.trajectory_start, t_start + 0.001 + 1e-9);
  // Its last waypoint at t_start + 0.5 exactly, not at the taking cycle + 0.5.
  while (left.t < t_start + 0.5 - 1e-9) both(1);
  const double last_before = state(a).stamp;
  EXPECT_LT(last_before, t_start + 0.5);
  EXPECT_GT(std::abs(state(a).desired_position[0] - start[0]), 1e-12);
  both(1);
  EXPECT_GE(state(a).stamp, t_start + 0.5);
  EXPECT_LT((state(a).desired_position - start).cwiseAbs().maxCoeff(), 1e-12);

  // A start 0.3 s behind: the waypoint at 0.2 is past and dropped, the one at 0.6 reached at start + 0.6.
  both(200);
  bc::ControllerCommand behind = trajectoryTo(target, 0.6, 3);
  behind.waypoints.times = Eigen::Vector2d(0.2, 0.6);
  behind.waypoints.positions = (Eigen::MatrixXd(7, 2) << start, target).finished();
  behind.start = left.t - 0.3;
  const double t_end = behind.start + 0.6;
  a.command(behind);
  while (left.t < t_end - 1e-9) both(1);
  EXPECT_EQ(state(a).goal_id, 3u);
  EXPECT_GT(std::abs(state(a).desired_position[0] - target[0]), 1e-12);
  both(1);
  EXPECT_LT((state(a).desired_position - target).cwiseAbs().maxCoeff(), 1e-12);

  // Every waypoint behind: rejected, InThePast; validate() with the offset says so beforehand.
  bc::ControllerCommand past = behind;
  past.goal_id = 4;
  past.start = left.t - 1.0;
  EXPECT_EQ(a.validate(past.waypoints, -1.0), bc::TrajectoryStatus::InThePast);
  a.command(past);
  both(2);
  EXPECT_EQ(state(a).goal_id, 4u);
  EXPECT_EQ(state(a).goal, bc::GoalState::Rejected);
  EXPECT_EQ(state(a).rejection, bc::TrajectoryStatus::InThePast);

  // A loop that stands still (idle) receives a command, and takes it only when it runs again.
  bc::ControllerCommand later = trajectoryTo(start, 0.5, 5);
  later.start = left.t;
  b.command(later);
  const std::uint64_t taken = b.commandsTaken();
  const double alive = b.lastCycle();
  b.idle();
  EXPECT_EQ(b.receivedGoal(), 5u);
  EXPECT_EQ(b.commandsTaken(), taken);
  EXPECT_GE(b.lastCycle(), alive);
  both(1);
  EXPECT_EQ(b.commandsTaken(), taken + 1);
  EXPECT_EQ(state(b).goal_id, 5u);
}

// A hold that comes while the arm moves (a cancel) stops it smoothly from its desired state: neither the desired
// position nor the desired velocity has a step (the stop starts where the reference is at the cycle that takes it,
// not where it was one cycle before), the velocity falls to rest within 2 max|q̇_d| / stop_deceleration, and the arm
// comes to rest near where it stopped.
TEST(RealtimeArmController, AHoldWhileMovingStopsSmoothly) {
  Loop loop;
  bc::RealtimeArmController controller(loop.model, Loop::friction(), Loop::config());
  run(loop, controller, 50);
  Eigen::VectorXd target = loop.q;
  target[0] += 0.6;
  controller.command(trajectoryTo(target, 1.0, 1));
  bc::ArmControllerState before = run(loop, controller, 500);  // mid-motion: the quintic at its fastest
  const double speed = before.desired_velocity.cwiseAbs().maxCoeff();
  ASSERT_GT(speed, 0.5);
  bc::ControllerCommand hold;
  hold.kind = bc::ControllerCommand::Kind::Mode;
  hold.mode = bc::ControllerMode::Hold;
  controller.command(hold);
  double largest_step = 0.0, largest_jump = 0.0;
  bc::ArmControllerState previous = before;
  const double stop_time = 2.0 * speed / bc::ArmControllerConfig{}.stop_deceleration;
  const int steps = static_cast<int>(std::ceil(stop_time / 0.001)) + 2;
  for (int k = 0; k < steps; ++k) {
    const bc::ArmControllerState s = run(loop, controller, 1);
    largest_step = std::max(largest_step, (s.desired_velocity - previous.desired_velocity).cwiseAbs().maxCoeff());
    // The position against its velocity's integral over the cycle (trapezoid): a reference set back shows.
    const Eigen::VectorXd moved =
        s.desired_position - previous.desired_position - 0.5 * 0.001 * (s.desired_velocity + previous.desired_velocity);
    largest_jump = std::max(largest_jump, moved.cwiseAbs().maxCoeff());
    previous = s;
  }
  EXPECT_LT(largest_jump, 1e-6) << "a step in the desired position (one cycle's motion is " << speed * 1e-3 << ")";
  EXPECT_EQ(previous.goal, bc::GoalState::Preempted);
  EXPECT_EQ(previous.mode, bc::ControllerMode::Hold);
  EXPECT_LT(largest_step, 0.02) << "a step in the desired velocity";  // ~ stop_deceleration × 1 ms × 1.9
  EXPECT_LT(previous.desired_velocity.cwiseAbs().maxCoeff(), 1e-9);
  const Eigen::VectorXd rest = previous.desired_position;
  run(loop, controller, 800);
  EXPECT_LT((loop.q - rest).cwiseAbs().maxCoeff(), 0.02);
}

TEST(RealtimeArmController, TheLoopNeverAllocatesWhileCommandsArriveFromAnotherThread) {
  Loop loop;
  bc::RealtimeArmController controller(loop.model, Loop::friction(), Loop::config());
  run(loop, controller, 10);
  std::atomic<bool> stop{false};
  std::atomic<long> sent{0};
  std::thread commander([&] {
    Eigen::VectorXd target = loop.q;  // read once before the loop moves on
    for (std::uint64_t id = 1; !stop; ++id) {
      target[0] = 0.2 * std::sin(0.01 * static_cast<double>(id));
      controller.command(trajectoryTo(target, 0.5, id));
      ++sent;
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
  });
  std::uint64_t last_sequence = 0, taken = 0;
  {
    NoAllocGuard guard;
    // At least 3000 cycles, and on until the commander's commands got through (a loaded machine may not schedule
    // it during the first 3000): the loop yields its core once past them.
    for (int k = 0; k < 3000 || (taken <= 10 && k < 2000000); ++k) {
      if (k >= 3000) std::this_thread::yield();
      loop.step(controller);
      if (const bc::ArmControllerState* s = controller.latestState()) {
        EXPECT_GT(s->sequence, last_sequence);
        last_sequence = s->sequence;
        taken = s->commands_taken;
      }
    }
  }
  stop = true;
  commander.join();
  EXPECT_GT(taken, 10u);
  EXPECT_GT(sent.load(), 10);
  EXPECT_TRUE(loop.q.allFinite());
}

}  // namespace
