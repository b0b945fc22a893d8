/// \file
/// Dual REPS (thesis Ch. 6): REPS with repulsive Gaussians fitted to clusters of bad rollouts and attractive ones
/// fitted to clusters of good rollouts (6.2), clustered by Alg. 6.1, solved through the dual (6.12) and the weights
/// (6.13), with the KL repair of Sec. 6.1.2. Target bimanual_skills_learning. Off the control loop.
#pragma once

#include "bimanual_skills/learning/reps.hpp"

#include <Eigen/Core>

#include <vector>

namespace bimanual_skills::learning {

struct DualRepsParameters {
  RepsParameters reps;            ///< ε, reuse, reward normalisation and covariance regularisation, as for REPS.
  int clusters = 5;               ///< c: clusters of each of the two k-means runs of Alg. 6.1 (0: plain REPS).
  int max_repulsive = 4;          ///< |C_low| ≤ this.
  int max_attractive = 1;         ///< |C_high| ≤ this.
  bool split_repulsive = true;    ///< C_low from the 2-cluster k-means of the clusters' mean scores (Alg. 6.1 step 7),
                                  ///< else the max_repulsive worst clusters.
  bool split_attractive = false;  ///< Likewise for C_high (step 4), else the max_attractive best clusters.
  double xi = 5.0;                ///< ξ: KL(π‖g_i) ≥ ξ for the repulsive clusters.
  double chi = 1.0;               ///< χ: KL(π‖g_i) ≤ χ for the attractive ones (the thesis uses 2ε).
  double minimum_repulsion = 0.01;  ///< Lower bound of every ν_i, in normalised-reward units per nat.
  double rho = 0.0;                 ///< ρ of (6.1); 0: 10 / D as in the thesis.
  double cluster_prior = 3.0;       ///< Σ_i = (n_i Σ_WML + m Σ_q) / (n_i + m), m = cluster_prior · D pseudo-points
                                    ///< of the policy's covariance: a cluster of n_i points in D dimensions has a
                                    ///< sample covariance of rank < n_i, poorly estimated unless n_i ≫ D.
  int repair_iterations = 8;        ///< KL repair steps before the repulsive constraints are dropped.
  double repair_factor = 0.5;       ///< Each repair step scales ξ and the ν_i bound by this, χ by its inverse.

  void validate() const;
};

/// The settings of the thesis' comparisons (Sec. 6.1.3) with its ε and reuse: REPS (no clusters, every update the
/// REPS update) and DREPS (c = 5: one attractive cluster, up to 4 repulsive ones chosen by the 2-cluster split,
/// ξ = 5, χ = 2ε).
DualRepsParameters thesisReps(double epsilon, int reuse);
DualRepsParameters thesisDreps(double epsilon, int reuse);

/// A cluster Gaussian g_i = N(μ_i, Σ_i) of Alg. 6.1 and its multiplier after the update.
struct DualRepsCluster {
  Eigen::VectorXd mean;
  Eigen::MatrixXd covariance;
  bool attractive = false;
  int size = 0;             ///< Rollouts in the cluster.
  double multiplier = 0.0;  ///< ν_i or ω_i.
};

struct DualRepsUpdate {
  RepsUpdate policy;  ///< New mean and covariance, weights (6.13), η and the sample KL(π‖q).
  std::vector<DualRepsCluster> clusters;
  int repairs = 0;                 ///< KL repair steps taken.
  bool repulsion_dropped = false;  ///< The repair did not converge: the update used the attractive clusters only.
  bool plain_reps = false;         ///< No cluster was usable or every repair failed: the REPS update was used.
};

/// Alg. 6.1: k-means on [θ_k − μ, f(r_k)] with f of (6.1) for the attractive clusters and on [θ_k − μ, f(1/(1 + r̂_k))]
/// (r̂ the rewards normalised to [0, 1]) for the repulsive ones, cluster selection, and reward-weighted ML Gaussians.
/// The thesis' 1/max(r_k, 1e-9) maps every non-positive reward to 1e9, so the inverse is taken of the normalised
/// reward shifted to [1, 2]: it still stretches the low rewards (slope 4× steeper at the worst than at the best).
std::vector<DualRepsCluster> dualRepsClusters(const Eigen::MatrixXd& samples, const Eigen::VectorXd& rewards,
                                              const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance,
                                              const DualRepsParameters& parameters);

/// Alg. 6.2. With `clusters` = 0 (or no repulsive and no attractive clusters allowed) every update is the REPS
/// update, computed by the same code.
class DualReps {
 public:
  explicit DualReps(const DualRepsParameters& parameters);

  /// One update from rollouts θ (rows) sampled from the current policy q = N(mean, covariance) and their rewards
  /// (higher is better), plus up to `reuse` kept rollouts. \throws std::invalid_argument on bad sizes or values.
  DualRepsUpdate update(const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance, const Eigen::MatrixXd& samples,
                        const Eigen::VectorXd& rewards);

 private:
  DualRepsParameters parameters_;
  RolloutBuffer buffer_;
};

}  // namespace bimanual_skills::learning
