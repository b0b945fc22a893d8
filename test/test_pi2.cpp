// PI2 (thesis 5.8–5.13) and PI2-CMA: equal costs leave the rollouts equally likely; a rollout best at every step
// takes the probability mass; a one-hot basis gives the literal time-weighted average of (5.12); the via-point
// task is learned; the adapted covariance stays positive definite and shrinks; bad input throws.
#include "bimanual_skills/learning/gaussian.hpp"
#include "bimanual_skills/learning/pi2.hpp"
#include "bimanual_skills/tasks/policy_search_tasks.hpp"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>

#include <cmath>
#include <random>

namespace bl = bimanual_skills::learning;
namespace bt = bimanual_skills::tasks;

TEST(Pi2, EqualCostsGiveUniformProbabilities) {
  const Eigen::MatrixXd basis = Eigen::MatrixXd::Random(20, 4).cwiseAbs();
  const Eigen::VectorXd mean = Eigen::VectorXd::Zero(8);
  const Eigen::MatrixXd samples = Eigen::MatrixXd::Random(6, 8);
  const bl::Pi2Update u =
      bl::pi2Update({}, mean, Eigen::MatrixXd::Identity(8, 8), samples, Eigen::MatrixXd::Ones(6, 20), basis);
  EXPECT_TRUE(u.probabilities.isApproxToConstant(1.0 / 6.0, 1e-12));
  EXPECT_TRUE(u.mean.allFinite());
}

TEST(Pi2, OneHotBasisGivesTheTimeWeightedAverageOfTheBestRollout) {
  // Step i activates kernel i only, so M_{t_i} ε keeps ε's i-th entry; with one rollout cheapest at every step and
  // a large h, δω_i = ε_best[i] (N − i) / Σ_j (N − j) by (5.11)–(5.12).
  const int n = 5;
  const Eigen::MatrixXd basis = Eigen::MatrixXd::Identity(n, n);
  Eigen::MatrixXd samples = Eigen::MatrixXd::Random(4, n);
  Eigen::MatrixXd costs = Eigen::MatrixXd::Ones(4, n);
  costs.row(2).setZero();
  bl::Pi2Parameters parameters;
  parameters.h = 200.0;
  const Eigen::VectorXd mean = Eigen::VectorXd::Zero(n);
  const bl::Pi2Update u = bl::pi2Update(parameters, mean, Eigen::MatrixXd::Identity(n, n), samples, costs, basis);
  const double total = n * (n + 1) / 2.0;
  for (int i = 0; i < n; ++i) EXPECT_NEAR(u.mean[i], samples(2, i) * (n - i) / total, 1e-9) << i;
  EXPECT_NEAR(u.probabilities(0, 2), 1.0, 1e-9);
}

TEST(Pi2, LearnsTheViaPointAndCmaShrinksTheCovariance) {
  // 1-D DMP from 0 to 1 in 1 s through y = 0.5 at t = 0.3 s: 60 updates of 10 rollouts, seed 4.
  bt::ViaPointTask task;
  for (const bool cma : {false, true}) {
    std::mt19937 rng(4);
    bl::GaussianSampler sampler;
    Eigen::VectorXd mean = task.policy().parameters();
    Eigen::MatrixXd covariance = Eigen::MatrixXd::Identity(10, 10) * 900.0;
    bl::Pi2Parameters parameters;
    parameters.covariance_adaptation = cma;
    const double initial_error = task.viaPointError(mean);
    for (int update = 0; update < 60; ++update) {
      const Eigen::MatrixXd samples = sampler.draw(mean, bl::choleskyFactor(covariance), 10, rng);
      Eigen::MatrixXd costs(10, task.policy().steps);
      for (int k = 0; k < 10; ++k) costs.row(k) = task.stepCosts(samples.row(k).transpose()).transpose();
      const bl::Pi2Update u = bl::pi2Update(parameters, mean, covariance, samples, costs, task.basis());
      mean = u.mean;
      covariance = u.covariance;
      ASSERT_EQ(covariance.llt().info(), Eigen::Success);
    }
    const double error = task.viaPointError(mean);
    std::printf("%s: via-point error %.4f -> %.4f, covariance trace %.1f\n", cma ? "PI2-CMA" : "PI2", initial_error,
                error, covariance.trace());
    EXPECT_LT(error, 0.02);
    if (cma) {
      EXPECT_LT(covariance.trace(), 9000.0);
    }
  }
}

TEST(Pi2, BadInputThrows) {
  const Eigen::MatrixXd basis = Eigen::MatrixXd::Ones(5, 2);
  const Eigen::VectorXd mean = Eigen::VectorXd::Zero(4);
  const Eigen::MatrixXd covariance = Eigen::MatrixXd::Identity(4, 4);
  EXPECT_THROW(bl::pi2Update({}, mean, covariance, Eigen::MatrixXd::Zero(3, 3), Eigen::MatrixXd::Zero(3, 5), basis),
               std::invalid_argument);
  Eigen::MatrixXd costs = Eigen::MatrixXd::Zero(3, 5);
  costs(1, 1) = std::nan("");
  EXPECT_THROW(bl::pi2Update({}, mean, covariance, Eigen::MatrixXd::Zero(3, 4), costs, basis), std::invalid_argument);
  bl::Pi2Parameters bad;
  bad.h = -1.0;
  EXPECT_THROW(bl::pi2Update(bad, mean, covariance, Eigen::MatrixXd::Zero(3, 4), Eigen::MatrixXd::Zero(3, 5), basis),
               std::invalid_argument);
}
