// The real-time parts of the controller node and the simulator node: the quintic joint trajectory (against finite
// differences and its own waypoints), the arm controller in closed loop with the model's forward dynamics (tracking,
// observer against a known payload, safety reactions, no allocation) and the torque command gate.
#include "bimanual_skills/control/arm_controller.hpp"
#include "bimanual_skills/control/joint_trajectory.hpp"
#include "bimanual_skills/sim/torque_command_gate.hpp"
#include "test_support.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

namespace bc = bimanual_skills::control;
namespace bd = bimanual_skills::dynamics;
namespace bk = bimanual_skills::kinematics;
namespace bsim = bimanual_skills::sim;
using bimanual_skills::test_support::lowGains;
using bimanual_skills::test_support::wamWithRotors;
using bimanual_skills::testing::NoAllocGuard;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

bc::JointTrajectory freeTrajectory(int n, int capacity) {
  return bc::JointTrajectory(n, capacity, Eigen::VectorXd::Constant(n, -kInf), Eigen::VectorXd::Constant(n, kInf));
}

bc::Waypoints threePoints() {
  bc::Waypoints w;
  w.times = Eigen::Vector3d(0.5, 1.0, 2.0);
  w.positions = (Eigen::MatrixXd(2, 3) << 0.3, 0.8, 0.2, -0.1, -0.4, -0.6).finished();
  return w;
}

struct Sample {
  Eigen::VectorXd q, qd, qdd;
};

Sample sampleAt(const bc::JointTrajectory& trajectory, double t) {
  Sample s{Eigen::VectorXd(trajectory.joints()), Eigen::VectorXd(trajectory.joints()),
           Eigen::VectorXd(trajectory.joints())};
  trajectory.sample(t, s.q, s.qd, s.qdd);
  return s;
}

/// Central-difference check of q̇ and q̈, and continuity across [t0, t1].
void expectSmooth(const bc::JointTrajectory& trajectory, double t0, double t1) {
  const double h = 1e-5;
  for (double t = t0 + 1e-4; t < t1; t += 0.0137) {
    const Sample a = sampleAt(trajectory, t - h), b = sampleAt(trajectory, t), c = sampleAt(trajectory, t + h);
    EXPECT_LT(((c.q - a.q) / (2 * h) - b.qd).cwiseAbs().maxCoeff(), 1e-5) << "t = " << t;
    EXPECT_LT(((c.qd - a.qd) / (2 * h) - b.qdd).cwiseAbs().maxCoeff(), 1e-4) << "t = " << t;
    // A step in q̈ would show as a jump between neighbours 2h apart.
    EXPECT_LT((c.qdd - a.qdd).cwiseAbs().maxCoeff(), 1e-2) << "t = " << t;
  }
}

}  // namespace

TEST(JointTrajectory, PassesThroughWaypointsWithContinuousAccelerations) {
  bc::JointTrajectory trajectory = freeTrajectory(2, 8);
  const bc::Waypoints w = threePoints();
  ASSERT_EQ(trajectory.load(w), bc::TrajectoryStatus::Ok);
  const Eigen::Vector2d q0(0.0, 0.0), v0(0.2, -0.1), a0(0.5, 0.0);
  ASSERT_EQ(trajectory.start(10.0, q0, v0, a0), bc::TrajectoryStatus::Ok);
  const Sample start = sampleAt(trajectory, 10.0);
  EXPECT_LT((start.q - q0).norm(), 1e-12);
  EXPECT_LT((start.qd - v0).norm(), 1e-12);
  EXPECT_LT((start.qdd - a0).norm(), 1e-12);
  for (int i = 0; i < 3; ++i) {
    EXPECT_LT((sampleAt(trajectory, 10.0 + w.times[i]).q - w.positions.col(i)).norm(), 1e-12) << i;
  }
  // Joint 0 turns at waypoint 2 (0.3 → 0.8 → 0.2): velocity 0 there; joint 1 keeps going down: the mean slope.
  const Sample mid = sampleAt(trajectory, 11.0);
  EXPECT_NEAR(mid.qd[0], 0.0, 1e-12);
  EXPECT_NEAR(mid.qd[1], 0.5 * (-0.3 / 0.5 + -0.2 / 1.0), 1e-12);
  const Sample end = sampleAt(trajectory, 13.0);
  EXPECT_LT((end.q - w.positions.col(2)).norm(), 1e-12);
  EXPECT_LT(end.qd.norm() + end.qdd.norm(), 1e-12);
  EXPECT_TRUE(trajectory.finished(12.0));
  expectSmooth(trajectory, 10.0, 12.5);
}

TEST(JointTrajectory, ReplacementMidMotionHasNoJump) {
  bc::JointTrajectory trajectory = freeTrajectory(2, 8);
  ASSERT_EQ(trajectory.load(threePoints()), bc::TrajectoryStatus::Ok);
  ASSERT_EQ(trajectory.start(0.0, Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()),
            bc::TrajectoryStatus::Ok);
  const Sample before = sampleAt(trajectory, 0.7);
  bc::Waypoints other;
  other.times = Eigen::VectorXd::Constant(1, 1.0);
  other.positions = Eigen::Vector2d(-0.5, 0.5);
  ASSERT_EQ(trajectory.load(other), bc::TrajectoryStatus::Ok);
  ASSERT_EQ(trajectory.start(0.7, before.q, before.qd, before.qdd), bc::TrajectoryStatus::Ok);
  const Sample after = sampleAt(trajectory, 0.7);
  EXPECT_LT((after.q - before.q).norm() + (after.qd - before.qd).norm() + (after.qdd - before.qdd).norm(), 1e-12);
  expectSmooth(trajectory, 0.7, 1.8);
}

// A stop from a moving state: one smooth segment to rest at q + q̇ T/2, no step in q, q̇ or q̈ at its start.
TEST(JointTrajectory, StopsSmoothlyFromAMovingState) {
  bc::JointTrajectory trajectory = freeTrajectory(2, 4);
  const Eigen::Vector2d q(0.3, -0.2), qd(1.5, -0.4), qdd(2.0, 0.5);
  trajectory.stop(10.0, q, qd, qdd, 0.6);
  const Sample start = sampleAt(trajectory, 10.0);
  EXPECT_LT((start.q - q).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((start.qd - qd).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((start.qdd - qdd).cwiseAbs().maxCoeff(), 1e-9);
  expectSmooth(trajectory, 10.0, 10.6);
  const Sample end = sampleAt(trajectory, 10.6), after = sampleAt(trajectory, 11.5);
  EXPECT_LT((end.q - (q + 0.3 * qd)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT(end.qd.cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((after.q - end.q).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_TRUE(trajectory.finished(10.6));
}

TEST(JointTrajectory, RejectsBadWaypointsAndKeepsTheOldOnes) {
  bc::JointTrajectory trajectory(2, 3, Eigen::Vector2d(-1, -1), Eigen::Vector2d(1, 1));
  bc::Waypoints w = threePoints();
  ASSERT_EQ(trajectory.load(w), bc::TrajectoryStatus::Ok);
  bc::Waypoints bad = w;
  bad.positions(1, 1) = std::nan("");
  EXPECT_EQ(trajectory.load(bad), bc::TrajectoryStatus::NotFinite);
  bad = w;
  bad.times[2] = 0.9;
  EXPECT_EQ(trajectory.load(bad), bc::TrajectoryStatus::NotIncreasing);
  bad = w;
  bad.times[0] = 0.0;
  EXPECT_EQ(trajectory.load(bad), bc::TrajectoryStatus::NotIncreasing);
  bad = w;
  bad.positions(0, 0) = 1.5;
  EXPECT_EQ(trajectory.load(bad), bc::TrajectoryStatus::OutOfLimits);
  bad = w;
  bad.velocities = Eigen::MatrixXd::Zero(2, 2);
  EXPECT_EQ(trajectory.load(bad), bc::TrajectoryStatus::WrongSize);
  bad.times = Eigen::VectorXd::LinSpaced(4, 0.1, 0.4);
  bad.positions = Eigen::MatrixXd::Zero(2, 4);
  bad.velocities.resize(0, 0);
  EXPECT_EQ(trajectory.load(bad), bc::TrajectoryStatus::WrongSize);  // beyond the capacity of 3
  ASSERT_EQ(trajectory.start(0.0, Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero()),
            bc::TrajectoryStatus::Ok);
  EXPECT_LT((sampleAt(trajectory, 2.0).q - w.positions.col(2)).norm(), 1e-12);
}

namespace {

/// The WAM model with rotors, driven by the controller through its own forward dynamics (semi-implicit Euler at
/// 1 kHz), optionally carrying a payload the controller does not know.
struct ClosedLoop {
  bk::ChainModel model = wamWithRotors();
  bd::DynamicsData data{model};
  Eigen::VectorXd q = (Eigen::VectorXd(7) << 0.0, 0.6, 0.0, 1.6, 0.0, 0.4, 0.0).finished();
  Eigen::VectorXd qd = Eigen::VectorXd::Zero(7), qdd = Eigen::VectorXd::Zero(7), tau = Eigen::VectorXd::Zero(7);
  bd::Payload payload;
  double t = 0.0;
  static constexpr double kStep = 0.001;

  static bc::ArmControllerConfig config() {
    bc::ArmControllerConfig c;
    c.gains = lowGains();
    c.observer = bc::ObserverGains::diagonal(7, 10.0, 0.0, 100.0, 0.0, 10.0);
    c.observer.rate_hz = 1000.0;
    c.friction_compensation = false;
    return c;
  }

  /// One control period: the controller sees the state, the plant integrates its torque.
  bc::ControllerStatus step(bc::ArmController& controller) {
    const bc::ControllerStatus status = controller.update(t, t, q, qd, tau);
    if (bd::forwardDynamics(model, data, q, qd, tau, qdd, payload) != bd::DynamicsStatus::Success) ADD_FAILURE();
    qd += kStep * qdd;
    q += kStep * qd;
    t += kStep;
    return status;
  }
};

bd::FrictionModel noFriction() {
  bd::FrictionModel friction;
  friction.joints.assign(7, bd::JointFriction{});
  return friction;
}

}  // namespace

TEST(ArmController, TracksATrajectoryAndEstimatesAnUnknownPayload) {
  ClosedLoop loop;
  bc::ArmController controller(loop.model, noFriction(), ClosedLoop::config());
  for (int k = 0; k < 200; ++k) loop.step(controller);
  EXPECT_EQ(controller.mode(), bc::ControllerMode::Hold);
  bc::Waypoints w;
  w.times = Eigen::Vector2d(1.0, 2.0);
  w.positions.resize(7, 2);
  w.positions.col(0) = loop.q + Eigen::VectorXd::Constant(7, 0.3);
  w.positions.col(1) = loop.q - Eigen::VectorXd::Constant(7, 0.1);
  ASSERT_EQ(controller.setTrajectory(w), bc::TrajectoryStatus::Ok);
  double worst = 0.0;
  for (int k = 0; k < 2500; ++k) {
    EXPECT_NE(loop.step(controller), bc::ControllerStatus::InvalidState);
    worst = std::max(worst, controller.trackingError().cwiseAbs().maxCoeff());
  }
  EXPECT_EQ(controller.mode(), bc::ControllerMode::Track);
  EXPECT_LT(worst, 0.02);  // the model is exact: only discretisation lag remains
  EXPECT_LT((loop.q - w.positions.col(1)).cwiseAbs().maxCoeff(), 1e-3);

  // A 1.5 kg load at the tool appears as a downward force of m g at the tool (base frame z is up).
  loop.payload.mass = 1.5;
  for (int k = 0; k < 3000; ++k) loop.step(controller);
  EXPECT_NEAR(controller.estimatedWrench()[2], -1.5 * 9.81, 0.03 * 1.5 * 9.81);
  EXPECT_LT(controller.estimatedWrench().head<2>().norm(), 0.3);
}

namespace {

/// A moving arm carrying 1.5 kg the controller does not know, its plant integrated at 1 kHz, controlled at
/// `period` [s] (the torque held in between) with a fraction `drop` of the states lost (seeded): the mean estimated
/// vertical tool force of every 0.25 s window of [2, 6] s, and the weight.
struct PayloadRun {
  std::vector<double> window_means;
  double weight = 1.5 * 9.81;
  long irregular = 0;
};

constexpr double kSwingPeriod = 4.0;  ///< [s]
constexpr int kWindow = 250;          ///< Samples (0.25 s) per window.

PayloadRun payloadAtRate(int period_steps, double drop, bool nominal_period_observer = false) {
  ClosedLoop loop;
  loop.payload.mass = 1.5;
  bc::ArmController controller(loop.model, noFriction(), ClosedLoop::config());
  // The observer of the controller integrates the measured Δt; this one is fed every state at its nominal period,
  // as the controller did before: the reference the measured Δt has to beat.
  bc::DisturbanceObserver nominal(loop.model, noFriction(), ClosedLoop::config().observer);
  Eigen::VectorXd torque = Eigen::VectorXd::Zero(7), sign = Eigen::VectorXd::Zero(7);
  std::mt19937 rng(11);
  std::bernoulli_distribution lost(drop);
  bc::Waypoints w;
  const int points = 60;
  w.times.resize(points);
  w.positions.resize(7, points);
  PayloadRun run;
  double sum = 0.0;
  int samples = 0;
  for (int k = 0; k < 6000; ++k) {
    const double t = k * ClosedLoop::kStep;
    if (k == 200) {
      // Joints 1, 2 and 4 swing (0.3, 0.15 and 0.2 rad, a 4 s period) for 6 s.
      const Eigen::VectorXd q0 = loop.q;
      for (int p = 0; p < points; ++p) {
        w.times[p] = 0.1 * (p + 1);
        w.positions.col(p) = q0;
        const double phase = std::sin(2.0 * M_PI * w.times[p] / kSwingPeriod);
        w.positions(0, p) += 0.3 * phase;
        w.positions(1, p) += 0.15 * phase;
        w.positions(3, p) -= 0.2 * phase;
      }
      EXPECT_EQ(controller.setTrajectory(w), bc::TrajectoryStatus::Ok);
    }
    if (k % period_steps == 0 && !lost(rng)) {
      controller.update(t, t, loop.q, loop.qd, torque);
      if (nominal_period_observer) (void)nominal.update(loop.q, loop.qd, loop.tau, sign);
      loop.tau = torque;
    }
    if (bd::forwardDynamics(loop.model, loop.data, loop.q, loop.qd, loop.tau, loop.qdd, loop.payload) !=
        bd::DynamicsStatus::Success) {
      ADD_FAILURE();
    }
    loop.qd += ClosedLoop::kStep * loop.qdd;
    loop.q += ClosedLoop::kStep * loop.qd;
    if (t >= 2.0) {
      sum += nominal_period_observer ? nominal.wrench()[2] : controller.estimatedWrench()[2];
      if (++samples == kWindow) {
        run.window_means.push_back(-sum / samples);
        sum = 0.0;
        samples = 0;
      }
    }
  }
  run.irregular = controller.observer().irregularSteps();
  return run;
}

double worstWindowError(const PayloadRun& run) {
  double worst = 0.0;
  for (double mean : run.window_means) worst = std::max(worst, std::abs(mean - run.weight) / run.weight);
  return worst;
}

}  // namespace

// The observer integrates and filters with the measured Δt, so a robot at 500 Hz (its nominal rate is 1 kHz) and
// states lost on the way give the payload's weight as well as 1 kHz does: within 3 % in every 0.25 s window of a
// swinging motion. Fed at its nominal period instead, it is off by more at 500 Hz.
TEST(ArmController, EstimatesAPayloadAtAnyRate) {
  const PayloadRun at_1khz = payloadAtRate(1, 0.0), at_500hz = payloadAtRate(2, 0.0), dropped = payloadAtRate(1, 0.1);
  const PayloadRun nominal_500hz = payloadAtRate(2, 0.0, true);
  std::printf(
      "worst 0.25 s window error of the estimated weight: 1 kHz %.2f %%, 500 Hz %.2f %%, 1 kHz with 10 %% "
      "lost %.2f %% (%ld irregular steps); at 500 Hz with the nominal period %.2f %%\n",
      100 * worstWindowError(at_1khz), 100 * worstWindowError(at_500hz), 100 * worstWindowError(dropped),
      dropped.irregular, 100 * worstWindowError(nominal_500hz));
  ASSERT_EQ(at_1khz.window_means.size(), 16u);
  EXPECT_LT(worstWindowError(at_1khz), 0.03);
  EXPECT_LT(worstWindowError(at_500hz), 0.03);
  EXPECT_LT(worstWindowError(dropped), 0.03);
  EXPECT_GT(dropped.irregular, 100);
  EXPECT_GT(worstWindowError(nominal_500hz), 0.03);
}

TEST(ArmController, SafetyReactions) {
  ClosedLoop loop;
  bc::ArmController controller(loop.model, noFriction(), ClosedLoop::config());
  Eigen::VectorXd torque = Eigen::VectorXd::Constant(7, 42.0);
  // NaN state: no torque computed.
  Eigen::VectorXd bad = loop.q;
  bad[3] = std::nan("");
  EXPECT_EQ(controller.update(0.0, 0.0, bad, loop.qd, torque), bc::ControllerStatus::InvalidState);
  EXPECT_EQ(torque[0], 42.0);
  EXPECT_FALSE(controller.started());
  for (int k = 0; k < 100; ++k) loop.step(controller);
  // A trajectory outside the limits is rejected; the controller keeps holding.
  bc::Waypoints w;
  w.times = Eigen::VectorXd::Constant(1, 1.0);
  w.positions = loop.q;
  w.positions(1, 0) = 5.0;
  EXPECT_EQ(controller.setTrajectory(w), bc::TrajectoryStatus::OutOfLimits);
  // Stale state (stamped 0.2 s before now): nothing computed, and the controller holds where it resumes.
  w.positions = loop.q + Eigen::VectorXd::Constant(7, 0.2);
  ASSERT_EQ(controller.setTrajectory(w), bc::TrajectoryStatus::Ok);
  for (int k = 0; k < 300; ++k) loop.step(controller);
  EXPECT_EQ(controller.mode(), bc::ControllerMode::Track);
  EXPECT_EQ(controller.update(loop.t + 0.2, loop.t, loop.q, loop.qd, torque), bc::ControllerStatus::StaleState);
  EXPECT_TRUE(controller.stale(loop.t + 0.2));
  loop.step(controller);
  EXPECT_EQ(controller.mode(), bc::ControllerMode::Hold);
  EXPECT_LT((controller.desiredPosition() - (loop.q - loop.qd * ClosedLoop::kStep)).norm(), 1e-9);
  // Too fast: hold at the current position.
  const Eigen::VectorXd fast = Eigen::VectorXd::Constant(7, 10.0);
  EXPECT_EQ(controller.update(loop.t, loop.t, loop.q, fast, torque), bc::ControllerStatus::VelocityLimit);
  EXPECT_EQ(controller.mode(), bc::ControllerMode::Hold);
  EXPECT_EQ(bc::velocityLimitText(Eigen::Vector3d(0.1, -2.5, 0.3), Eigen::Vector3d(2.0, 2.0, 0.5)),
            "joint 2 moved at -2.500000 rad/s, over its velocity limit 2.000000 rad/s");
  EXPECT_EQ(bc::velocityLimitText(fast, Eigen::Vector3d(2.0, 2.0, 2.0)), "");
  // Torques stay within the limits even far from the target.
  EXPECT_LE((torque.cwiseAbs() - loop.model.effortLimits()).maxCoeff(), 1e-12);
  // Time going backwards (a simulation reset: stamps and clock) restarts the controller in hold at the state it is
  // given; an earlier stamp while the clock goes on is a delayed state: stale.
  ASSERT_EQ(controller.setTrajectory(w), bc::TrajectoryStatus::Ok);
  loop.step(controller);
  EXPECT_EQ(controller.mode(), bc::ControllerMode::Track);
  const Eigen::VectorXd q_reset = Eigen::VectorXd::Constant(7, 0.1);
  EXPECT_EQ(controller.update(loop.t, 0.0, q_reset, Eigen::VectorXd::Zero(7), torque),
            bc::ControllerStatus::StaleState);
  EXPECT_EQ(controller.update(0.0, 0.0, q_reset, Eigen::VectorXd::Zero(7), torque), bc::ControllerStatus::Ok);
  EXPECT_EQ(controller.mode(), bc::ControllerMode::Hold);
  EXPECT_LT((controller.desiredPosition() - q_reset).norm(), 1e-15);
}

// A segment handed over with its start state (a reference generator's, TargetFollower's) starts exactly there,
// whatever the controller's own desired state was, and a consistent one (constant acceleration) is followed as it
// is; a bad start state changes nothing.
TEST(ArmController, StartsATrajectoryFromAGivenStateWhenToldTo) {
  ClosedLoop loop;
  bc::ArmController controller(loop.model, noFriction(), ClosedLoop::config());
  for (int k = 0; k < 10; ++k) loop.step(controller);
  const double h = 0.04;
  const Eigen::VectorXd q0 = loop.q + Eigen::VectorXd::Constant(7, 0.01), v = Eigen::VectorXd::Constant(7, 0.2),
                        a = Eigen::VectorXd::Constant(7, -3.0);
  bc::Waypoints w;
  w.times = Eigen::VectorXd::Constant(1, h);
  w.positions = q0 + h * v + (0.5 * h * h) * a;
  w.velocities = v + h * a;
  w.accelerations = a;
  const Eigen::VectorXd wrong = Eigen::VectorXd::Zero(6);
  Eigen::VectorXd nan = q0;
  nan[2] = std::nan("");
  EXPECT_EQ(controller.setTrajectoryFrom(w, wrong, v, a), bc::TrajectoryStatus::WrongSize);
  EXPECT_EQ(controller.setTrajectoryFrom(w, q0, v, wrong), bc::TrajectoryStatus::WrongSize);
  EXPECT_EQ(controller.setTrajectoryFrom(w, nan, v, a), bc::TrajectoryStatus::NotFinite);
  loop.step(controller);
  EXPECT_EQ(controller.mode(), bc::ControllerMode::Hold);
  ASSERT_EQ(controller.setTrajectoryFrom(w, q0, v, a), bc::TrajectoryStatus::Ok);
  loop.step(controller);
  EXPECT_EQ(controller.mode(), bc::ControllerMode::Track);
  EXPECT_LT((controller.desiredPosition() - q0).norm(), 1e-12);
  EXPECT_LT((controller.desiredVelocity() - v).norm(), 1e-12);
  EXPECT_LT((controller.desiredAcceleration() - a).norm(), 1e-12);
  for (int k = 1; k <= 20; ++k) {  // along the segment at its constant acceleration
    loop.step(controller);
    const double t = k * ClosedLoop::kStep;
    EXPECT_LT((controller.desiredVelocity() - (v + t * a)).norm(), 1e-9);
    EXPECT_LT((controller.desiredAcceleration() - a).norm(), 1e-6);
  }
}

TEST(ArmController, ModesAndNoAllocation) {
  ClosedLoop loop;
  bc::ArmController controller(loop.model, noFriction(), ClosedLoop::config());
  bc::Waypoints w;
  w.times = Eigen::Vector2d(0.2, 0.4);
  w.positions.resize(7, 2);
  w.positions.col(0) = loop.q;
  w.positions.col(1) = loop.q;
  NoAllocGuard guard;
  for (int k = 0; k < 10; ++k) loop.step(controller);
  controller.setMode(bc::ControllerMode::GravityCompensation);
  loop.step(controller);
  EXPECT_EQ(controller.mode(), bc::ControllerMode::GravityCompensation);
  EXPECT_EQ(controller.setTrajectory(w), bc::TrajectoryStatus::Ok);
  loop.step(controller);
  EXPECT_EQ(controller.mode(), bc::ControllerMode::Track);
  controller.setMode(bc::ControllerMode::Hold);
  loop.step(controller);
  EXPECT_EQ(controller.mode(), bc::ControllerMode::Hold);
  bc::ControllerMode mode;
  EXPECT_TRUE(bc::modeFromString("gravity_compensation", mode));
  EXPECT_EQ(mode, bc::ControllerMode::GravityCompensation);
  EXPECT_FALSE(bc::modeFromString("dance", mode));
}

TEST(TorqueCommandGate, UsesFreshCommandsAndBrakesOtherwise) {
  bsim::TorqueCommandGate gate(2, 0.05, Eigen::Vector2d(2.0, 1.0));
  Eigen::Vector2d out;
  const Eigen::Vector2d position(0.1, 0.2), velocity(0.5, -1.0), not_a_number(std::nan(""), 0.0);
  const Eigen::Vector3d three_joints = Eigen::Vector3d::Zero();
  NoAllocGuard guard;
  EXPECT_TRUE(gate.torque(0.0, position, velocity, out));  // nothing received yet: brake
  EXPECT_LT((out - Eigen::Vector2d(-1.0, 1.0)).norm(), 1e-15);
  EXPECT_EQ(gate.accept(1.0, Eigen::Vector2d(3.0, 4.0)), bsim::RobotStatus::Ok);
  EXPECT_FALSE(gate.torque(1.04, position, velocity, out));
  EXPECT_LT((out - Eigen::Vector2d(3.0, 4.0)).norm(), 1e-15);
  EXPECT_EQ(gate.accept(1.01, not_a_number), bsim::RobotStatus::InvalidCommand);
  EXPECT_EQ(gate.accept(1.01, three_joints), bsim::RobotStatus::InvalidCommand);
  EXPECT_FALSE(gate.torque(1.04, position, velocity, out));
  EXPECT_LT((out - Eigen::Vector2d(3.0, 4.0)).norm(), 1e-15);  // the rejected commands changed nothing
  EXPECT_TRUE(gate.torque(1.06, position, velocity, out));     // stale: never replayed
  EXPECT_LT((out - Eigen::Vector2d(-1.0, 1.0)).norm(), 1e-15);
}

// A command with a joint impedance: the robot adds K (q_d + q̇_d (t − t_c) − q) + D (q̇_d − q̇) at each of its steps,
// the setpoint moving on at its velocity, until the command is stale; bad impedances are refused and change nothing;
// a torque-only command drops the impedance.
TEST(TorqueCommandGate, ClosesTheCommandsJointImpedanceBetweenCommands) {
  bsim::TorqueCommandGate gate(2, 0.05, Eigen::Vector2d(2.0, 1.0));
  Eigen::Vector2d out;
  const Eigen::Vector2d torque(3.0, 4.0), q_d(1.0, -1.0), qd_d(0.5, 0.0), k(100.0, 10.0), d(5.0, 1.0);
  const Eigen::Vector2d negative(-1.0, 1.0), not_a_number(std::nan(""), 0.0);
  NoAllocGuard guard;
  ASSERT_EQ(gate.accept(1.0, torque, q_d, qd_d, k, d), bsim::RobotStatus::Ok);
  const Eigen::Vector2d q(1.01, -0.9), qd(0.4, 0.2);
  EXPECT_FALSE(gate.torque(1.02, q, qd, out));
  const Eigen::Vector2d expected =
      torque + k.cwiseProduct(q_d + 0.02 * qd_d - q) + d.cwiseProduct(qd_d - qd);  // (4.5, 3.8)
  EXPECT_LT((out - expected).norm(), 1e-12);
  // At the command's own state the impedance adds nothing but its damping of the velocity error.
  EXPECT_FALSE(gate.torque(1.0, q_d, qd_d, out));
  EXPECT_LT((out - torque).norm(), 1e-12);
  EXPECT_EQ(gate.accept(1.01, torque, q_d, qd_d, negative, d), bsim::RobotStatus::InvalidCommand);
  EXPECT_EQ(gate.accept(1.01, torque, not_a_number, qd_d, k, d), bsim::RobotStatus::InvalidCommand);
  EXPECT_FALSE(gate.torque(1.02, q, qd, out));
  EXPECT_LT((out - expected).norm(), 1e-12) << "the refused commands changed nothing";
  EXPECT_TRUE(gate.torque(1.06, q, qd, out));  // stale: braking, no impedance
  EXPECT_LT((out + Eigen::Vector2d(2.0, 1.0).cwiseProduct(qd)).norm(), 1e-15);
  ASSERT_EQ(gate.accept(2.0, torque), bsim::RobotStatus::Ok);
  EXPECT_FALSE(gate.torque(2.01, q, qd, out));
  EXPECT_LT((out - torque).norm(), 1e-15) << "a torque-only command has no impedance";
}

// A command that came late: its setpoint is the one of the state it answers and moves on from that state's stamp,
// not from when the command arrived; a stamp after the arrival or older than the timeout counts from the arrival.
TEST(TorqueCommandGate, MovesTheSetpointOnFromTheStateTheCommandAnswers) {
  bsim::TorqueCommandGate gate(2, 0.05, Eigen::Vector2d(2.0, 1.0));
  Eigen::Vector2d out;
  const Eigen::Vector2d torque(3.0, 4.0), q_d(1.0, -1.0), qd_d(0.5, -0.2), k(100.0, 10.0), d(5.0, 1.0);
  const Eigen::Vector2d q(1.01, -0.9), qd(0.4, 0.2);
  const auto expected = [&](double ahead) {
    return Eigen::Vector2d(torque + k.cwiseProduct(q_d + ahead * qd_d - q) + d.cwiseProduct(qd_d - qd));
  };
  NoAllocGuard guard;
  ASSERT_EQ(gate.accept(1.0, torque, q_d, qd_d, k, d, 0.97), bsim::RobotStatus::Ok);  // answers a state 30 ms old
  EXPECT_FALSE(gate.torque(1.02, q, qd, out));
  EXPECT_LT((out - expected(0.05)).norm(), 1e-12);
  EXPECT_FALSE(gate.torque(1.04, q, qd, out)) << "stale by the arrival, not by the answered stamp";
  EXPECT_LT((out - expected(0.07)).norm(), 1e-12);
  ASSERT_EQ(gate.accept(2.0, torque, q_d, qd_d, k, d, 2.5), bsim::RobotStatus::Ok);  // a stamp ahead of the clock
  EXPECT_FALSE(gate.torque(2.02, q, qd, out));
  EXPECT_LT((out - expected(0.02)).norm(), 1e-12);
  ASSERT_EQ(gate.accept(3.0, torque, q_d, qd_d, k, d, 2.9), bsim::RobotStatus::Ok);  // older than the timeout
  EXPECT_FALSE(gate.torque(3.02, q, qd, out));
  EXPECT_LT((out - expected(0.02)).norm(), 1e-12);
}
