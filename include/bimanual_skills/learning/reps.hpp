/// \file
/// Episodic relative entropy policy search (thesis eqs. 5.6–5.7, dual 6.15) over a Gaussian policy N(μ, Σ), and the
/// dual of Dual REPS (6.12) it is the special case of. Target bimanual_skills_learning (NLopt). Runs off the
/// control loop: it allocates and may throw.
#pragma once

#include "bimanual_skills/learning/gaussian.hpp"

#include <Eigen/Core>

#include <deque>
#include <utility>
#include <vector>

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

/// A Gaussian g_i of Dual REPS evaluated at the samples, with the KL constraint it adds to (6.2): repulsive (low
/// performing, KL(π‖g_i) ≥ ξ, multiplier ν_i ≥ minimum_multiplier) or attractive (KL(π‖g_i) ≤ χ, ω_i ≥ 0).
struct DualConstraint {
  Eigen::VectorXd log_density;  ///< log g_i(θ_k) for every sample k.
  bool attractive = false;
  double bound = 0.0;               ///< ξ (repulsive) or χ (attractive).
  double minimum_multiplier = 0.0;  ///< Lower bound of ν_i (repulsive only).
};

/// Solution of the (Dual) REPS dual for given rewards.
struct DualSolution {
  Eigen::VectorXd weights;      ///< d_k of (6.13) normalised to sum 1.
  double eta = 0.0;             ///< η.
  Eigen::VectorXd multipliers;  ///< ν_i or ω_i, one per constraint, in the order given.
  double kl = 0.0;              ///< Σ_k p_k log(N p_k), the sample estimate of KL(π‖q).
};

/// Minimises the dual (6.12) over η, ν, ω with NLopt MMA and its analytic gradient, subject to
/// η + ω − ν > 0 and the multipliers' bounds, and returns the weights (6.13):
///   h = η ε + Σ_high ω_i χ − Σ_low ν_i ξ + κ log((1/N) Σ_k exp(a_k/κ)),  κ = η + ω − ν,
///   a_k = r_k + (ν − ω) log q(θ_k) + Σ_high ω_i log g_i(θ_k) − Σ_low ν_i log g_i(θ_k).
/// With no constraints this is the REPS dual (6.15) and its weights exp(r_k/η) (5.7) — the same code path, so Dual
/// REPS without clusters is REPS bit for bit. `log_q` (log q(θ_k)) is only read when there are constraints.
DualSolution solveRepsDual(const Eigen::VectorXd& rewards, double epsilon, const Eigen::VectorXd& log_q,
                           const std::vector<DualConstraint>& constraints);

/// The dual of solveRepsDual() at x = [κ, m_1, …, m_c] (κ = η + ω − ν > 0, m_i = ν_i or ω_i), with its gradient
/// with respect to x when `gradient` is given (resized to c + 1). Exposed for tests and analysis.
double repsDualObjective(const Eigen::VectorXd& rewards, double epsilon, const Eigen::VectorXd& log_q,
                         const std::vector<DualConstraint>& constraints, const Eigen::VectorXd& x,
                         Eigen::VectorXd* gradient);

/// The rollouts an update uses: up to `reuse` kept from earlier updates, then the new batch (rewards raw).
class RolloutBuffer {
 public:
  explicit RolloutBuffer(int reuse) : reuse_(reuse) {}
  /// Kept rollouts followed by this batch. \throws std::invalid_argument on size mismatches, fewer than 2 samples,
  /// non-finite values or a parameter dimension that changed between updates.
  std::pair<Eigen::MatrixXd, Eigen::VectorXd> gather(const Eigen::MatrixXd& samples,
                                                     const Eigen::VectorXd& rewards) const;
  /// Keeps the newest `reuse` rollouts of this batch and earlier ones.
  void keep(const Eigen::MatrixXd& samples, const Eigen::VectorXd& rewards);

 private:
  int reuse_;
  std::deque<std::pair<Eigen::VectorXd, double>> kept_;
};

/// r ← (r − min r) / (max r − min r), or zeros when all rewards are equal.
Eigen::VectorXd normalisedRewards(const Eigen::VectorXd& rewards);

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
  RolloutBuffer buffer_;
};

}  // namespace bimanual_skills::learning
