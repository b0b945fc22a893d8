/// \file
/// Coordination matrices of reduced-dimension movement primitives (thesis Sec. 7.1.1 and 7.2.1): the linear map Ω
/// (d × r) from r latent DoF to the d DoF of the robot, its PCA initialisation (7.26–7.27), the time blending of N_s
/// matrices (7.38–7.39), their order and sign matching (Alg. 7.3), the KL-minimising reprojection of the latent
/// weight distribution when Ω changes (7.29–7.36, 7.42) and the reward-weighted coordination matrix update
/// CMU / MCMU (Alg. 7.2, 7.40).
///
/// Notation shared with latent_trajectory_em.hpp: the latent weights ω = [ω_1; …; ω_r] hold one block of n basis
/// weights per latent DoF (W, r × n, has the rows ω_jᵀ), and at time step t the d values (forcing terms of a DR-DMP,
/// positions of a DR-ProMP) are
///   f_t = Ω^t Ψ_tᵀ ω = Ω^t W φ_t,   Ψ_tᵀ = I_r ⊗ φ_tᵀ (7.3, 7.24),   Ω^t = Σ_s φ_s^t Ω_s (7.39),
/// φ_t the basis (n values) and φ_s^t the normalised activations of the N_s matrices (7.38); with one matrix Ω^t = Ω.
/// Stacked over the N_t steps, F = O Ψᵀ ω with O = blockdiag(Ω^1, …, Ω^{N_t}) (7.31, 7.42). Products with O Ψᵀ
/// are formed from the N_s² basis products G_{ss'} = Σ_t φ_s^t φ_{s'}^t φ_t φ_tᵀ instead of the (N_t d × r n) matrix:
/// (O_a Ψᵀ)ᵀ (O_b Ψᵀ) = Σ_{s,s'} (Ω_{a,s}ᵀ Ω_{b,s'}) ⊗ G_{ss'}, so their cost does not grow with N_t.
/// Offline (allocates, throws std::invalid_argument) unless marked real-time safe.
#pragma once

#include <Eigen/Core>

#include <limits>
#include <vector>

namespace bimanual_skills::learning {

/// The time grid of a coordinated model: the basis φ_t and the activations φ_s^t at each of N_t steps, and the basis
/// products G_{ss'} computed once.
class CoordinationGrid {
 public:
  /// `basis` N_t × n (row t = φ_tᵀ), `activations` N_t × N_s (row t = φ_s^t, rows summing to 1 for a blend).
  /// \throws std::invalid_argument for empty, non-finite or inconsistent matrices.
  CoordinationGrid(const Eigen::MatrixXd& basis, const Eigen::MatrixXd& activations);
  /// One coordination matrix: all activations 1.
  explicit CoordinationGrid(const Eigen::MatrixXd& basis);

  int steps() const noexcept { return static_cast<int>(basis_.rows()); }
  int kernels() const noexcept { return static_cast<int>(basis_.cols()); }
  int matrices() const noexcept { return static_cast<int>(activations_.cols()); }
  const Eigen::MatrixXd& basis() const noexcept { return basis_; }
  const Eigen::MatrixXd& activations() const noexcept { return activations_; }
  /// G_{ss'} = Σ_t φ_s^t φ_{s'}^t φ_t φ_tᵀ (n × n). \throws std::out_of_range for s, s2 outside [0, matrices()).
  const Eigen::MatrixXd& product(int s, int s2) const;

 private:
  Eigen::MatrixXd basis_, activations_;
  std::vector<Eigen::MatrixXd> products_;  ///< G_{ss'} at s · N_s + s'.
};

/// Ω^t = Σ_s φ_s^t Ω_s (7.39) into `out` (d × r), the maximiser of (7.37) for orthonormal Ω_s. The caller sizes
/// `out` like the matrices and passes one activation per matrix. Real-time safe: no allocation, no exceptions.
void blendCoordination(const std::vector<Eigen::MatrixXd>& matrices,
                       const Eigen::Ref<const Eigen::VectorXd>& activations, Eigen::Ref<Eigen::MatrixXd> out) noexcept;

/// (O_a Ψᵀ)ᵀ (O_b Ψᵀ) = Σ_{s,s'} (Ω_{a,s}ᵀ Ω_{b,s'}) ⊗ G_{ss'} (r_a n × r_b n), for N_s matrices of d × r_a and
/// d × r_b. \throws std::invalid_argument for counts other than grid.matrices() or inconsistent sizes.
Eigen::MatrixXd coordinatedGram(const CoordinationGrid& grid, const std::vector<Eigen::MatrixXd>& a,
                                const std::vector<Eigen::MatrixXd>& b);

/// O Ψᵀ as a dense (N_t d × r n) matrix, rows ordered step by step (the d values of step 0 first). For tests and
/// the naive forms of the algorithms. \throws std::invalid_argument as coordinatedGram().
Eigen::MatrixXd coordinatedDesign(const CoordinationGrid& grid, const std::vector<Eigen::MatrixXd>& matrices);

/// The values Ω^t W φ_t of latent weights ω at every step (N_t × d, row t = f_tᵀ). \throws std::invalid_argument
/// for inconsistent sizes.
Eigen::MatrixXd coordinatedValues(const CoordinationGrid& grid, const std::vector<Eigen::MatrixXd>& matrices,
                                  const Eigen::VectorXd& weights);

/// Ridge least-squares latent weights of values F (N_t × d): argmin_ω Σ_t ‖f_t − Ω^t Ψ_tᵀ ω‖² + ridge ‖ω‖²
/// (learning::ridgeLeastSquares on coordinatedDesign()). \throws std::invalid_argument for inconsistent sizes or
/// weights the values do not determine (raise the ridge).
Eigen::VectorXd fitLatentWeights(const CoordinationGrid& grid, const std::vector<Eigen::MatrixXd>& matrices,
                                 const Eigen::MatrixXd& values, double ridge);

/// Principal directions of samples.
struct PcaCoordination {
  Eigen::MatrixXd omega;            ///< Ω = [u_1, …, u_r] (d × r, orthonormal), largest singular values first.
  Eigen::VectorXd singular_values;  ///< σ_1 ≥ … ≥ σ_d of the centred (weighted) sample matrix.
};

/// PCA coordination matrix (7.26–7.27): the samples (d × N, one column per time step and/or demonstration) are
/// centred by their (weighted) mean, each column scaled by √w_k when `column_weights` are given (N entries ≥ 0,
/// not all 0), and Ω is the r left singular vectors of the largest singular values. Each column's entry of largest
/// magnitude is made positive (the SVD's sign is arbitrary). \throws std::invalid_argument for r outside [1, d],
/// non-finite samples or bad weights.
PcaCoordination pcaCoordination(const Eigen::MatrixXd& samples, int r,
                                const Eigen::VectorXd& column_weights = Eigen::VectorXd());

/// Reordering and sign matching of PCA results (Alg. 7.3): every Ω_s, s ≥ 2, has its columns permuted and their
/// signs flipped to match Ω_1 (the reference), from K = Ω_1ᵀ Ω_s. A column j of Ω_s whose largest |K(i, j)| is also
/// the largest of row i is assigned to column i with the sign of K(i, j) (lines 7–13). Where this leaves the
/// assignment incomplete (rank(PCAROT) < r, after which the printed algorithm repeats the same lines unchanged) the
/// remaining columns are assigned greedily by the largest |K| among unassigned rows and columns. Then
/// Ω_s ← Ω_s PCAROTᵀ. \throws std::invalid_argument for matrices of unequal sizes.
void alignCoordinationMatrices(std::vector<Eigen::MatrixXd>& matrices);

/// How LatentReprojection carries μ_ω, Σ_ω into new coordinates.
enum class ReprojectionRule {
  /// The printed KL minimiser (7.35–7.36) through M† (M below). Where a new direction is nearly outside the old span
  /// M is ill-conditioned and M† amplifies: in the planar10 experiment with MCMU(2, 8) M† reached singular values of
  /// 10²–10³ and Σ_ω eigenvalues of 10⁹ within three updates.
  Printed,
  /// The least-squares projection of the old values onto the new coordination, N = (O Ψᵀ)† Ô Ψ̂ᵀ (r n × r̂ n):
  /// μ_ω = N μ̂_ω, Σ_ω = N Σ̂_ω Nᵀ, the moments of the values' distribution projected onto the new span. N = M⁻¹ (the
  /// same result as Printed) whenever the new coordination spans what the old one spans; otherwise N is bounded by
  /// the conditioning of O Ψᵀ alone.
  LeastSquares,
};

/// The reprojection of the latent weight distribution when the coordination changes from Ω̂_s (r̂ latent DoF) to
/// Ω_s (r) (7.29–7.36, and 7.42 for several matrices): M = (Ô Ψ̂ᵀ)† O Ψᵀ (r̂ n × r n) maps new latent weights to the
/// old ones that give the closest values, and the new N(μ_ω, Σ_ω) minimises KL(N(μ̂_ω, Σ̂_ω) ‖ N(M μ_ω, M Σ_ω Mᵀ)):
///   μ_ω = M† μ̂_ω (7.35),   Σ_ω = M† [Σ̂_ω + (M μ_ω − μ̂_ω)(M μ_ω − μ̂_ω)ᵀ] M†ᵀ (7.36)
/// (ReprojectionRule::Printed), or the least-squares projection of ReprojectionRule::LeastSquares. When Ω_s spans what
/// Ω̂_s spans (r = r̂) both keep the distribution of the values F = O Ψᵀ ω exactly.
class LatentReprojection {
 public:
  /// \throws std::invalid_argument for counts other than grid.matrices(), inconsistent sizes, or an old or new
  /// coordination whose O Ψᵀ does not have full column rank.
  LatentReprojection(const CoordinationGrid& grid, const std::vector<Eigen::MatrixXd>& old_matrices,
                     const std::vector<Eigen::MatrixXd>& new_matrices,
                     ReprojectionRule rule = ReprojectionRule::Printed);

  const Eigen::MatrixXd& matrix() const noexcept { return M_; }              ///< M.
  const Eigen::MatrixXd& pseudoInverse() const noexcept { return M_pinv_; }  ///< M†.
  const Eigen::MatrixXd& projection() const noexcept { return N_; }          ///< N = (O Ψᵀ)† Ô Ψ̂ᵀ.
  /// The map of old latent weights to new ones of the rule: M† or N.
  const Eigen::MatrixXd& sampleMap() const noexcept { return rule_ == ReprojectionRule::Printed ? M_pinv_ : N_; }
  /// μ_ω of the rule ((7.35) or N μ̂_ω); also maps one latent sample into the new coordinates. \throws
  /// std::invalid_argument for a size other than r̂ n.
  Eigen::VectorXd mean(const Eigen::VectorXd& old_mean) const;
  /// Σ_ω of the rule ((7.36) or N Σ̂_ω Nᵀ), symmetrised. \throws std::invalid_argument for sizes other than r̂ n.
  Eigen::MatrixXd covariance(const Eigen::VectorXd& old_mean, const Eigen::MatrixXd& old_covariance) const;

 private:
  ReprojectionRule rule_;
  Eigen::MatrixXd M_, M_pinv_, N_;
};

/// Settings of the coordination matrix update (Alg. 7.2 and its MCMU variant).
struct CoordinationUpdateParameters {
  /// η: the last latent DoF is dropped when σ_1/σ_r > η (IDR); infinity keeps r (DR-DMP_CMU, Table 7.2).
  double eta = std::numeric_limits<double>::infinity();
  double filter = 1.0;      ///< α of line 2: F_co ← α F_co^new + (1 − α) F_co^previous, in (0, 1].
  int min_latent_dims = 1;  ///< r is never reduced below this.
  /// Line 9: the printed (7.35–7.36) or the least-squares reprojection (see ReprojectionRule).
  ReprojectionRule reprojection = ReprojectionRule::LeastSquares;

  void validate() const;
};

/// Outcome of one coordination matrix update.
struct CoordinationUpdateResult {
  std::vector<Eigen::MatrixXd> matrices;    ///< New Ω_s (d × r each; aligned by Alg. 7.3 when N_s > 1).
  std::vector<Eigen::MatrixXd> excitation;  ///< Filtered F_co^s (d × N_t each): the `previous` of the next update.
  Eigen::VectorXd singular_values;          ///< σ of the centred Σ_s F_co^s, the quantities η is compared with.
  bool reduced = false;                     ///< r dropped by one.
  Eigen::VectorXd mean;                     ///< μ_ω reprojected (7.35).
  Eigen::MatrixXd covariance;               ///< Σ_ω reprojected (7.36).
  Eigen::MatrixXd sample_map;               ///< M† or N: maps old latent samples into the new coordinates.
};

/// Reward-weighted coordination matrix update, CMU (Alg. 7.2) and with N_s > 1 matrices MCMU (7.40):
///  1. F_co^s (d × N_t), column t = φ_s^t Σ_k p_k f_t^k (7.28, 7.40), p the normalised rollout weights (REPS gives
///     one per rollout: P_t^k = p_k) and f_t^k the values (executed forcing terms) of rollout k, F^k = `values[k]`
///     (N_t × d);
///  2. filtered with the previous F_co^s (line 2) unless `previous_excitation` is empty;
///  3–7. PCA (7.26–7.27) of the pooled Σ_s F_co^s; if σ_1/σ_r > η, r ← r − 1 (once per update, never below
///     min_latent_dims);
///  8. Ω_s = the r leading principal directions of each F_co^s (one matrix: of F_co), aligned by Alg. 7.3;
///  9. μ_ω, Σ_ω reprojected (LatentReprojection with parameters.reprojection).
/// \throws std::invalid_argument for inconsistent sizes, non-finite values, negative or all-zero weights.
CoordinationUpdateResult coordinationMatrixUpdate(const CoordinationGrid& grid,
                                                  const CoordinationUpdateParameters& parameters,
                                                  const std::vector<Eigen::MatrixXd>& matrices,
                                                  const std::vector<Eigen::MatrixXd>& previous_excitation,
                                                  const std::vector<Eigen::MatrixXd>& values,
                                                  const Eigen::VectorXd& weights, const Eigen::VectorXd& mean,
                                                  const Eigen::MatrixXd& covariance);

/// The weighted excitation F_co^s of step 1 above (7.28, 7.40), without filtering: one d × N_t matrix per
/// coordination matrix of the grid. \throws std::invalid_argument as coordinationMatrixUpdate().
std::vector<Eigen::MatrixXd> weightedExcitation(const CoordinationGrid& grid,
                                                const std::vector<Eigen::MatrixXd>& values,
                                                const Eigen::VectorXd& weights);

}  // namespace bimanual_skills::learning
