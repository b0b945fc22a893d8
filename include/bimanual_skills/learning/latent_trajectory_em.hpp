/// \file
/// Weighted expectation-maximisation of a linear latent trajectory model: the DR-ProMP's (thesis 7.13–7.19, the
/// values are joint positions and φ_t the ProMP basis) and the EM DR-DMP's (7.43–7.49, the values are forcing terms
/// and φ_t the DMP basis g(x_t)), with the PCA initialisation and the contextual least-squares initialisation (7.20).
/// Notation as in coordination_matrix.hpp (one coordination matrix: the grid's N_s must be 1). Offline: allocates
/// and throws std::invalid_argument.
#pragma once

#include "bimanual_skills/learning/coordination_matrix.hpp"

#include <Eigen/Core>

#include <vector>

namespace bimanual_skills::learning {

/// θ = {μ_ω, Σ_ω, Ω, Σ_y, K_ω} of (7.2–7.5), (7.14), (7.44): at each step t of a trajectory
///   y_t = Ω Ψ_tᵀ ω + ε_y,   ε_y ~ N(0, Σ_y),   ω | s ~ N(μ_ω + K_ω s, Σ_ω),   Ψ_tᵀ = I_r ⊗ φ_tᵀ.
struct LatentTrajectoryModel {
  Eigen::MatrixXd coordination;  ///< Ω (d × r).
  Eigen::VectorXd mean;          ///< μ_ω (r n).
  Eigen::MatrixXd covariance;    ///< Σ_ω (r n × r n), positive definite.
  Eigen::MatrixXd noise;         ///< Σ_y (d × d), positive definite (Σ_f of the DR-DMP).
  Eigen::MatrixXd context_gain;  ///< K_ω (r n × M); M = 0 columns: no context.

  int dofs() const noexcept { return static_cast<int>(coordination.rows()); }
  int latentDims() const noexcept { return static_cast<int>(coordination.cols()); }
  /// \throws std::invalid_argument naming the first inconsistent or non-finite member, for n kernels.
  void validate(int kernels) const;
};

/// Weighted trajectories: Y^k (N_t × d, row t = y_tᵀ), weights d_k ≥ 0 (not all 0; REPS weights, or 1 for
/// demonstrations of equal importance) and contexts s_k (rows of an N_d × M matrix; 0 columns: no context).
struct WeightedTrajectories {
  std::vector<Eigen::MatrixXd> trajectories;
  Eigen::VectorXd weights;
  Eigen::MatrixXd contexts;

  /// \throws std::invalid_argument for inconsistent sizes, non-finite data or bad weights.
  void validate(int steps, int dofs, int context_size) const;
};

/// The E-step's posteriors p(ω | Y^k) = N(μ_k, Σ_post) (7.13); Σ_post is the same for every trajectory.
struct LatentPosterior {
  Eigen::MatrixXd means;       ///< r n × N_d, column k = μ_k.
  Eigen::MatrixXd covariance;  ///< Σ_post.
};

/// E-step with the Kronecker structure (cost linear in N_t): with R = I_{N_t} ⊗ Σ_y and A = Ω_{N_t} Ψᵀ,
///   AᵀR⁻¹A = (Ωᵀ Σ_y⁻¹ Ω) ⊗ G = H,   G = Σ_t φ_t φ_tᵀ,
///   Σ_post = (Σ_ω⁻¹ + H)⁻¹ = L (I + Lᵀ H L)⁻¹ Lᵀ  (Woodbury; Σ_ω = L Lᵀ),
///   μ_k = m_k + Σ_post (b_k − H m_k),  m_k = μ_ω + K_ω s_k,  b_k = AᵀR⁻¹ Y^k = vec_rows(Ωᵀ Σ_y⁻¹ Y^kᵀ Φ),
/// equal to the thesis' μ_k = m_k + Σ_ω A ᵀ Γ⁻¹ (Y^k − A m_k), Σ_post = Σ_ω − Σ_ω Aᵀ Γ⁻¹ A Σ_ω with
/// Γ = R + A Σ_ω Aᵀ of size (N_t d)². \throws std::invalid_argument for inconsistent data, N_s ≠ 1, or Σ_ω, Σ_y not
/// positive definite.
LatentPosterior latentEStep(const CoordinationGrid& grid, const LatentTrajectoryModel& model,
                            const WeightedTrajectories& data);

/// The same E-step in the printed form, inverting Γ (Cholesky of the (N_t d)² matrix): the reference of
/// latentEStep(). \throws as latentEStep().
LatentPosterior latentEStepNaive(const CoordinationGrid& grid, const LatentTrajectoryModel& model,
                                 const WeightedTrajectories& data);

/// Settings of the M-step and of the EM loop.
struct LatentEmParameters {
  int max_iterations = 50;
  double tolerance = 1e-8;          ///< Stop when the log-likelihood gains less than tolerance · (1 + |L|).
  bool update_coordination = true;  ///< false keeps Ω (e.g. a full ProMP with Ω = I).
  double noise_floor = 0.0;         ///< Added to Σ_y's diagonal after (7.19) (keeps it positive definite).
  double covariance_floor = 0.0;    ///< Added to Σ_ω's diagonal after (7.16).
  double context_ridge = 1e-9;      ///< Ridge on K_ω in the joint solution of (7.15) and (7.18).

  void validate() const;
};

/// M-step (7.15–7.19, 7.46–7.49) from the posteriors, with p_k = d_k / Σ d the normalised weights:
///   [μ_ω K_ω] = the p-weighted least squares of μ_k on [1; s_k] (the joint maximiser of (7.15) and (7.18); without
///     contexts μ_ω = Σ p_k μ_k),
///   Σ_ω = Σ_post + Σ p_k (μ_k − μ_ω − K_ω s_k)(…)ᵀ (7.16),
///   Ω = [Σ_k p_k Σ_t y_t^k (Ψ_tᵀ μ_k)ᵀ] [Σ_t Ψ_tᵀ S Ψ_t]⁻¹, S = Σ_post + Σ p_k μ_k μ_kᵀ (7.17), whose r × r
///     second factor has the entries tr(S_ij G),
///   Σ_y = (1/N_t) Σ p_k Σ_t [Ω Ψ_tᵀ Σ_post Ψ_t Ωᵀ + e_t^k e_t^kᵀ], e_t^k = y_t^k − Ω Ψ_tᵀ μ_k (7.19),
/// in this order (each maximises the expected complete log-likelihood given the ones before, so the EM never
/// decreases the weighted log-likelihood), then the floors. \throws std::invalid_argument as latentEStep().
LatentTrajectoryModel latentMStep(const CoordinationGrid& grid, const LatentTrajectoryModel& model,
                                  const WeightedTrajectories& data, const LatentPosterior& posterior,
                                  const LatentEmParameters& parameters);

/// The weighted marginal log-likelihood Σ_k d_k log N(Y^k | A m_k, Γ) (what the EM maximises), by the matrix
/// determinant lemma and the Woodbury identity: log|Γ| = N_t log|Σ_y| + log|I + Lᵀ H L|,
/// eᵀΓ⁻¹e = Σ_t e_tᵀ Σ_y⁻¹ e_t − c_eᵀ Σ_post c_e with c_e = AᵀR⁻¹ e. \throws as latentEStep().
double latentLogLikelihood(const CoordinationGrid& grid, const LatentTrajectoryModel& model,
                           const WeightedTrajectories& data);

/// The same from the dense Γ (the reference). \throws as latentEStep().
double latentLogLikelihoodNaive(const CoordinationGrid& grid, const LatentTrajectoryModel& model,
                                const WeightedTrajectories& data);

/// Result of latentEm().
struct LatentEmResult {
  LatentTrajectoryModel model;
  std::vector<double> log_likelihood;  ///< Before the first iteration and after each one.
  int iterations = 0;
};

/// Weighted EM (7.13–7.19): E- and M-steps from `initial` until the log-likelihood gain falls below the tolerance
/// or max_iterations. \throws as latentEStep().
LatentEmResult latentEm(const CoordinationGrid& grid, const WeightedTrajectories& data,
                        const LatentTrajectoryModel& initial, const LatentEmParameters& parameters);

/// Settings of the PCA initialisation.
struct LatentPcaParameters {
  double ridge = 1e-6;             ///< Ridge of the latent weights' least squares, and λ of (7.20).
  double covariance_prior = 1e-6;  ///< Added to Σ_ω's diagonal.
  double noise_floor = 1e-10;      ///< Added to Σ_y's diagonal.

  void validate() const;
};

/// PCA initialisation (Sec. 7.1.3, "Initialization"): Ω = the r principal directions of all y_t^k (pcaCoordination,
/// weighted by d_k); ω_k the ridge least-squares latent weights of each trajectory (fitLatentWeights); μ_ω, Σ_ω their
/// d-weighted mean and covariance plus the prior, or with contexts [μ_ω, K_ω]ᵀ = (S diag(d) Sᵀ + λ I)⁻¹
/// S diag(d) W_dᵀ (7.20) and Σ_ω the weighted covariance of ω_k − μ_ω − K_ω s_k; Σ_y the weighted mean residual
/// covariance (1/N_t) Σ_t e_t e_tᵀ of the reconstruction (the thesis initialises Σ_y with the whole covariance of the
/// data about its mean; the residual is its maximum-likelihood value given Ω and ω_k). \throws
/// std::invalid_argument for inconsistent data, N_s ≠ 1 or r outside [1, d].
LatentTrajectoryModel latentPcaModel(const CoordinationGrid& grid, const WeightedTrajectories& data, int r,
                                     const LatentPcaParameters& parameters);

/// The marginal of y_t under the model for context s: N(Ω Ψ_tᵀ m, Ω Ψ_tᵀ Σ_ω Ψ_t Ωᵀ + Σ_y), m = μ_ω + K_ω s (7.5).
/// \throws std::invalid_argument for a step outside the grid or a context of the wrong size.
void latentMarginal(const CoordinationGrid& grid, const LatentTrajectoryModel& model, int step,
                    const Eigen::VectorXd& context, Eigen::VectorXd& mean, Eigen::MatrixXd& covariance);

}  // namespace bimanual_skills::learning
