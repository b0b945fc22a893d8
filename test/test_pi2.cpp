// PI2 (thesis 5.8–5.13) and PI2-CMA: equal costs leave the rollouts equally likely; a rollout best at every step
// takes the probability mass; a one-hot basis gives the literal time-weighted average of (5.12); the via-point
// task is learned; the adapted covariance stays positive definite and shrinks; bad input throws.
#include "bimanual_skills/learning/pi2.hpp"
#include "bimanual_skills/primitives/dmp.hpp"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>

#include <cmath>
#include <random>

namespace bl = bimanual_skills::learning;
namespace bp = bimanual_skills::primitives;

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
  const double dt = 0.01;
  Eigen::MatrixXd demonstration(101, 1);
  for (int i = 0; i <= 100; ++i) {
    const double s = i / 100.0;
    demonstration(i, 0) = 10 * std::pow(s, 3) - 15 * std::pow(s, 4) + 6 * std::pow(s, 5);
  }
  bp::DmpParameters dmp_parameters;
  dmp_parameters.kernels = 10;
  const bp::Dmp dmp = bp::Dmp::fit(dmp_parameters, demonstration, dt);
  Eigen::MatrixXd basis(100, 10);
  bp::DmpState state = dmp.initialState();
  for (int i = 0; i < 100; ++i) {
    Eigen::VectorXd g(10);
    dmp.basis(state.x, g);
    basis.row(i) = g.transpose();
    dmp.step(state, dt);
  }
  const auto rollout = [&](const Eigen::VectorXd& w, double& via) {
    const bp::Dmp sample = dmp.withWeights(w.transpose());
    bp::DmpState s = sample.initialState();
    Eigen::VectorXd c(100);
    for (int i = 0; i < 100; ++i) {
      sample.step(s, dt);
      c[i] = 1e-6 * s.ydd[0] * s.ydd[0];
      if (i == 29) {
        via = s.y[0];
        c[i] += 1e4 * std::pow(s.y[0] - 0.5, 2);
      }
    }
    return c;
  };
  for (const bool cma : {false, true}) {
    std::mt19937 rng(4);
    std::normal_distribution<double> normal(0.0, 1.0);
    Eigen::VectorXd mean = dmp.weights().row(0).transpose();
    Eigen::MatrixXd covariance = Eigen::MatrixXd::Identity(10, 10) * 900.0;
    bl::Pi2Parameters parameters;
    parameters.covariance_adaptation = cma;
    double via = 0.0;
    rollout(mean, via);
    const double initial_error = std::abs(via - 0.5);
    for (int update = 0; update < 60; ++update) {
      const Eigen::MatrixXd L = covariance.llt().matrixL();
      Eigen::MatrixXd samples(10, 10), costs(10, 100);
      for (int k = 0; k < 10; ++k) {
        Eigen::VectorXd e(10);
        for (int i = 0; i < 10; ++i) e[i] = normal(rng);
        samples.row(k) = (mean + L * e).transpose();
        costs.row(k) = rollout(samples.row(k).transpose(), via).transpose();
      }
      const bl::Pi2Update u = bl::pi2Update(parameters, mean, covariance, samples, costs, basis);
      mean = u.mean;
      covariance = u.covariance;
      ASSERT_EQ(covariance.llt().info(), Eigen::Success);
    }
    rollout(mean, via);
    std::printf("%s: via-point error %.4f -> %.4f, covariance trace %.1f\n", cma ? "PI2-CMA" : "PI2", initial_error,
                std::abs(via - 0.5), covariance.trace());
    EXPECT_LT(std::abs(via - 0.5), 0.02);
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
