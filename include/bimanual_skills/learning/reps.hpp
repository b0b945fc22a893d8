/// \file
/// Episodic relative entropy policy search (thesis eqs. 5.6–5.7, dual 6.15) over a Gaussian policy N(μ, Σ).
/// Target bimanual_skills_policy_search (NLopt). Runs off the control loop: it allocates and may throw.
#pragma once

#include <Eigen/Core>

#include <deque>

namespace bimanual_skills::learning {

struct RepsParameters {
  double epsilon = 0.5;           ///< KL bound ε between the reweighted samples and the sampling policy.
  int reuse = 0;                  ///< Rollouts of earlier updates kept and reused (0: only the latest batch).
  bool normalise_rewards = true;  ///< r ← (r − min r) / (max r − min r) before the dual (thesis footnote 1).
  double covariance_regularisation = 1e-8;  ///< Added to the new covariance's diagonal.

  void validate() const;
};

/// Result of one REPS update.
struct RepsUpdate {
  Eigen::VectorXd mean;
  Eigen::MatrixXd covariance;
  Eigen::VectorXd weights;  ///< Normalised sample weights d_k / Σ d (over all samples used, newest batch last).
  double eta = 0.0;         ///< Lagrange multiplier of the KL bound.
  double kl = 0.0;          ///< Σ p_k log(N p_k): the KL of the weights from uniform, ≤ ε up to the optimiser.
};

/// REPS: new policy ∝ q(θ) exp(r(θ)/η) with η = argmin_η η ε + η log((1/N) Σ_k exp(r_k/η)), minimised by NLopt
/// (MMA) with the dual's analytic gradient; the new Gaussian is the weighted maximum-likelihood fit of the samples.
class Reps {
 public:
  explicit Reps(const RepsParameters& parameters);

  /// One update from rollouts θ (rows = samples, columns = parameters) and their rewards (higher is better), plus
  /// up to `reuse` rollouts kept from earlier calls. \throws std::invalid_argument on size mismatches, fewer than
  /// 2 samples or non-finite values.
  RepsUpdate update(const Eigen::MatrixXd& samples, const Eigen::VectorXd& rewards);

  /// Weights exp(r/η) normalised, and η, for given rewards (the dual alone; used by update()).
  static Eigen::VectorXd weights(const Eigen::VectorXd& rewards, double epsilon, double& eta, double& kl);

 private:
  RepsParameters parameters_;
  std::deque<std::pair<Eigen::VectorXd, double>> kept_;
};

}  // namespace bimanual_skills::learning
