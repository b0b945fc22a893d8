// Dual REPS (thesis Ch. 6) and its k-means: deterministic clustering, no clusters == REPS bit for bit, the KL bound
// after the repair, clusters where the bad and good rollouts are, escape from the REPS plateau of (6.16).
#include "bimanual_skills/learning/dual_reps.hpp"
#include "bimanual_skills/learning/kmeans.hpp"
#include "bimanual_skills/tasks/policy_search_tasks.hpp"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <cmath>
#include <random>
#include <vector>

namespace bl = bimanual_skills::learning;
namespace bt = bimanual_skills::tasks;

namespace {

Eigen::MatrixXd gaussianSamples(std::mt19937& rng, const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance,
                                int n) {
  return bl::GaussianSampler().draw(mean, bl::choleskyFactor(covariance), n, rng);
}

/// (6.16) with optima at (2, 1), (−2, 1), (0, −2) around the origin.
const bt::MultimodalReward threeOptima;

/// The policy mean after each of `updates` updates of `rollouts` rollouts on (6.16), from N(0, I).
std::vector<Eigen::VectorXd> learnThreeOptima(const bl::DualRepsParameters& parameters, unsigned seed, int updates,
                                              int rollouts) {
  bl::DualReps learner(parameters);
  std::mt19937 rng(seed);
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(2);
  Eigen::MatrixXd covariance = Eigen::MatrixXd::Identity(2, 2);
  std::vector<Eigen::VectorXd> means;
  for (int update = 0; update < updates; ++update) {
    const Eigen::MatrixXd samples = gaussianSamples(rng, mean, covariance, rollouts);
    Eigen::VectorXd rewards(rollouts);
    for (int k = 0; k < rollouts; ++k) rewards[k] = threeOptima(samples.row(k).transpose());
    const bl::DualRepsUpdate u = learner.update(mean, covariance, samples, rewards);
    mean = u.policy.mean;
    covariance = u.policy.covariance;
    means.push_back(mean);
  }
  return means;
}

}  // namespace

TEST(KMeans, SeparatesBlobsDeterministically) {
  std::mt19937 rng(3);
  const std::vector<Eigen::Vector3d> centres = {{0, 0, 0}, {10, 0, 0}, {0, 10, 5}};
  Eigen::MatrixXd points(90, 3);
  for (int c = 0; c < 3; ++c) {
    points.middleRows(30 * c, 30) = gaussianSamples(rng, centres[c], Eigen::Matrix3d::Identity(), 30);
  }
  const bl::KMeansResult a = bl::kMeans(points, 3);
  const bl::KMeansResult b = bl::kMeans(points, 3);
  EXPECT_EQ(a.labels, b.labels);
  EXPECT_EQ(a.centres, b.centres);
  for (int c = 0; c < 3; ++c) {  // every blob in one cluster, and the three clusters distinct
    for (int k = 1; k < 30; ++k) EXPECT_EQ(a.labels[30 * c + k], a.labels[30 * c]);
  }
  EXPECT_NE(a.labels[0], a.labels[30]);
  EXPECT_NE(a.labels[0], a.labels[60]);
  EXPECT_NE(a.labels[30], a.labels[60]);
  EXPECT_THROW(bl::kMeans(points, 0), std::invalid_argument);
  EXPECT_THROW(bl::kMeans(points, 91), std::invalid_argument);
}

TEST(DualReps, DualGradientMatchesFiniteDifferencesAndTheSolutionIsAMinimum) {
  // (6.12) with one repulsive and one attractive Gaussian on random samples.
  std::mt19937 rng(13);
  const Eigen::MatrixXd samples = gaussianSamples(rng, Eigen::VectorXd::Zero(3), Eigen::MatrixXd::Identity(3, 3), 60);
  Eigen::VectorXd rewards(60);
  for (int k = 0; k < 60; ++k) rewards[k] = -samples.row(k).squaredNorm();
  rewards = bl::normalisedRewards(rewards);
  const Eigen::VectorXd log_q =
      bl::gaussianLogDensity(samples, Eigen::VectorXd::Zero(3), Eigen::MatrixXd::Identity(3, 3));
  std::vector<bl::DualConstraint> constraints(2);
  constraints[0].log_density =
      bl::gaussianLogDensity(samples, Eigen::VectorXd::Constant(3, 1.0), 0.5 * Eigen::MatrixXd::Identity(3, 3));
  constraints[0].bound = 5.0;
  constraints[0].minimum_multiplier = 0.01;
  constraints[1].log_density =
      bl::gaussianLogDensity(samples, Eigen::VectorXd::Constant(3, -0.2), 0.5 * Eigen::MatrixXd::Identity(3, 3));
  constraints[1].attractive = true;
  constraints[1].bound = 1.0;
  for (const Eigen::Vector3d& x : {Eigen::Vector3d(0.3, 0.02, 0.01), Eigen::Vector3d(1.5, 0.1, 0.3)}) {
    Eigen::VectorXd gradient;
    bl::repsDualObjective(rewards, 0.5, log_q, constraints, x, &gradient);
    for (int i = 0; i < 3; ++i) {
      const double h = 1e-6;
      Eigen::VectorXd plus = x, minus = x;
      plus[i] += h;
      minus[i] -= h;
      const double fd = (bl::repsDualObjective(rewards, 0.5, log_q, constraints, plus, nullptr) -
                         bl::repsDualObjective(rewards, 0.5, log_q, constraints, minus, nullptr)) /
                        (2 * h);
      EXPECT_NEAR(gradient[i], fd, 1e-6 * std::max(1.0, std::abs(fd))) << "component " << i;
    }
  }
  // The solution: no feasible nearby point (η ≥ 0, ν ≥ its bound, ω ≥ 0) has a lower dual.
  const bl::DualSolution solution = bl::solveRepsDual(rewards, 0.5, log_q, constraints);
  Eigen::VectorXd best(3);
  best << solution.eta + solution.multipliers[1] - solution.multipliers[0], solution.multipliers;
  const double value = bl::repsDualObjective(rewards, 0.5, log_q, constraints, best, nullptr);
  std::mt19937 perturb(2);
  std::normal_distribution<double> normal(0.0, 1e-3);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::VectorXd x = best;
    for (int i = 0; i < 3; ++i) x[i] += normal(perturb);
    const double eta = x[0] + x[1] - x[2];
    if (x[0] <= 0.0 || eta < 0.0 || x[1] < 0.01 || x[2] < 0.0) continue;
    EXPECT_GE(bl::repsDualObjective(rewards, 0.5, log_q, constraints, x, nullptr), value - 1e-9);
  }
}

TEST(DualReps, WithoutClustersItIsRepsBitForBit) {
  bl::RepsParameters reps_parameters;
  reps_parameters.reuse = 100;
  bl::Reps reps(reps_parameters);
  bl::DualRepsParameters dual_parameters;
  dual_parameters.reps = reps_parameters;
  dual_parameters.clusters = 0;
  bl::DualReps dreps(dual_parameters);
  std::mt19937 rng(5);
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(4);
  Eigen::MatrixXd covariance = Eigen::MatrixXd::Identity(4, 4);
  for (int update = 0; update < 15; ++update) {
    const Eigen::MatrixXd samples = gaussianSamples(rng, mean, covariance, 40);
    Eigen::VectorXd rewards(40);
    for (int k = 0; k < 40; ++k) rewards[k] = -(samples.row(k).array() - 1.0).square().sum();
    const bl::RepsUpdate a = reps.update(samples, rewards);
    const bl::DualRepsUpdate b = dreps.update(mean, covariance, samples, rewards);
    ASSERT_EQ(a.mean, b.policy.mean) << "update " << update;
    ASSERT_EQ(a.covariance, b.policy.covariance);
    ASSERT_EQ(a.weights, b.policy.weights);
    ASSERT_EQ(a.eta, b.policy.eta);
    EXPECT_TRUE(b.clusters.empty());
    mean = a.mean;
    covariance = a.covariance;
  }
}

TEST(DualReps, ClustersSitOnBadAndGoodRolloutsAndTheKlBoundHolds) {
  std::mt19937 rng(9);
  const Eigen::VectorXd mean = Eigen::VectorXd::Zero(2);
  const Eigen::MatrixXd covariance = Eigen::MatrixXd::Identity(2, 2);
  const Eigen::MatrixXd samples = gaussianSamples(rng, mean, covariance, 200);
  Eigen::VectorXd rewards(200);
  for (int k = 0; k < 200; ++k) rewards[k] = threeOptima(samples.row(k).transpose());
  bl::DualRepsParameters parameters;
  const std::vector<bl::DualRepsCluster> clusters =
      bl::dualRepsClusters(samples, bl::normalisedRewards(rewards), mean, covariance, parameters);
  int attractive = 0, repulsive = 0;
  for (const auto& c : clusters) {
    // The reward at a repulsive cluster's mean is below the batch's mean reward, at an attractive one above.
    const double at_mean = threeOptima(c.mean);
    if (c.attractive) {
      ++attractive;
      EXPECT_GT(at_mean, rewards.mean());
    } else {
      ++repulsive;
      EXPECT_LT(at_mean, rewards.mean());
    }
    // Positive definite: the smallest eigenvalue (llt()'s diagonal would pass a matrix that is not).
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(c.covariance).eigenvalues().minCoeff(), 0.0);
    EXPECT_LE((c.covariance - c.covariance.transpose()).cwiseAbs().maxCoeff(), 1e-12);
  }
  EXPECT_EQ(attractive, 1);
  EXPECT_GE(repulsive, 1);
  EXPECT_LE(repulsive, 4);
  bl::DualReps dreps(parameters);
  const bl::DualRepsUpdate update = dreps.update(mean, covariance, samples, rewards);
  EXPECT_LE(update.policy.kl, parameters.reps.epsilon * 1.001);
  EXPECT_NEAR(update.policy.weights.sum(), 1.0, 1e-12);
  EXPECT_EQ(update.clusters.size(), clusters.size());
}

TEST(DualReps, LeavesThePlateauBetweenOptimaThatHoldsReps) {
  // 40 updates of 100 rollouts (reusing 400) from N(0, I) on (6.16), 5 seeds: DREPS ends within 0.3 of an optimum
  // in every run; REPS, which averages between optima, in fewer.
  const auto nearest = [](bool dual, unsigned seed) {
    bl::DualRepsParameters parameters;
    parameters.reps.reuse = 400;
    if (!dual) parameters.clusters = 0;
    parameters.chi = 2.0 * parameters.reps.epsilon;
    const Eigen::VectorXd mean = learnThreeOptima(parameters, seed, 40, 100).back();
    double distance = 1e9;
    for (const Eigen::Vector2d& p : {Eigen::Vector2d(2, 1), Eigen::Vector2d(-2, 1), Eigen::Vector2d(0, -2)}) {
      distance = std::min(distance, (mean - p).norm());
    }
    return distance;
  };
  int dreps_near = 0, reps_near = 0;
  for (unsigned seed = 1; seed <= 5; ++seed) {
    dreps_near += nearest(true, seed) < 0.3 ? 1 : 0;
    reps_near += nearest(false, seed) < 0.3 ? 1 : 0;
  }
  std::printf("(6.16), 5 runs of 40 updates: within 0.3 of an optimum: DREPS %d, REPS %d\n", dreps_near, reps_near);
  EXPECT_EQ(dreps_near, 5);
  EXPECT_LT(reps_near, dreps_near);
}

TEST(MultimodalReward, InDimensionKeepsTheDistancesOfThe2dProblem) {
  EXPECT_EQ(bt::MultimodalReward::inDimension(2).optima, threeOptima.optima);
  for (const int d : {20, 100}) {
    const bt::MultimodalReward reward = bt::MultimodalReward::inDimension(d);
    ASSERT_EQ(reward.dimension(), d);
    EXPECT_LT(reward.centroid().norm(), 1e-12);
    for (std::size_t i = 0; i < 3; ++i) {
      EXPECT_NEAR(reward.optima[i].norm(), threeOptima.optima[i].norm(), 1e-12);
      EXPECT_NEAR(reward(reward.optima[i]), threeOptima(threeOptima.optima[i]), 1e-12);
      for (std::size_t j = 0; j < 3; ++j) {
        EXPECT_NEAR((reward.optima[i] - reward.optima[j]).norm(),
                    (threeOptima.optima[i] - threeOptima.optima[j]).norm(), 1e-12);
      }
    }
    // Each optimum is a local maximum: a step of 0.1 along any coordinate lowers the reward.
    for (int k = 0; k < d; ++k) {
      for (const double step : {-0.1, 0.1}) {
        Eigen::VectorXd moved = reward.optima[0];
        moved[k] += step;
        EXPECT_LT(reward(moved), reward(reward.optima[0]));
      }
    }
    // The origin, their centroid, is the worst of the optima's span: below the optima and below a point between two.
    EXPECT_LT(reward(Eigen::VectorXd::Zero(d)), reward(0.5 * (reward.optima[0] + reward.optima[1])));
  }
  EXPECT_THROW(bt::MultimodalReward::inDimension(3), std::invalid_argument);
  EXPECT_THROW(bt::MultimodalReward::inDimension(0), std::invalid_argument);
  EXPECT_THROW(bt::MultimodalReward::inDimension(20)(Eigen::VectorXd::Zero(2)), std::invalid_argument);
}

TEST(DualReps, TheSameSeedGivesTheSameLearningCurve) {
  // Clustering (k-means from its deterministic start), dual, repair and reuse: nothing depends on anything but the
  // samples, so two learners fed from equally seeded generators agree bit for bit.
  bl::DualRepsParameters parameters;
  parameters.reps.reuse = 200;
  const auto a = learnThreeOptima(parameters, 21, 10, 50);
  const auto b = learnThreeOptima(parameters, 21, 10, 50);
  const auto c = learnThreeOptima(parameters, 22, 10, 50);
  for (std::size_t k = 0; k < a.size(); ++k) EXPECT_EQ(a[k], b[k]) << "update " << k;
  EXPECT_NE(a.back(), c.back());
}

TEST(DualReps, BadInputThrows) {
  bl::DualRepsParameters bad;
  bad.chi = 0.0;
  EXPECT_THROW(bl::DualReps{bad}, std::invalid_argument);
  bl::DualReps dreps(bl::DualRepsParameters{});
  const Eigen::MatrixXd samples = Eigen::MatrixXd::Random(20, 3);
  const Eigen::VectorXd rewards = Eigen::VectorXd::Random(20);
  EXPECT_THROW(dreps.update(Eigen::VectorXd::Zero(2), Eigen::MatrixXd::Identity(2, 2), samples, rewards),
               std::invalid_argument);
  Eigen::VectorXd nan = rewards;
  nan[4] = std::nan("");
  EXPECT_THROW(dreps.update(Eigen::VectorXd::Zero(3), Eigen::MatrixXd::Identity(3, 3), samples, nan),
               std::invalid_argument);
}
