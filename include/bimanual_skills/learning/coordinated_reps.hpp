/// \file
/// Policy search over the latent weights of a coordinated (reduced-dimension) movement primitive, with the θ updates
/// of the thesis' Table 7.2 selectable by configuration: REPS with a fixed coordination (DR-DMP⁰, ProMP+REPS,
/// DMP+REPS with Ω = I), REPS followed by the coordination matrix update (CMU / MCMU, Alg. 7.2; IDR with a finite η),
/// and REPS weights followed by the weighted EM of the latent model (EM DR-DMP, 7.43–7.49, and EM-REPS with
/// DR-ProMP, Alg. 7.1). Target bimanual_skills_learning (NLopt). Runs off the control loop: allocates, throws.
#pragma once

#include "bimanual_skills/learning/coordination_matrix.hpp"
#include "bimanual_skills/learning/covariance_adaptation.hpp"
#include "bimanual_skills/learning/latent_trajectory_em.hpp"
#include "bimanual_skills/learning/reps.hpp"

#include <Eigen/Core>

#include <deque>
#include <vector>

namespace bimanual_skills::learning {

/// How the coordination follows the rollouts (Table 7.2, "θ update").
enum class CoordinationRule {
  Fixed,  ///< REPS on the latent weights; Ω_s stay as initialised (DR-DMP⁰(r), DR-DMP⁰(N_s, r)).
  Cmu,    ///< REPS, then CMU / MCMU (Alg. 7.2): DR-DMP_CMU(r), DR-DMP_MCMU(N_s, r); IDR with η < ∞.
  Em,  ///< REPS weights, then weighted EM of Ω, μ_ω, Σ_ω, Σ_y on the rollouts' values (EM DR-DMP(r), Alg. 7.1).
};

/// How Σ_ω follows the rollouts under the Fixed and Cmu rules.
enum class CovarianceRule {
  MaximumLikelihood,  ///< REPS' weighted maximum-likelihood covariance (5.7), blended by covariance_memory λ.
  /// REPS' weights and mean, with the covariance and a step size adapted as in CMA-ES (CovarianceAdaptation; the
  /// thesis' ref. [135]): Σ_ω = σ² C. Not in the thesis' experiments; its Sec. 8 proposes it against premature
  /// convergence.
  Adapted,
};

struct CoordinatedRepsParameters {
  RepsParameters reps;  ///< ε, rollouts reused from earlier updates, rewards normalised, ridge on Σ_ω.
  CoordinationRule rule = CoordinationRule::Fixed;
  CoordinationUpdateParameters update;  ///< Cmu: η and the filter α.
  LatentEmParameters em;                ///< Em: iterations and floors (the grid must have one matrix).
  /// λ in [0, 1): Fixed and Cmu take Σ_ω ← (1 − λ) Σ_ML + λ Σ_ω, Σ_ML REPS' weighted maximum-likelihood covariance
  /// and Σ_ω the one the rollouts were drawn from. With fewer rollouts than latent weights Σ_ML has lower rank
  /// than Σ_ω, and with λ = 0 (the thesis' update) the search never again explores the directions no rollout
  /// happened to span; λ > 0 lets them shrink geometrically instead.
  double covariance_memory = 0.0;
  /// MaximumLikelihood (the thesis) or Adapted; Adapted needs the Fixed or Cmu rule and λ = 0.
  CovarianceRule covariance_rule = CovarianceRule::MaximumLikelihood;

  void validate() const;
};

/// The policy: coordination matrices, the Gaussian over latent weights, and (Em) the noise Σ_y of the values.
struct CoordinatedPolicy {
  std::vector<Eigen::MatrixXd> coordination;  ///< Ω_s, d × r each.
  Eigen::VectorXd mean;                       ///< μ_ω (r n).
  Eigen::MatrixXd covariance;                 ///< Σ_ω.
  Eigen::MatrixXd noise;                      ///< Σ_y of the latent model (Em only; d × d).

  int latentDims() const noexcept { return static_cast<int>(coordination.front().cols()); }
};

/// What one update did.
struct CoordinatedRepsReport {
  Eigen::VectorXd weights;  ///< REPS weights d_k of the rollouts used (kept ones first, then this batch).
  double eta = 0.0;         ///< REPS temperature.
  double kl = 0.0;          ///< KL of the weights from uniform.
  bool reduced = false;     ///< Cmu: the latent dimension dropped by one.
  int em_iterations = 0;    ///< Em: EM iterations run.
};

/// One learner for one run. Each update takes the latent weights ω_k the rollouts were drawn with (rows; in the
/// coordinates of the current policy), the values each rollout executed (N_t × d: the forcing terms of a DR-DMP,
/// exploration outside the latent space included, or the positions of a DR-ProMP) and the rewards. Rollouts kept
/// for reuse (RepsParameters::reuse) are carried into new coordinates with the reprojection's sample map (M† or N)
/// whenever Ω changes.
class CoordinatedReps {
 public:
  /// `grid`: the basis and activations of the rollouts' N_t steps. `initial_excitation`: F_co^s of the
  /// demonstrations for the CMU filter (may be empty: no filtering at the first update). \throws
  /// std::invalid_argument for invalid parameters, a policy inconsistent with the grid, or Em with N_s ≠ 1 or
  /// without a noise covariance. With CovarianceRule::Adapted the initial Σ_ω is σ² C with σ = 1.
  CoordinatedReps(const CoordinatedRepsParameters& parameters, const CoordinationGrid& grid,
                  const CoordinatedPolicy& initial, const std::vector<Eigen::MatrixXd>& initial_excitation = {});

  const CoordinatedPolicy& policy() const noexcept { return policy_; }
  const CoordinationGrid& grid() const noexcept { return grid_; }

  /// One update (see the class comment). \throws std::invalid_argument for inconsistent sizes or non-finite data.
  CoordinatedRepsReport update(const Eigen::MatrixXd& samples, const std::vector<Eigen::MatrixXd>& values,
                               const Eigen::VectorXd& rewards);

 private:
  struct Rollout {
    Eigen::VectorXd sample;
    Eigen::MatrixXd values;
    double reward;
  };

  CoordinatedRepsParameters parameters_;
  CoordinationGrid grid_;
  CoordinatedPolicy policy_;
  std::vector<Eigen::MatrixXd> excitation_;
  std::deque<Rollout> kept_;
  CovarianceAdaptation adaptation_;  ///< Adapted only: σ, C and the paths; Σ_ω = σ² C.
};

}  // namespace bimanual_skills::learning
