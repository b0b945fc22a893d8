// Global IK: FK -> IK -> FK round trips within limits, determinism, closest/all-solutions modes, bad input,
// unreachable targets, and no allocation during a solve.
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "test_support.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

namespace bk = bimanual_skills::kinematics;
using bimanual_skills::testing::NoAllocGuard;

using bimanual_skills::test_support::randomWithinLimits;
using bimanual_skills::test_support::tipPose;
using bimanual_skills::test_support::wam;

namespace {

double poseErrorMax(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  Eigen::VectorXd e(6);
  bk::poseError(a, b, bk::TaskMode::Pose, e);
  return e.cwiseAbs().maxCoeff();
}

}  // namespace

class GlobalIkRoundTrip : public ::testing::TestWithParam<bk::InverseOperator> {};

TEST_P(GlobalIkRoundTrip, SolvesRandomReachablePosesWithinLimits) {
  const bk::ChainModel model = wam();
  bk::GlobalIkParameters parameters;
  parameters.local.inverse = GetParam();
  parameters.local.limits =
      GetParam() == bk::InverseOperator::ErrorDamping ? bk::LimitScheme::None : bk::LimitScheme::ContinuousTaskPriority;
  parameters.timeout = 1.0;  // generous: this test is about correctness, not speed
  bk::GlobalIkSolver solver(model, parameters);
  std::mt19937 rng(99);
  const Eigen::VectorXd nominal = 0.5 * (model.lowerLimits() + model.upperLimits());
  Eigen::VectorXd q(7);
  for (int sample = 0; sample < 100; ++sample) {
    const Eigen::Isometry3d target = tipPose(model, randomWithinLimits(model, rng));
    const bk::GlobalIkResult result = solver.solve(target, nominal, q);
    ASSERT_EQ(result.status, bk::IkStatus::Converged) << "sample " << sample;
    EXPECT_TRUE(model.withinLimits(q));
    EXPECT_LE(poseErrorMax(tipPose(model, q), target), 1e-5);
  }
}

INSTANTIATE_TEST_SUITE_P(LocalMethods, GlobalIkRoundTrip,
                         ::testing::Values(bk::InverseOperator::SvfSelectiveDamping,
                                           bk::InverseOperator::ErrorDamping));

TEST(GlobalIk, TheDefaultSolvesTheWamAndTwoArmsOfOtherGeometry) {
  // The default configuration (ED restarted within the budget) on the WAM, a 7-joint arm with wrist offsets and
  // asymmetric limits and a 6-joint arm with a spherical wrist, from the mid-limit seed and from random seeds.
  const std::string dir = BIMANUAL_SKILLS_SOURCE_DIR "/urdf/";
  const std::vector<bk::ChainModel> arms = {
      wam(), bk::ChainModel::fromUrdfFile(dir + "test_arms/offset_wrist_arm.urdf", "base_link", "tool"),
      bk::ChainModel::fromUrdfFile(dir + "test_arms/spherical_wrist_arm.urdf", "base_link", "tool")};
  for (const bk::ChainModel& model : arms) {
    bk::GlobalIkParameters parameters;
    parameters.timeout = 0.5;  // correctness, not speed
    EXPECT_EQ(parameters.local.inverse, bk::InverseOperator::ErrorDamping);
    bk::GlobalIkSolver solver(model, parameters);
    std::mt19937 rng(7);
    const Eigen::VectorXd nominal = 0.5 * (model.lowerLimits() + model.upperLimits());
    Eigen::VectorXd q(model.nq());
    for (int sample = 0; sample < 200; ++sample) {
      const Eigen::Isometry3d target = tipPose(model, randomWithinLimits(model, rng));
      const Eigen::VectorXd seed = sample % 2 == 0 ? nominal : randomWithinLimits(model, rng);
      ASSERT_EQ(solver.solve(target, seed, q).status, bk::IkStatus::Converged) << model.nq() << " joints, " << sample;
      EXPECT_TRUE(model.withinLimits(q));
      EXPECT_LE(poseErrorMax(tipPose(model, q), target), 1e-5);
    }
  }
}

TEST(GlobalIk, SameInputsGiveTheSameAnswer) {
  const bk::ChainModel model = wam();
  bk::GlobalIkParameters parameters;
  parameters.local.inverse = bk::InverseOperator::ErrorDamping;
  parameters.local.limits = bk::LimitScheme::None;
  parameters.timeout = 1.0;
  std::mt19937 rng(5);
  const Eigen::Isometry3d target = tipPose(model, randomWithinLimits(model, rng));
  const Eigen::VectorXd seed = Eigen::VectorXd::Constant(7, 2.5);  // outside some limits: forces restarts
  bk::GlobalIkSolver a(model, parameters);
  bk::GlobalIkSolver b(model, parameters);
  Eigen::VectorXd qa(7), qb(7), qa2(7);
  const bk::GlobalIkResult ra = a.solve(target, seed, qa);
  const bk::GlobalIkResult rb = b.solve(target, seed, qb);
  a.solve(target, seed, qa2);
  ASSERT_EQ(ra.status, bk::IkStatus::Converged);
  EXPECT_EQ(ra.attempts, rb.attempts);
  EXPECT_EQ(qa, qb);
  EXPECT_EQ(qa, qa2);
}

TEST(GlobalIk, ClosestToSeedIsNoFartherThanFirstFound) {
  const bk::ChainModel model = wam();
  bk::GlobalIkParameters parameters;
  parameters.local.inverse = bk::InverseOperator::ErrorDamping;
  parameters.local.limits = bk::LimitScheme::None;
  parameters.max_attempts = 200;
  parameters.timeout = 10.0;
  std::mt19937 rng(6);
  const Eigen::Isometry3d target = tipPose(model, randomWithinLimits(model, rng));
  const Eigen::VectorXd seed = randomWithinLimits(model, rng);
  Eigen::VectorXd first(7), closest(7);
  bk::GlobalIkSolver first_solver(model, parameters);
  ASSERT_EQ(first_solver.solve(target, seed, first).status, bk::IkStatus::Converged);
  parameters.mode = bk::SolutionMode::ClosestToSeed;
  bk::GlobalIkSolver closest_solver(model, parameters);
  const bk::GlobalIkResult result = closest_solver.solve(target, seed, closest);
  ASSERT_EQ(result.status, bk::IkStatus::Converged);
  EXPECT_EQ(result.attempts, 200);
  EXPECT_LE((closest - seed).norm(), (first - seed).norm() + 1e-12);
  EXPECT_LE(poseErrorMax(tipPose(model, closest), target), 1e-5);
}

TEST(GlobalIk, AllDistinctFindsSeveralValidSolutions) {
  const bk::ChainModel model = wam();
  bk::GlobalIkParameters parameters;
  parameters.local.inverse = bk::InverseOperator::ErrorDamping;
  parameters.local.limits = bk::LimitScheme::None;
  parameters.mode = bk::SolutionMode::AllDistinct;
  parameters.max_attempts = 100;
  parameters.timeout = 10.0;
  bk::GlobalIkSolver solver(model, parameters);
  const Eigen::VectorXd q_goal = (Eigen::VectorXd(7) << 0.3, 0.5, -0.2, 1.4, 0.2, 0.4, 0.1).finished();
  const Eigen::Isometry3d target = tipPose(model, q_goal);
  Eigen::VectorXd q(7);
  ASSERT_EQ(solver.solve(target, q_goal, q).status, bk::IkStatus::Converged);
  ASSERT_GE(solver.solutionCount(), 5);  // a 7-DoF arm has a continuum of solutions
  for (int i = 0; i < solver.solutionCount(); ++i) {
    EXPECT_TRUE(model.withinLimits(solver.solution(i)));
    EXPECT_LE(poseErrorMax(tipPose(model, solver.solution(i)), target), 1e-5);
    for (int j = 0; j < i; ++j) {
      EXPECT_GE((solver.solution(i) - solver.solution(j)).cwiseAbs().maxCoeff(), parameters.distinct_tolerance);
    }
  }
}

TEST(GlobalIk, UnreachableTargetReturnsTheBestAttempt) {
  const bk::ChainModel model = wam();
  bk::GlobalIkParameters parameters;
  parameters.local.max_iterations = 50;
  parameters.max_attempts = 20;
  parameters.timeout = 10.0;
  bk::GlobalIkSolver solver(model, parameters);
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  target.translation() << 2.0, 0.0, 0.5;
  Eigen::VectorXd q(7);
  const bk::GlobalIkResult result = solver.solve(target, Eigen::VectorXd::Zero(7), q);
  EXPECT_EQ(result.status, bk::IkStatus::MaxIterations);
  EXPECT_EQ(result.attempts, 20);
  EXPECT_GT(result.residual, 0.5);
  EXPECT_TRUE(q.allFinite());
  // The best attempt is reported: its residual is what FK of q gives.
  EXPECT_NEAR(poseErrorMax(tipPose(model, q), target), result.residual, 1e-9);
  parameters.timeout = 1e-4;
  parameters.max_attempts = 1000000;
  bk::GlobalIkSolver quick(model, parameters);
  EXPECT_EQ(quick.solve(target, Eigen::VectorXd::Zero(7), q).status, bk::IkStatus::Timeout);
}

TEST(GlobalIk, BadInputIsAStatus) {
  const bk::ChainModel model = wam();
  bk::GlobalIkSolver solver(model, bk::GlobalIkParameters());
  Eigen::VectorXd q(7);
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  EXPECT_EQ(solver.solve(target, Eigen::VectorXd::Zero(6), q).status, bk::IkStatus::InvalidInput);
  target.linear()(0, 0) = std::nan("");
  EXPECT_EQ(solver.solve(target, Eigen::VectorXd::Zero(7), q).status, bk::IkStatus::InvalidInput);
  bk::GlobalIkParameters bad;
  bad.timeout = 0.0;
  EXPECT_THROW(bk::GlobalIkSolver(model, bad), std::invalid_argument);
}

TEST(GlobalIk, SolveDoesNotAllocate) {
  const bk::ChainModel model = wam();
  for (bk::SolutionMode mode : {bk::SolutionMode::FirstFound, bk::SolutionMode::AllDistinct}) {
    bk::GlobalIkParameters parameters;
    parameters.mode = mode;
    parameters.max_attempts = 5;
    parameters.timeout = 10.0;
    bk::GlobalIkSolver solver(model, parameters);
    std::mt19937 rng(8);
    const Eigen::Isometry3d target = tipPose(model, randomWithinLimits(model, rng));
    const Eigen::VectorXd seed = randomWithinLimits(model, rng);
    Eigen::VectorXd q(7);
    bk::GlobalIkResult result;
    {
      NoAllocGuard guard;
      result = solver.solve(target, seed, q);
    }
    EXPECT_NE(result.status, bk::IkStatus::InvalidInput);
  }
}
