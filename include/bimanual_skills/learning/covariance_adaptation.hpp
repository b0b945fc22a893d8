/// \file
/// Covariance matrix adaptation with cumulative step-size control (N. Hansen, "The CMA evolution strategy: a
/// comparing review", 2006, the thesis' ref. [135]) driven by given recombination weights, such as REPS' d_k. The
/// thesis names it (Secs. 7.2 and 8) as the remedy for the premature convergence of weighted maximum-likelihood
/// covariances: the covariance keeps a filtered memory of successful steps (rank-one and rank-μ updates) and a
/// global step size σ grows while consecutive mean steps point the same way and shrinks while they cancel.
/// Runs off the control loop: allocates, throws.
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::learning {

/// The search distribution N(m, σ² C) and the evolution paths of CMA-ES.
struct CovarianceAdaptation {
  double step_size = 1.0;      ///< σ.
  Eigen::MatrixXd shape;       ///< C (symmetric positive definite).
  Eigen::VectorXd step_path;   ///< p_σ, the conjugate evolution path (in C^{-1/2} coordinates).
  Eigen::VectorXd shape_path;  ///< p_c, the evolution path of the rank-one update.
  int generations = 0;         ///< Updates done (for the h_σ stall test).

  /// σ = 1, C = `covariance`, zero paths. \throws std::invalid_argument unless `covariance` is square and finite
  /// with a positive diagonal.
  static CovarianceAdaptation start(const Eigen::MatrixXd& covariance);

  Eigen::MatrixXd covariance() const { return step_size * step_size * shape; }  ///< σ² C.

  /// One update from the samples (rows) drawn around `old_mean` with N(·, σ² C), their normalised recombination
  /// weights w_k (Σ w_k = 1, w_k ≥ 0) and the new mean m' = Σ w_k θ_k (the caller's, so that it is REPS' own):
  ///   μ_eff = 1 / Σ w_k², y_k = (θ_k − m) / σ, y_w = (m' − m) / σ,
  ///   p_σ ← (1 − c_σ) p_σ + √(c_σ (2 − c_σ) μ_eff) C^{-1/2} y_w,
  ///   p_c ← (1 − c_c) p_c + h_σ √(c_c (2 − c_c) μ_eff) y_w,
  ///   C ← (1 − c_1 − c_μ) C + c_1 (p_c p_cᵀ + (1 − h_σ) c_c (2 − c_c) C) + c_μ Σ w_k y_k y_kᵀ,
  ///   σ ← σ exp((c_σ / d_σ) (‖p_σ‖ / E‖N(0, I)‖ − 1)),
  /// with Hansen's default learning rates for the dimension n and μ_eff. \throws std::invalid_argument for
  /// inconsistent sizes, weights that are not normalised or non-finite data.
  void update(const Eigen::VectorXd& old_mean, const Eigen::VectorXd& new_mean, const Eigen::MatrixXd& samples,
              const Eigen::VectorXd& weights);

  /// Carries the state into new coordinates θ' = M θ (a coordination change, M r' × r) where the search
  /// distribution's covariance is now `covariance` (r' × r', e.g. the reprojection's M σ² C Mᵀ): σ is kept,
  /// C ← covariance / σ², p ← M p. \throws std::invalid_argument for inconsistent sizes or a non-finite covariance.
  void moveTo(const Eigen::MatrixXd& sample_map, const Eigen::MatrixXd& covariance);
};

/// CMA-ES's recombination weights of a batch (Hansen 2006, (μ/μ_w, λ)), rewards maximised: the best μ = max(1, λ/2)
/// samples get w ∝ ln(μ + ½) − ln(rank), the others 0; Σ w = 1. Ties keep the batch's order.
/// \throws std::invalid_argument for no rewards or non-finite ones.
Eigen::VectorXd cmaEsWeights(const Eigen::VectorXd& rewards);

/// One CMA-ES generation: the new mean Σ w_k θ_k with cmaEsWeights(rewards), and `adaptation` updated from the same
/// weights (its covariance() is the next search distribution's). Returns the new mean. \throws
/// std::invalid_argument as CovarianceAdaptation::update().
Eigen::VectorXd cmaEsStep(const Eigen::VectorXd& mean, CovarianceAdaptation& adaptation, const Eigen::MatrixXd& samples,
                          const Eigen::VectorXd& rewards);

}  // namespace bimanual_skills::learning
