// REPS (thesis 5.6–5.7, dual 6.15): the KL bound holds with equality when active, weights grow with the reward,
// a quadratic optimum is found, rollouts are reused, the same seed gives the same learning curve, bad input throws.
// The CMA-ES covariance and step-size adaptation driven by REPS' weights: it converges linearly on a 20-D quadratic
// where the weighted maximum-likelihood covariance stalls, σ grows along a linear reward and is about unbiased under
// random selection, and the state moves into new coordinates.
#include "bimanual_skills/learning/covariance_adaptation.hpp"
#include "bimanual_skills/learning/reps.hpp"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

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

/// `updates` updates of 20 samples on r(θ) = −‖θ − θ*‖² in 20-D from N(0, 0.1² I), weights by REPS (ε = 0.5), the
/// covariance adapted (CMA-ES) or REPS' weighted maximum likelihood; returns the final distance to θ*.
double searchQuadratic(bool adapted, int updates, double* final_step_size = nullptr) {
  constexpr int n = 20, count = 20;
  const Eigen::VectorXd target = Eigen::VectorXd::Constant(n, 1.0);
  std::mt19937 rng(5);
  bl::GaussianSampler sampler;
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(n);
  bl::CovarianceAdaptation state = bl::CovarianceAdaptation::start(0.01 * Eigen::MatrixXd::Identity(n, n));
  Eigen::MatrixXd covariance = state.covariance();
  for (int u = 0; u < updates; ++u) {
    const Eigen::MatrixXd samples = sampler.draw(mean, bl::choleskyFactor(covariance), count, rng);
    const Eigen::VectorXd rewards = -(samples.rowwise() - target.transpose()).rowwise().squaredNorm();
    double eta = 0.0, kl = 0.0;
    const Eigen::VectorXd weights = bl::Reps::weights(rewards, 0.5, eta, kl);
    auto [new_mean, ml_covariance] = bl::weightedGaussian(samples, weights, 1e-12);
    if (adapted) {
      state.update(mean, new_mean, samples, weights);
      covariance = state.covariance();
    } else {
      covariance = ml_covariance;
    }
    mean = new_mean;
  }
  if (final_step_size != nullptr) *final_step_size = state.step_size;
  return (mean - target).norm();
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

TEST(CovarianceAdaptation, ConvergesWhereTheMaximumLikelihoodCovarianceStalls) {
  // From 4.5 away with σ = 0.1 in 20-D: the adapted step size first grows, then shrinks with the distance, and the
  // mean converges linearly; REPS' own covariance of 20 samples collapses long before the optimum.
  const double adapted = searchQuadratic(true, 400), plain = searchQuadratic(false, 400);
  std::printf("20-D quadratic, 400 updates of 20: distance %.2e adapted, %.2e maximum likelihood\n", adapted, plain);
  EXPECT_LT(adapted, 1e-4);
  EXPECT_GT(plain, 0.5);
  double grown = 0.0;
  searchQuadratic(true, 40, &grown);
  EXPECT_GT(grown, 1.5);  // σ = 1 at the start
}

TEST(CovarianceAdaptation, StepSizeIsAboutUnbiasedUnderRandomSelection) {
  // Flat reward: equal weights, the mean moves by chance only. Over 200 runs of 20 generations the mean of log σ must
  // stay near 0 (its standard error is about 0.03); a 10 % error in E‖N(0, I)‖ would move it by about 0.6.
  constexpr int n = 10, count = 20, runs = 200, generations = 20;
  std::mt19937 rng(3);
  bl::GaussianSampler sampler;
  const Eigen::VectorXd weights = Eigen::VectorXd::Constant(count, 1.0 / count);
  double sum = 0.0;
  for (int run = 0; run < runs; ++run) {
    bl::CovarianceAdaptation state = bl::CovarianceAdaptation::start(Eigen::MatrixXd::Identity(n, n));
    Eigen::VectorXd mean = Eigen::VectorXd::Zero(n);
    for (int u = 0; u < generations; ++u) {
      const Eigen::MatrixXd samples = sampler.draw(mean, bl::choleskyFactor(state.covariance()), count, rng);
      const Eigen::VectorXd new_mean = samples.transpose() * weights;
      state.update(mean, new_mean, samples, weights);
      mean = new_mean;
    }
    EXPECT_EQ(state.generations, generations);
    sum += std::log(state.step_size);
  }
  std::printf("random selection: mean log(sigma) %.3f after %d generations\n", sum / runs, generations);
  EXPECT_LT(std::abs(sum / runs), 0.1);
}

TEST(CovarianceAdaptation, KeepsTheShapeWellConditioned) {
  // A shape that has lost rank (a direction no rollout explores) is lifted to condition 1e14, and σ stays finite.
  Eigen::MatrixXd singular = Eigen::MatrixXd::Identity(3, 3);
  singular(2, 2) = 1e-30;
  bl::CovarianceAdaptation state = bl::CovarianceAdaptation::start(singular);
  const Eigen::Vector3d m = Eigen::Vector3d::Zero();
  const Eigen::MatrixXd samples = (Eigen::MatrixXd(2, 3) << 1, 0, 0, 0, 1, 0).finished();
  state.update(m, samples.colwise().mean().transpose(), samples, Eigen::Vector2d(0.5, 0.5));
  EXPECT_TRUE(std::isfinite(state.step_size));
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(state.shape);
  EXPECT_GT(eigen.eigenvalues().minCoeff(), 1e-15 * eigen.eigenvalues().maxCoeff());
}

TEST(CovarianceAdaptation, MovesIntoNewCoordinatesAndRejectsBadInput) {
  bl::CovarianceAdaptation state = bl::CovarianceAdaptation::start(Eigen::MatrixXd::Identity(3, 3));
  state.step_size = 2.0;
  state.step_path = Eigen::Vector3d(1.0, 2.0, 3.0);
  state.shape_path = Eigen::Vector3d(-1.0, 0.0, 1.0);
  const Eigen::MatrixXd map = (Eigen::MatrixXd(2, 3) << 1, 0, 0, 0, 1, 1).finished();
  state.moveTo(map, 8.0 * Eigen::MatrixXd::Identity(2, 2));
  EXPECT_EQ(state.shape, 2.0 * Eigen::MatrixXd::Identity(2, 2));
  EXPECT_EQ(state.step_path, Eigen::Vector2d(1.0, 5.0));
  EXPECT_EQ(state.shape_path, Eigen::Vector2d(-1.0, 1.0));
  EXPECT_EQ(state.covariance(), 8.0 * Eigen::MatrixXd::Identity(2, 2));
  EXPECT_THROW(state.moveTo(map, Eigen::MatrixXd::Identity(2, 2)), std::invalid_argument);  // map of width 3
  EXPECT_THROW(bl::CovarianceAdaptation::start(Eigen::MatrixXd::Zero(2, 3)), std::invalid_argument);
  const Eigen::Vector2d m = Eigen::Vector2d::Zero();
  EXPECT_THROW(state.update(m, m, Eigen::MatrixXd::Zero(2, 2), Eigen::Vector2d(0.7, 0.7)), std::invalid_argument);
  EXPECT_THROW(state.update(m, m, Eigen::MatrixXd::Zero(2, 2), Eigen::Vector2d(1.5, -0.5)), std::invalid_argument);
  EXPECT_THROW(
      state.update(m, Eigen::Vector2d(std::nan(""), 0.0), Eigen::MatrixXd::Zero(2, 2), Eigen::Vector2d(0.5, 0.5)),
      std::invalid_argument);
  EXPECT_NO_THROW(state.update(m, m, Eigen::MatrixXd::Zero(2, 2), Eigen::Vector2d(0.5, 0.5)));
}

TEST(CovarianceAdaptation, CmaEsWeightsAndGenerationsFindAQuadraticsOptimum) {
  // Log-rank weights of the best half (Hansen 2006): for 4 samples μ = 2, w ∝ ln 2.5 − ln 1, ln 2.5 − ln 2.
  const Eigen::VectorXd w = bl::cmaEsWeights(Eigen::Vector4d(0.3, 0.9, -1.0, 0.5));
  const double a = std::log(2.5), b = std::log(2.5) - std::log(2.0);
  EXPECT_NEAR(w[1], a / (a + b), 1e-15);
  EXPECT_NEAR(w[3], b / (a + b), 1e-15);
  EXPECT_EQ(w[0], 0.0);
  EXPECT_EQ(w[2], 0.0);
  EXPECT_THROW(bl::cmaEsWeights(Eigen::VectorXd()), std::invalid_argument);
  EXPECT_THROW(bl::cmaEsWeights(Eigen::Vector2d(1.0, NAN)), std::invalid_argument);
  // CMA-ES on r(θ) = −‖θ − θ*‖² in 10-D from 3 away, 12 samples per generation: it converges.
  constexpr int n = 10;
  const Eigen::VectorXd target = Eigen::VectorXd::Constant(n, 1.0);
  std::mt19937 rng(2);
  bl::GaussianSampler sampler;
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(n);
  bl::CovarianceAdaptation state = bl::CovarianceAdaptation::start(0.25 * Eigen::MatrixXd::Identity(n, n));
  for (int generation = 0; generation < 300; ++generation) {
    const Eigen::MatrixXd samples = sampler.draw(mean, bl::choleskyFactor(state.covariance()), 12, rng);
    mean = bl::cmaEsStep(mean, state, samples, -(samples.rowwise() - target.transpose()).rowwise().squaredNorm());
  }
  EXPECT_LT((mean - target).norm(), 1e-4);
}
