// REPS (thesis 5.6–5.7, dual 6.15): the KL bound holds with equality when active, weights grow with the reward,
// a quadratic optimum is found, rollouts are reused, the same seed gives the same learning curve, bad input throws.
#include "bimanual_skills/learning/reps.hpp"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>

#include <cmath>
#include <random>
#include <vector>

namespace bl = bimanual_skills::learning;

namespace {

/// 40 updates of 50 rollouts on r(θ) = −‖θ − θ*‖² in 5-D from N(0, I); returns the mean after each update.
std::vector<Eigen::VectorXd> learn(unsigned seed, int reuse) {
  const Eigen::VectorXd target = (Eigen::VectorXd(5) << 1.0, -0.5, 0.3, 0.8, -1.2).finished();
  bl::RepsParameters parameters;
  parameters.reuse = reuse;
  bl::Reps reps(parameters);
  std::mt19937 rng(seed);
  bl::GaussianSampler sampler;
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(5);
  Eigen::MatrixXd covariance = Eigen::MatrixXd::Identity(5, 5);
  std::vector<Eigen::VectorXd> curve;
  for (int update = 0; update < 40; ++update) {
    const Eigen::MatrixXd samples = sampler.draw(mean, bl::choleskyFactor(covariance), 50, rng);
    Eigen::VectorXd rewards(50);
    for (int k = 0; k < 50; ++k) rewards[k] = -(samples.row(k).transpose() - target).squaredNorm();
    const bl::RepsUpdate result = reps.update(samples, rewards);
    mean = result.mean;
    covariance = result.covariance;
    curve.push_back(mean);
  }
  return curve;
}

}  // namespace

TEST(Reps, KlBoundIsMetAndWeightsFollowTheReward) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (double epsilon : {0.1, 0.5, 1.0, 2.0}) {
    Eigen::VectorXd rewards(50);
    for (int k = 0; k < 50; ++k) rewards[k] = u(rng);
    double eta = 0.0, kl = 0.0;
    const Eigen::VectorXd p = bl::Reps::weights(rewards, epsilon, eta, kl);
    EXPECT_NEAR(kl, epsilon, 1e-4 * epsilon) << "epsilon " << epsilon;  // active: KL ≤ ε holds with equality
    EXPECT_NEAR(p.sum(), 1.0, 1e-12);
    for (int a = 0; a < 50; ++a) {
      for (int b = 0; b < 50; ++b) {
        if (rewards[a] > rewards[b]) {
          EXPECT_GE(p[a], p[b]);
        }
      }
    }
  }
}

TEST(Reps, FindsTheOptimumOfAQuadraticReward) {
  const std::vector<Eigen::VectorXd> curve = learn(7, 0);
  const Eigen::VectorXd target = (Eigen::VectorXd(5) << 1.0, -0.5, 0.3, 0.8, -1.2).finished();
  std::printf("REPS, 5-D quadratic: distance to the optimum %.3f after 1 update, %.4f after 40\n",
              (curve.front() - target).norm(), (curve.back() - target).norm());
  EXPECT_LE((curve.back() - target).norm(), 0.05);
}

TEST(Reps, ReusesEarlierRolloutsAndIsDeterministic) {
  bl::RepsParameters parameters;
  parameters.reuse = 100;
  bl::Reps reps(parameters);
  const Eigen::MatrixXd samples = Eigen::MatrixXd::Random(50, 3);
  const Eigen::VectorXd rewards = Eigen::VectorXd::Random(50);
  EXPECT_EQ(reps.update(samples, rewards).weights.size(), 50);
  EXPECT_EQ(reps.update(samples, rewards).weights.size(), 100);
  EXPECT_EQ(reps.update(samples, rewards).weights.size(), 150);
  EXPECT_EQ(reps.update(samples, rewards).weights.size(), 150);
  const auto a = learn(11, 50);
  const auto b = learn(11, 50);
  for (std::size_t k = 0; k < a.size(); ++k) EXPECT_EQ(a[k], b[k]);
}

TEST(Reps, BadInputThrows) {
  bl::Reps reps(bl::RepsParameters{});
  EXPECT_THROW(reps.update(Eigen::MatrixXd::Zero(5, 2), Eigen::VectorXd::Zero(4)), std::invalid_argument);
  Eigen::VectorXd nan = Eigen::VectorXd::Zero(5);
  nan[2] = std::nan("");
  EXPECT_THROW(reps.update(Eigen::MatrixXd::Zero(5, 2), nan), std::invalid_argument);
  bl::RepsParameters bad;
  bad.epsilon = 0.0;
  EXPECT_THROW(bl::Reps{bad}, std::invalid_argument);
}
