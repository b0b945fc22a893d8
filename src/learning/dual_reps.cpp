#include "bimanual_skills/learning/dual_reps.hpp"

#include "bimanual_skills/learning/kmeans.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <tuple>

namespace bimanual_skills::learning {
namespace {

/// (6.1): ρ √tr(Σ) (v − min v) / (max v − min v + 10⁻⁹).
Eigen::VectorXd scoreTransform(const Eigen::VectorXd& v, double rho, const Eigen::MatrixXd& covariance) {
  return rho * std::sqrt(covariance.trace()) * (v.array() - v.minCoeff()) / (v.maxCoeff() - v.minCoeff() + 1e-9);
}

/// Indices of the clusters chosen from their mean scores (higher is chosen first): with `split`, those of the upper
/// group of a 2-cluster k-means of the means; at most `most`, the highest first.
std::vector<int> chooseClusters(const std::vector<std::pair<double, int>>& mean_scores, bool split, int most) {
  std::vector<std::pair<double, int>> order = mean_scores;
  std::sort(order.begin(), order.end(), [](const auto& a, const auto& b) {
    return a.first > b.first || (a.first == b.first && a.second < b.second);
  });
  std::size_t keep = order.size();
  if (split && order.size() >= 2) {
    Eigen::MatrixXd means(static_cast<Eigen::Index>(order.size()), 1);
    for (std::size_t i = 0; i < order.size(); ++i) means(static_cast<Eigen::Index>(i), 0) = order[i].first;
    const KMeansResult groups = kMeans(means, 2);
    const int upper = groups.centres(0, 0) >= groups.centres(1, 0) ? 0 : 1;
    keep = static_cast<std::size_t>((groups.labels.array() == upper).count());
  }
  keep = std::min(keep, static_cast<std::size_t>(std::max(most, 0)));
  std::vector<int> chosen;
  for (std::size_t i = 0; i < keep; ++i) chosen.push_back(order[i].second);
  return chosen;
}

/// One k-means pass of Alg. 6.1 on [θ − μ, score] and the reward-weighted Gaussians of the chosen clusters.
void clusterPass(const Eigen::MatrixXd& centred, const Eigen::VectorXd& score, const Eigen::MatrixXd& samples,
                 const Eigen::MatrixXd& covariance, const DualRepsParameters& p, bool attractive,
                 std::vector<DualRepsCluster>& out) {
  const int most = attractive ? p.max_attractive : p.max_repulsive;
  if (most <= 0) return;
  const Eigen::Index n = samples.rows();
  Eigen::MatrixXd points(n, centred.cols() + 1);
  points << centred, score;
  const int k = static_cast<int>(std::min<Eigen::Index>(p.clusters, n));
  const KMeansResult clusters = kMeans(points, k);
  std::vector<std::pair<double, int>> mean_scores;
  for (int c = 0; c < k; ++c) {
    const auto members = (clusters.labels.array() == c).count();
    if (members == 0) continue;
    mean_scores.emplace_back((clusters.labels.array() == c).select(score.array(), 0.0).sum() / members, c);
  }
  for (const int c : chooseClusters(mean_scores, attractive ? p.split_attractive : p.split_repulsive, most)) {
    Eigen::VectorXd weights = (clusters.labels.array() == c).select(score.array(), 0.0).matrix();
    if (!(weights.sum() > 0.0)) weights = (clusters.labels.array() == c).cast<double>().matrix();
    weights /= weights.sum();
    DualRepsCluster cluster;
    std::tie(cluster.mean, cluster.covariance) = weightedGaussian(samples, weights, 0.0);
    cluster.attractive = attractive;
    cluster.size = static_cast<int>((clusters.labels.array() == c).count());
    const double prior = p.cluster_prior * static_cast<double>(samples.cols());
    cluster.covariance = (cluster.size * cluster.covariance + prior * covariance) / (cluster.size + prior);
    out.push_back(std::move(cluster));
  }
}

}  // namespace

DualRepsParameters thesisReps(double epsilon, int reuse) {
  DualRepsParameters p;
  p.reps.epsilon = epsilon;
  p.reps.reuse = reuse;
  p.clusters = 0;
  return p;
}

DualRepsParameters thesisDreps(double epsilon, int reuse) {
  DualRepsParameters p = thesisReps(epsilon, reuse);
  p.clusters = 5;
  p.max_attractive = 1;
  p.max_repulsive = 4;
  p.split_repulsive = true;
  p.xi = 5.0;
  p.chi = 2.0 * epsilon;
  return p;
}

void DualRepsParameters::validate() const {
  reps.validate();
  if (clusters < 0 || max_repulsive < 0 || max_attractive < 0 || !(xi >= 0.0) || !(chi > 0.0) ||
      !(minimum_repulsion >= 0.0) || !(rho >= 0.0) || !(cluster_prior > 0.0) || repair_iterations < 0 ||
      !(repair_factor > 0.0 && repair_factor < 1.0)) {
    throw std::invalid_argument(
        "DualRepsParameters: need clusters, max_repulsive, max_attractive, repair_iterations >= 0, xi >= 0, chi > 0, "
        "minimum_repulsion >= 0, rho >= 0, cluster_prior > 0, repair_factor in (0, 1)");
  }
}

std::vector<DualRepsCluster> dualRepsClusters(const Eigen::MatrixXd& samples, const Eigen::VectorXd& rewards,
                                              const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance,
                                              const DualRepsParameters& parameters) {
  std::vector<DualRepsCluster> out;
  if (parameters.clusters == 0) return out;
  const double rho = parameters.rho > 0.0 ? parameters.rho : 10.0 / static_cast<double>(samples.cols());
  const Eigen::MatrixXd centred = samples.rowwise() - mean.transpose();
  clusterPass(centred, scoreTransform(rewards, rho, covariance), samples, covariance, parameters, true, out);
  const Eigen::VectorXd inverse = (1.0 + normalisedRewards(rewards).array()).inverse().matrix();
  clusterPass(centred, scoreTransform(inverse, rho, covariance), samples, covariance, parameters, false, out);
  return out;
}

DualReps::DualReps(const DualRepsParameters& parameters) : parameters_(parameters), buffer_(parameters.reps.reuse) {
  parameters_.validate();
}

DualRepsUpdate DualReps::update(const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance,
                                const Eigen::MatrixXd& samples, const Eigen::VectorXd& rewards) {
  auto [theta, r] = buffer_.gather(samples, rewards);
  if (mean.size() != theta.cols() || covariance.rows() != mean.size() || covariance.cols() != mean.size() ||
      !mean.allFinite() || !covariance.allFinite()) {
    throw std::invalid_argument("DualReps::update: the policy's mean and covariance must match the samples' dimension");
  }
  const RepsParameters& reps = parameters_.reps;
  if (reps.normalise_rewards) r = normalisedRewards(r);
  DualRepsUpdate out;
  out.clusters = dualRepsClusters(theta, r, mean, covariance, parameters_);
  Eigen::VectorXd log_q;
  std::vector<DualConstraint> constraints;
  if (!out.clusters.empty()) {
    log_q = gaussianLogDensity(theta, mean, covariance);
    for (const DualRepsCluster& cluster : out.clusters) {
      constraints.push_back({gaussianLogDensity(theta, cluster.mean, cluster.covariance), cluster.attractive,
                             cluster.attractive ? parameters_.chi : parameters_.xi,
                             cluster.attractive ? 0.0 : parameters_.minimum_repulsion});
    }
  }
  // KL repair (Sec. 6.1.2): while KL(π‖q) exceeds ε, relax ξ, the ν_i bound and χ step by step; then drop the
  // repulsive constraints; then fall back to REPS, whose solution meets the bound.
  const double tolerance = 1e-3;
  DualSolution solution = solveRepsDual(r, reps.epsilon, log_q, constraints);
  while (!constraints.empty() && solution.kl > reps.epsilon * (1.0 + tolerance)) {
    if (out.repairs < parameters_.repair_iterations) {
      ++out.repairs;
      for (DualConstraint& c : constraints) {
        c.bound = c.attractive ? c.bound / parameters_.repair_factor : c.bound * parameters_.repair_factor;
        c.minimum_multiplier *= parameters_.repair_factor;
      }
    } else if (!out.repulsion_dropped) {
      out.repulsion_dropped = true;
      constraints.erase(
          std::remove_if(constraints.begin(), constraints.end(), [](const DualConstraint& c) { return !c.attractive; }),
          constraints.end());
    } else {
      constraints.clear();
    }
    solution = solveRepsDual(r, reps.epsilon, log_q, constraints);
  }
  out.plain_reps = constraints.empty();
  // Multipliers back onto the clusters still in use (attractive ones keep their order; repulsive ones follow).
  std::size_t next = 0;
  for (DualRepsCluster& cluster : out.clusters) {
    const bool used = !out.plain_reps && (cluster.attractive || !out.repulsion_dropped);
    cluster.multiplier = used ? solution.multipliers[static_cast<Eigen::Index>(next++)] : 0.0;
  }
  out.policy.weights = std::move(solution.weights);
  out.policy.eta = solution.eta;
  out.policy.kl = solution.kl;
  std::tie(out.policy.mean, out.policy.covariance) =
      weightedGaussian(theta, out.policy.weights, reps.covariance_regularisation);
  buffer_.keep(samples, rewards);
  return out;
}

}  // namespace bimanual_skills::learning
