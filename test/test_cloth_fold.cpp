// The cloth-folding task on the simulated WAMs: the demonstration folds the cloth, rollouts are repeatable, the
// policy's goal weights move where the fold ends, bad or wild policies end with a reason instead of a crash; the
// fold quality's ground truth; the camera's fold reward ranks hand-made folds as their quality does.
#include "bimanual_skills/tasks/cloth_fold.hpp"
#include "bimanual_skills/tasks/fold_quality.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "bimanual_skills/vision/synthetic_cloth.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace bt = bimanual_skills::tasks;

namespace {

bt::ClothFoldConfig config() {
  bt::ClothFoldConfig c;
  c.sim_config = BIMANUAL_SKILLS_SOURCE_DIR "/config/sim.yaml";
  c.duration = 3.0;
  c.settle = 0.7;
  c.friction_files = {"", ""};  // no friction compensation (the robot file's models otherwise)
  return c;
}

/// Fraction of the far half's nodes (rest x beyond the centre) that ended over the near half, above the bottom layer.
double foldedFraction(const bt::FoldRollout& r, double centre_x, double table_top) {
  int far = 0, folded = 0;
  for (Eigen::Index i = 0; i < r.cloth_vertices.cols(); ++i) {
    if (r.cloth_rest_vertices(0, i) < centre_x + 0.05) continue;
    ++far;
    folded += r.cloth_vertices(0, i) < centre_x && r.cloth_vertices(2, i) > table_top + 0.006;
  }
  return far > 0 ? static_cast<double>(folded) / far : 0.0;
}

}  // namespace

TEST(ClothFold, TheDemonstrationFoldsTheClothRepeatably) {
  bt::ClothFoldTask task(config());
  EXPECT_EQ(task.parameterCount(), 12 * 21);  // 20 kernels' weights and the goal's per DoF
  bt::ClothFoldConfig weights_only = config();
  weights_only.policy = bt::FoldPolicy::Weights;
  EXPECT_EQ(bt::ClothFoldTask(weights_only).parameterCount(), 12 * 20);
  const Eigen::VectorXd theta = task.demonstrationParameters();
  const bt::FoldRollout first = task.run(theta);
  ASSERT_EQ(first.outcome, bt::FoldOutcome::Ok) << first.reason;
  EXPECT_GT(first.grasped_nodes[0], 0);
  EXPECT_GT(first.grasped_nodes[1], 0);
  EXPECT_LT(first.max_ik_error, 0.01);
  EXPECT_LT(first.max_tracking_error, 0.1);
  const double fraction = foldedFraction(first, 0.5, 0.15);
  std::printf(
      "demonstration: %.2f s simulated in %.2f s (%.1fx), IK error %.4f m, tracking %.4f rad, "
      "acceleration cost %.1f, folded %.0f %%, fold quality %.3f (distance %.4f m, displacement %.4f m)\n",
      first.simulated_seconds, first.wall_seconds, first.simulated_seconds / first.wall_seconds, first.max_ik_error,
      first.max_tracking_error, first.acceleration_cost, 100.0 * fraction, first.fold.q, first.fold.distance,
      first.fold.displacement);
  EXPECT_GT(first.fold.q, 0.3);  // the demonstration folds, imperfectly
  EXPECT_GT(fraction, 0.5);
  ASSERT_EQ(first.commanded_path.size(), 2u);
  EXPECT_GT(first.commanded_path[0].cols(), 100);
  // Same policy, same rollout, bit for bit.
  const bt::FoldRollout second = task.run(theta);
  ASSERT_EQ(second.outcome, bt::FoldOutcome::Ok);
  EXPECT_EQ((first.cloth_vertices - second.cloth_vertices).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(first.acceleration_cost, second.acceleration_cost);
}

// A robot whose camera sees the arms takes its images once they are out of its view; image_delay puts the
// in-process images at the same moment: q is still the cloth's at the settle time (to the bit), the reward's images
// show the cloth image_delay later, slid on.
TEST(ClothFold, TheImagesComeImageDelayAfterTheSettleTimeAndQStaysTheSettledCloths) {
  bt::ClothFoldTask task(config());
  bt::ClothFoldConfig delayed_config = config();
  delayed_config.image_delay = 2.0;
  bt::ClothFoldTask delayed(delayed_config);
  const bt::FoldRollout now = task.run(task.demonstrationParameters()),
                        later = delayed.run(delayed.demonstrationParameters());
  ASSERT_EQ(now.outcome, bt::FoldOutcome::Ok) << now.reason;
  ASSERT_EQ(later.outcome, bt::FoldOutcome::Ok) << later.reason;
  EXPECT_EQ(later.cloth_vertices, now.cloth_vertices);
  EXPECT_EQ(later.fold.q, now.fold.q);
  EXPECT_EQ(now.cloth_image_vertices.cols(), 0);
  ASSERT_EQ(later.cloth_image_vertices.cols(), now.cloth_vertices.cols());
  const double slid = (later.cloth_image_vertices - later.cloth_vertices).colwise().norm().maxCoeff();
  std::printf("the cloth 2 s after the settle time: nodes moved up to %.1f mm; q %.3f at the settle time, %.3f then\n",
              1e3 * slid, later.fold.q, delayed.foldQualityOf(later.cloth_image_vertices).q);
  EXPECT_GT(slid, 1e-3) << "the cloth is still sliding after the settle time";
  EXPECT_NEAR(later.simulated_seconds - now.simulated_seconds, 2.0, 1e-9);
  // The reward scores the later mesh: as if it were the rollout's only one.
  bt::FoldRewardConfig reward_config = bt::rewardSetting({}, "fold", "test");
  reward_config.renderer = bt::rendererFor(delayed.simConfig());
  const auto evaluate = [&](const bt::FoldRollout& rollout) {
    bt::FoldReward reward(reward_config, 0.3, delayed.idealFoldVertices(), delayed.clothTriangles());
    std::mt19937 rng(5);
    return reward.evaluate(rollout, rng);
  };
  bt::FoldRollout as_final = later;
  as_final.cloth_vertices = later.cloth_image_vertices;
  as_final.cloth_image_vertices.resize(3, 0);
  EXPECT_EQ(evaluate(later).r_fold, evaluate(as_final).r_fold);
  EXPECT_EQ(evaluate(later).mean_gradient, evaluate(as_final).mean_gradient);
  EXPECT_NE(evaluate(later).mean_gradient, evaluate(now).mean_gradient);
  bt::ClothFoldConfig bad = config();
  bad.image_delay = -1.0;
  EXPECT_THROW(bt::ClothFoldTask{bad}, std::invalid_argument);
}

TEST(ClothFold, ThePlanHoldsTheReferencesTheRolloutFollows) {
  bt::ClothFoldTask task(config());
  const std::vector<Eigen::MatrixXd> identity{
      Eigen::MatrixXd::Identity(bt::ClothFoldTask::kDofs, bt::ClothFoldTask::kDofs)};
  const bt::FoldPlan plan = task.plan(identity, task.demonstrationParameters());
  ASSERT_EQ(plan.outcome, bt::FoldOutcome::Ok) << plan.reason;
  const bt::FoldRollout rollout = task.run(identity, task.demonstrationParameters());
  ASSERT_EQ(rollout.outcome, bt::FoldOutcome::Ok) << rollout.reason;
  // Open-loop references: the same acceleration cost and IK error as the simulated rollout, bit for bit.
  EXPECT_EQ(plan.acceleration_cost, rollout.acceleration_cost);
  EXPECT_EQ(plan.max_ik_error, rollout.max_ik_error);
  ASSERT_EQ(plan.position.size(), 2u);
  const Eigen::Index periods = plan.position[0].cols();
  EXPECT_EQ(periods, static_cast<Eigen::Index>(std::lround(rollout.simulated_seconds / plan.dt)));
  EXPECT_GT(plan.release, plan.move_start);
  for (int arm = 0; arm < 2; ++arm) {
    // Starts at the start configuration, and the arm tracked it to the end (the measured joints at the last sample).
    EXPECT_LT((plan.position[arm].col(0) - task.startPositions()[arm]).cwiseAbs().maxCoeff(), 1e-3);
    const Eigen::MatrixXd& measured = rollout.joint_path[static_cast<std::size_t>(arm)];
    EXPECT_LT((plan.position[arm].col(periods - 1) - measured.col(measured.cols() - 1)).cwiseAbs().maxCoeff(), 0.05);
    // Velocities are the references' differences.
    const Eigen::Index k = plan.move_start + 500;
    EXPECT_NEAR((plan.position[arm].col(k) - plan.position[arm].col(k - 1)).norm() / plan.dt,
                plan.velocity[arm].col(k).norm(), 1e-9);
  }
  // The ground truth of a mesh, as the rollout computed it.
  EXPECT_EQ(task.foldQualityOf(rollout.cloth_vertices).q, rollout.fold.q);
  Eigen::VectorXd theta = task.demonstrationParameters();
  theta[3] = std::nan("");
  EXPECT_EQ(task.plan(identity, theta).outcome, bt::FoldOutcome::InvalidPolicy);
}

TEST(ClothFold, ParametersRoundTrip) {
  bt::ClothFoldTask task(config());
  const auto dmps = task.dmps(task.demonstrationParameters());
  for (int arm = 0; arm < 2; ++arm) {
    EXPECT_EQ(dmps[arm].positionWeights(), task.demonstration()[arm].positionWeights());
    EXPECT_EQ(dmps[arm].orientationWeights(), task.demonstration()[arm].orientationWeights());
    EXPECT_EQ(dmps[arm].goal().position, task.demonstration()[arm].goal().position);
  }
  EXPECT_THROW(task.dmps(Eigen::VectorXd::Zero(3)), std::invalid_argument);
}

// A policy's goal weights move where the tools end, and so the release and the fold: the left tool's goal moved
// 4 cm towards the near edge (x) and the right one's 3 cm up (z) end there, the DMPs of dmps() have those goals, and
// the fold differs.
TEST(ClothFold, GoalWeightsMoveWhereTheToolsEndAndTheFold) {
  bt::ClothFoldTask task(config());
  const int n = task.policyBasisSize(), k = task.config().kernels;
  ASSERT_EQ(n, k + 1);
  Eigen::VectorXd theta = task.demonstrationParameters();
  const double forcing_per_metre = task.dmpParameters().alpha_z * task.dmpParameters().beta_z;
  theta[0 * n + k] = -0.04 * forcing_per_metre;  // left arm, position x
  theta[8 * n + k] = 0.03 * forcing_per_metre;   // right arm, position z
  const bt::FoldRollout base = task.run(task.demonstrationParameters());
  const bt::FoldRollout moved = task.run(theta);
  ASSERT_EQ(base.outcome, bt::FoldOutcome::Ok) << base.reason;
  ASSERT_EQ(moved.outcome, bt::FoldOutcome::Ok) << moved.reason;
  // The commanded tool positions at the end of the movement (before the release), sampled at path_rate.
  const auto at_release = [&](const bt::FoldRollout& r, int arm) {
    const double t = task.config().hold_before + task.config().duration + 0.5 * task.config().hold_after;
    Eigen::Index i = 0;
    while (i + 1 < r.path_times.size() && r.path_times[i] < t) ++i;
    return Eigen::Vector3d(r.commanded_path[static_cast<std::size_t>(arm)].col(i));
  };
  const Eigen::Vector3d left = at_release(moved, 0) - at_release(base, 0);
  const Eigen::Vector3d right = at_release(moved, 1) - at_release(base, 1);
  EXPECT_NEAR(left.x(), -0.04, 0.005);
  EXPECT_NEAR(left.z(), 0.0, 0.005);
  EXPECT_NEAR(right.z(), 0.03, 0.005);
  EXPECT_NEAR(right.x(), 0.0, 0.005);
  const auto dmps = task.dmps(theta);
  EXPECT_NEAR((dmps[0].goal().position - task.demonstration()[0].goal().position).x(), -0.04, 1e-12);
  EXPECT_NEAR((dmps[1].goal().position - task.demonstration()[1].goal().position).z(), 0.03, 1e-12);
  std::printf("fold quality %.3f with the demonstration's goals, %.3f with the moved ones\n", base.fold.q,
              moved.fold.q);
  EXPECT_GT(std::abs(moved.fold.q - base.fold.q), 0.02);
}

TEST(ClothFold, BadAndWildPoliciesEndWithAReason) {
  bt::ClothFoldTask task(config());
  Eigen::VectorXd theta = task.demonstrationParameters();
  theta[17] = std::nan("");
  EXPECT_EQ(task.run(theta).outcome, bt::FoldOutcome::InvalidPolicy);
  EXPECT_EQ(task.run(Eigen::VectorXd::Zero(5)).outcome, bt::FoldOutcome::InvalidPolicy);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 3e4);
  theta = task.demonstrationParameters();
  for (Eigen::Index i = 0; i < theta.size(); ++i) theta[i] += noise(rng);
  const bt::FoldRollout wild = task.run(theta);
  EXPECT_NE(wild.outcome, bt::FoldOutcome::Ok);
  EXPECT_FALSE(wild.reason.empty());
  std::printf("wild policy: %s: %s\n", bt::toString(wild.outcome), wild.reason.c_str());
  // The task is usable again afterwards.
  EXPECT_EQ(task.run(task.demonstrationParameters()).outcome, bt::FoldOutcome::Ok);
}

// A stepped rollout (a step-by-step policy at the control rate) that streams the plan's velocities as its
// references follows the plan's positions and folds the cloth as run() does: the same simulation, noise, grasp,
// release and controllers, the references a period apart as one-waypoint trajectories instead of one spline.
TEST(ClothFold, ASteppedRolloutThatStreamsThePlanFoldsAsRunDoes) {
  bt::ClothFoldConfig c = config();
  c.noise = bt::foldNoiseSetting("robot", "test");
  bt::ClothFoldTask task(c);
  const std::vector<Eigen::MatrixXd> identity{
      Eigen::MatrixXd::Identity(bt::ClothFoldTask::kDofs, bt::ClothFoldTask::kDofs)};
  const bt::FoldPlan plan = task.plan(identity, task.demonstrationParameters());
  ASSERT_EQ(plan.outcome, bt::FoldOutcome::Ok);
  const bt::FoldRollout reference = task.run(identity, task.demonstrationParameters(), 5);
  ASSERT_EQ(reference.outcome, bt::FoldOutcome::Ok);
  EXPECT_THROW((void)task.step(Eigen::VectorXd::Zero(14)), std::logic_error);  // no stepped rollout yet
  ASSERT_EQ(task.beginSteps(5), bt::FoldOutcome::Ok);
  EXPECT_EQ(task.steppedPeriods(), plan.release);
  EXPECT_TRUE(task.stepping());
  Eigen::VectorXd velocity(14);
  double reference_error = 0.0;
  for (int k = 0; k < task.steppedPeriods(); ++k) {
    velocity << plan.velocity[0].col(k + 1), plan.velocity[1].col(k + 1);
    ASSERT_EQ(task.step(velocity), bt::FoldOutcome::Ok) << "period " << k;
    for (int arm = 0; arm < 2; ++arm) {
      reference_error = std::max(
          reference_error,
          (task.steppedReference(arm) - plan.position[static_cast<std::size_t>(arm)].col(k + 1)).cwiseAbs().maxCoeff());
    }
  }
  EXPECT_FALSE(task.stepping());
  EXPECT_THROW((void)task.step(velocity), std::logic_error);  // its driven periods are over
  const bt::FoldRollout stepped = task.finishSteps();
  ASSERT_EQ(stepped.outcome, bt::FoldOutcome::Ok) << stepped.reason;
  const double cloth = (stepped.cloth_vertices - reference.cloth_vertices).colwise().norm().maxCoeff();
  std::printf(
      "stepped: q %.4f (run %.4f), cloth within %.2e m, references within %.1e rad, acceleration cost %.1f "
      "(run %.1f), tracking %.4f rad (run %.4f), %.2f s simulated in %.2f s\n",
      stepped.fold.q, reference.fold.q, cloth, reference_error, stepped.acceleration_cost, reference.acceleration_cost,
      stepped.max_tracking_error, reference.max_tracking_error, stepped.simulated_seconds, stepped.wall_seconds);
  EXPECT_LT(reference_error, 1e-7);  // q + (Δq / dt) dt, rounded period by period
  EXPECT_EQ(stepped.simulated_seconds, reference.simulated_seconds);
  EXPECT_EQ(stepped.path_times.size(), reference.path_times.size());
  EXPECT_NEAR(stepped.fold.q, reference.fold.q, 0.01);
  EXPECT_LT(cloth, 0.005);
  EXPECT_NEAR(stepped.acceleration_cost, reference.acceleration_cost, 0.05 * reference.acceleration_cost);
  EXPECT_NEAR(stepped.max_tracking_error, reference.max_tracking_error, 0.01);
  // The same seed and references, the same rollout, bit for bit.
  ASSERT_EQ(task.beginSteps(5), bt::FoldOutcome::Ok);
  for (int k = 0; k < task.steppedPeriods(); ++k) {
    velocity << plan.velocity[0].col(k + 1), plan.velocity[1].col(k + 1);
    ASSERT_EQ(task.step(velocity), bt::FoldOutcome::Ok);
  }
  EXPECT_EQ((task.finishSteps().cloth_vertices - stepped.cloth_vertices).cwiseAbs().maxCoeff(), 0.0);
}

// Bad steps end the stepped rollout with the reason (never a crash); a reference pushed against a joint's limit
// stops at it; finishSteps() early holds the arms through the rest; run() ends a stepped rollout.
TEST(ClothFold, BadStepsEndASteppedRolloutWithAReason) {
  bt::ClothFoldTask task(config());
  ASSERT_EQ(task.beginSteps(1), bt::FoldOutcome::Ok);
  Eigen::VectorXd velocity = Eigen::VectorXd::Zero(14);
  ASSERT_EQ(task.step(velocity), bt::FoldOutcome::Ok);
  velocity[3] = std::nan("");
  EXPECT_EQ(task.step(velocity), bt::FoldOutcome::InvalidPolicy);
  EXPECT_EQ(task.step(Eigen::VectorXd::Zero(14)), bt::FoldOutcome::InvalidPolicy);  // it ended
  bt::FoldRollout ended = task.finishSteps();
  EXPECT_EQ(ended.outcome, bt::FoldOutcome::InvalidPolicy);
  EXPECT_NE(ended.reason.find("NaN"), std::string::npos) << ended.reason;
  EXPECT_THROW((void)task.finishSteps(), std::logic_error);

  ASSERT_EQ(task.beginSteps(1), bt::FoldOutcome::Ok);
  EXPECT_EQ(task.step(Eigen::VectorXd::Zero(13)), bt::FoldOutcome::InvalidPolicy);
  (void)task.finishSteps();
  ASSERT_EQ(task.beginSteps(1), bt::FoldOutcome::Ok);
  velocity.setZero();
  velocity[8] = 100.0;  // the right arm's joint 2, beyond any WAM's velocity limit
  EXPECT_EQ(task.step(velocity), bt::FoldOutcome::OutOfLimits);
  ended = task.finishSteps();
  EXPECT_NE(ended.reason.find("joint 2 leaves its limits: velocity 100"), std::string::npos) << ended.reason;

  // The left arm's wrist roll (joint 7: it turns the gripper about its axis) driven towards its upper limit: the
  // reference slows and stops at the limit and stays.
  const Eigen::VectorXd upper = task.armModel(0).upperLimits(), limit = task.armModel(0).velocityLimits();
  const Eigen::Index joint = 6;
  ASSERT_EQ(task.beginSteps(1), bt::FoldOutcome::Ok);
  velocity.setZero();
  velocity[joint] = 0.9 * limit[joint];
  int at_limit = 0;
  while (task.stepping() && task.step(velocity) == bt::FoldOutcome::Ok) {
    const double q = task.steppedReference(0)[joint];
    ASSERT_LE(q, upper[joint]);
    at_limit += q == upper[joint];
  }
  ended = task.finishSteps();
  std::printf("joint %d driven to its limit %.3f rad: %d periods there, %s %s\n", static_cast<int>(joint) + 1,
              upper[joint], at_limit, bt::toString(ended.outcome), ended.reason.c_str());
  EXPECT_GT(at_limit, 100);
  // run() ends a stepped rollout in progress.
  ASSERT_EQ(task.beginSteps(1), bt::FoldOutcome::Ok);
  EXPECT_EQ(task.run(task.demonstrationParameters()).outcome, bt::FoldOutcome::Ok);
  EXPECT_FALSE(task.stepping());
  EXPECT_THROW((void)task.step(Eigen::VectorXd::Zero(14)), std::logic_error);
}

// References a robot would be sent are checked against the URDF's limits as they are made, in the plan the ROS
// backend sends and in the rollout the simulation runs alike: the demonstration squeezed into 0.25 s asks for joint
// speeds beyond the WAM's limits.
TEST(ClothFold, ReferencesBeyondTheJointLimitsFailInBothBackendsAlike) {
  bt::ClothFoldConfig c = config();
  c.duration = 0.25;
  c.max_ik_error = 1.0;  // the CLIK may lag: the speed is what is checked here
  bt::ClothFoldTask task(c);
  const std::vector<Eigen::MatrixXd> identity{
      Eigen::MatrixXd::Identity(bt::ClothFoldTask::kDofs, bt::ClothFoldTask::kDofs)};
  const bt::FoldPlan plan = task.plan(identity, task.demonstrationParameters());
  const bt::FoldRollout rollout = task.run(identity, task.demonstrationParameters());
  std::printf("plan: %s: %s\nrollout: %s: %s\n", bt::toString(plan.outcome), plan.reason.c_str(),
              bt::toString(rollout.outcome), rollout.reason.c_str());
  EXPECT_EQ(plan.outcome, bt::FoldOutcome::OutOfLimits);
  EXPECT_EQ(rollout.outcome, bt::FoldOutcome::OutOfLimits);
  EXPECT_NE(plan.reason.find("velocity"), std::string::npos) << plan.reason;
  EXPECT_EQ(plan.reason, rollout.reason);
  EXPECT_EQ(bt::foldOutcomeFromString("OutOfLimits", "test"), bt::FoldOutcome::OutOfLimits);
}

// The rollout's arms are driven by the robot path's controller (control::ArmController, as ctc_controller runs it):
// its velocity monitor stops a rollout whose arm moves faster than the limit, as it would stop the robot, and the
// rollout says so; with the robot's own limits the demonstration runs.
TEST(ClothFold, TheRobotPathsVelocityMonitorStopsARolloutThatMovesTooFast) {
  bt::ClothFoldConfig c = config();
  c.velocity_limit = Eigen::VectorXd::Constant(1, 0.1);
  bt::ClothFoldTask slow(c);
  const bt::FoldRollout stopped = slow.run(slow.demonstrationParameters());
  std::printf("limit 0.1 rad/s: %s: %s\n", bt::toString(stopped.outcome), stopped.reason.c_str());
  EXPECT_EQ(stopped.outcome, bt::FoldOutcome::ControllerFailed);
  EXPECT_NE(stopped.reason.find("over its velocity limit 0.1"), std::string::npos) << stopped.reason;
  c.velocity_limit = Eigen::VectorXd::Constant(3, 1.0);
  EXPECT_THROW(bt::ClothFoldTask{c}, std::invalid_argument);
  c.velocity_limit = Eigen::VectorXd::Constant(1, -1.0);
  EXPECT_THROW(bt::ClothFoldTask{c}, std::invalid_argument);
}

TEST(ClothFold, BadConfiguration) {
  bt::ClothFoldConfig c = config();
  c.ik_method = "XYZ";
  EXPECT_THROW(bt::ClothFoldTask{c}, std::invalid_argument);
  c = config();
  c.duration = 0.0;
  EXPECT_THROW(bt::ClothFoldTask{c}, std::invalid_argument);
  c = config();
  c.sim_config = "/nonexistent.yaml";
  EXPECT_THROW(bt::ClothFoldTask{c}, std::invalid_argument);
}

// The robot's noise (FoldNoise): drawn from the rollout's seed (the same seed, the same rollout; another seed, another
// draw), the cloth laid where the draw says (its rest mesh shifted and turned by it), each cut at 3 σ; none by default.
TEST(ClothFold, TheRobotsNoiseMovesTheClothAndTheReleaseByTheSeedsDraw) {
  const bt::FoldNoise robot = bt::foldNoiseSetting("robot", "test");
  EXPECT_EQ(robot.setting, "robot");
  EXPECT_TRUE(robot.any());
  EXPECT_FALSE(bt::foldNoiseSetting("none", "test").any());
  EXPECT_THROW(bt::foldNoiseSetting("loud", "test"), std::invalid_argument);
  for (std::uint32_t seed = 0; seed < 200; ++seed) {
    const bt::FoldNoiseDraw d = bt::drawFoldNoise(robot, seed);
    ASSERT_LE(std::abs(d.cloth_x), 3.0 * robot.cloth_position);
    ASSERT_LE(std::abs(d.cloth_yaw), 3.0 * robot.cloth_yaw);
    ASSERT_LE(std::abs(d.release[1]), 3.0 * robot.release_time);
  }
  EXPECT_NE(bt::drawFoldNoise(robot, 1).cloth_x, bt::drawFoldNoise(robot, 2).cloth_x);
  EXPECT_EQ(bt::drawFoldNoise(bt::FoldNoise{}, 1).cloth_y, 0.0);

  bt::ClothFoldConfig c = config();
  bt::ClothFoldTask quiet(c);
  c.noise = robot;
  bt::ClothFoldTask noisy(c);
  const std::vector<Eigen::MatrixXd> identity{Eigen::MatrixXd::Identity(12, 12)};
  const Eigen::VectorXd theta = noisy.demonstrationParameters();
  const bt::FoldRollout a = noisy.run(identity, theta, 7u), b = noisy.run(identity, theta, 7u);
  const bt::FoldRollout other = noisy.run(identity, theta, 8u), plain = quiet.run(identity, theta, 7u);
  ASSERT_EQ(a.outcome, bt::FoldOutcome::Ok) << a.reason;
  ASSERT_EQ(other.outcome, bt::FoldOutcome::Ok) << other.reason;
  EXPECT_EQ(a.fold.q, b.fold.q);
  EXPECT_NE(a.fold.q, other.fold.q);
  EXPECT_EQ(plain.noise.cloth_x, 0.0);
  // The rest mesh is the plain one turned by the yaw about the cloth's centre, then shifted.
  const bt::FoldNoiseDraw& d = a.noise;
  EXPECT_EQ(d.cloth_x, bt::drawFoldNoise(robot, 7u).cloth_x);
  const Eigen::Vector3d centre = plain.cloth_rest_vertices.rowwise().mean();
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(d.cloth_yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  double worst = 0.0;
  for (Eigen::Index i = 0; i < a.cloth_rest_vertices.cols(); ++i) {
    const Eigen::Vector3d expected =
        centre + turn * (plain.cloth_rest_vertices.col(i) - centre) + Eigen::Vector3d(d.cloth_x, d.cloth_y, 0.0);
    worst = std::max(worst, (a.cloth_rest_vertices.col(i) - expected).norm());
  }
  EXPECT_LT(worst, 1e-9);
  EXPECT_NE(a.fold.q, plain.fold.q);
  // clothStartVertices(seed), before that rollout, is where the simulation then lays the cloth; without noise, the
  // file's placement for every seed.
  const Eigen::Matrix3Xd predicted = noisy.clothStartVertices(8u);
  ASSERT_EQ(predicted.cols(), other.cloth_rest_vertices.cols());
  EXPECT_LT((predicted - other.cloth_rest_vertices).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_GT((predicted - noisy.clothStartVertices(7u)).cwiseAbs().maxCoeff(), 1e-4);
  EXPECT_EQ((quiet.clothStartVertices(8u) - plain.cloth_rest_vertices).cwiseAbs().maxCoeff(), 0.0);

  bt::FoldNoise bad = robot;
  bad.release_time = -0.01;
  EXPECT_THROW(bad.validate("test"), std::invalid_argument);
  bad = robot;
  bad.cloth_position = 0.5;
  c.noise = bad;
  EXPECT_THROW(bt::ClothFoldTask{c}, std::invalid_argument);
}

namespace {

/// A flat nodes_x × nodes_y patch of `length` × `width` at z = 0, node (i, j) at column j·nodes_x + i.
Eigen::Matrix3Xd flatPatch(int nodes_x, int nodes_y, double length, double width) {
  Eigen::Matrix3Xd p(3, nodes_x * nodes_y);
  for (int j = 0; j < nodes_y; ++j) {
    for (int i = 0; i < nodes_x; ++i) {
      p.col(j * nodes_x + i) << length * (i / (nodes_x - 1.0) - 0.5), width * (j / (nodes_y - 1.0) - 0.5), 0.0;
    }
  }
  return p;
}

}  // namespace

// The fold quality is 1 for the ideal fold (the far half laid onto the near half, one thickness above it), 0 for the
// flat cloth at rest, in between for a half fold (the far half standing up), and it is lowered by moving the half
// that should stay.
TEST(FoldQuality, IdealFoldFlatClothAndInBetween) {
  const int nx = 20, ny = 24;
  const double thickness = 0.004;
  const Eigen::Matrix3Xd rest = flatPatch(nx, ny, 0.5, 0.6);
  const bt::FoldQuality flat = bt::foldQuality(rest, rest, nx, ny, thickness);
  EXPECT_NEAR(flat.q, 0.0, 1e-12);
  EXPECT_NEAR(flat.displacement, 0.0, 1e-12);
  EXPECT_NEAR(flat.distance, 0.5 * 10.0 / 19.0, 1e-12);  // mirror pairs 1, 3, …, 19 node spacings of 0.5/19 m

  Eigen::Matrix3Xd ideal = rest, standing = rest, dragged = rest;
  for (int j = 0; j < ny; ++j) {
    for (int i = nx / 2; i < nx; ++i) {
      const Eigen::Vector3d mirror = rest.col(j * nx + (nx - 1 - i));
      ideal.col(j * nx + i) = mirror + Eigen::Vector3d(0.0, 0.0, thickness);
      const double x = rest(0, j * nx + i);
      standing.col(j * nx + i) << 0.0, rest(1, j * nx + i), x;  // turned up about the fold line
    }
    for (int i = 0; i < nx / 2; ++i) dragged.col(j * nx + i) += Eigen::Vector3d(0.05, 0.0, 0.0);
  }
  const bt::FoldQuality folded = bt::foldQuality(ideal, rest, nx, ny, thickness);
  EXPECT_NEAR(folded.q, 1.0, 1e-12);
  EXPECT_NEAR(folded.distance, thickness, 1e-12);
  const bt::FoldQuality half = bt::foldQuality(standing, rest, nx, ny, thickness);
  EXPECT_GT(half.q, 0.2);
  EXPECT_LT(half.q, 0.8);
  const bt::FoldQuality moved = bt::foldQuality(dragged, rest, nx, ny, thickness);
  EXPECT_LT(moved.q, flat.q);
  EXPECT_NEAR(moved.displacement, 0.05, 1e-12);

  EXPECT_THROW(bt::foldQuality(rest, rest, 19, ny, thickness), std::invalid_argument);  // sizes
  EXPECT_THROW(bt::foldQuality(rest, rest, nx, ny, 0.0), std::invalid_argument);

  // idealFold() builds the same mesh, whichever way the rest patch's normal points.
  EXPECT_TRUE(bt::idealFold(rest, nx, ny, thickness).isApprox(ideal, 1e-15));
  Eigen::Matrix3Xd mirrored_rest = rest;
  for (int j = 0; j < ny; ++j) mirrored_rest.col(j * nx).swap(mirrored_rest.col(j * nx + 1));  // flips the normal
  EXPECT_GT(bt::idealFold(mirrored_rest, nx, ny, thickness).row(2).maxCoeff(), rest.row(2).maxCoeff());
  EXPECT_THROW(bt::idealFold(rest.leftCols(nx), nx, 1, thickness), std::invalid_argument);
}

// The camera's fold reward ranks a hand-made set of folds as their fold quality q does: the cloth left flat, folded
// along lines 12 and 6 cm beyond its middle (the top layer short of the near edge), folded in the middle and
// dragged 4 cm, folded 2 cm beyond the middle, folded in the middle (the ideal), each rendered with sensor noise
// against the flat cloth's own noisy image.
TEST(FoldReward, RanksHandMadeFoldsAsTheirQuality) {
  namespace bv = bimanual_skills::vision;
  const double table = 0.15, thickness = 0.004;
  const bv::ClothMesh flat = bv::flatCloth(0.5, 0.6, 20, 24, Eigen::Vector3d(0.5, 0.0, table + thickness));
  bt::FoldRewardConfig config = bt::rewardSetting({}, "fold", "test");
  config.renderer.camera = bv::TopDownCamera::covering(320, 240, 1.0, Eigen::Vector2d(0.5, 0.0), table + 1.5);
  config.renderer.table.height = table;
  const Eigen::Matrix3Xd ideal = bt::idealFold(flat.vertices, 20, 24, thickness);
  bt::FoldReward reward(config, 0.3, ideal, flat.triangles);
  std::vector<std::pair<std::string, Eigen::Matrix3Xd>> folds = {{"flat", flat.vertices}};
  const auto folded = [&](double beyond) { return bv::foldCloth(flat, 0.5 + beyond, 0.5 * thickness).vertices; };
  folds.emplace_back("fold line 12 cm out", folded(0.12));
  folds.emplace_back("fold line 6 cm out", folded(0.06));
  Eigen::Matrix3Xd dragged = folded(0.0);
  dragged.row(0).array() -= 0.04;
  folds.emplace_back("dragged 4 cm", dragged);
  folds.emplace_back("fold line 2 cm out", folded(0.02));
  folds.emplace_back("ideal", folded(0.0));
  std::vector<double> q, r;
  std::mt19937 rng(4);
  for (const auto& [name, vertices] : folds) {
    bt::FoldRollout rollout;
    rollout.cloth_vertices = vertices;
    rollout.cloth_triangles = flat.triangles;
    rollout.cloth_rest_vertices = flat.vertices;
    rollout.fold = bt::foldQuality(vertices, flat.vertices, 20, 24, thickness);
    const bt::FoldRewardTerms terms = reward.evaluate(rollout, rng);
    std::printf("%-22s q %6.3f  reward %7.4f  (edge %.3f, single %.3f, length %.3f m)\n", name.c_str(), rollout.fold.q,
                terms.reward, terms.fold_edge, terms.fold_single, terms.fold_length);
    q.push_back(rollout.fold.q);
    r.push_back(terms.reward);
  }
  for (std::size_t i = 1; i < q.size(); ++i) {
    ASSERT_GT(q[i], q[i - 1]) << folds[i].first << ": the set is not in order of q";
    EXPECT_GT(r[i], r[i - 1]) << folds[i].first << " does not score above " << folds[i - 1].first;
  }
  EXPECT_NEAR(r.front(), -1.0, 0.05);  // the flat cloth: mismatch 1
  EXPECT_GT(r.back(), -0.1);           // the ideal fold: mismatch near 0 (the crease and the noise)
}
