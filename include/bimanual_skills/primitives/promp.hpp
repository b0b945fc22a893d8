/// \file
/// Probabilistic movement primitives (thesis eqs. 5.16–5.18): a Gaussian over basis weights fitted to several
/// demonstrations, sampling, and conditioning on via-points.
#pragma once

#include <Eigen/Core>

#include <random>
#include <vector>

namespace bimanual_skills::primitives {

/// Outcome of a real-time ProMP evaluation. On anything but Success the outputs are unchanged.
enum class ProMpStatus { Success, WrongSize, NotFinite };
const char* toString(ProMpStatus status) noexcept;

struct ProMpParameters {
  int kernels = 20;                ///< Gaussian basis functions per DoF, centres uniform in the phase z ∈ [0, 1].
  double width = 0.0;              ///< Basis variance in z²; 0: (spacing)² / 2.
  double ridge = 1e-6;             ///< Ridge of each demonstration's least-squares weights.
  double covariance_prior = 1e-6;  ///< Added to Σ_ω's diagonal (few demonstrations give a singular sample covariance).
  double context_ridge = 1e-9;     ///< Ridge on K_ω in the contextual fit (ContextualProMp::fit); the mean is free.

  void validate() const;
};

struct ProMpData;

/// Per-demonstration least-squares weights: one column ω_k (dofs·kernels) per demonstration, and Σ_y, the mean
/// squared fitting residual per DoF.
struct DemonstrationWeights {
  Eigen::MatrixXd weights;
  Eigen::VectorXd observation_variance;
};

/// y_t = Ψ_tᵀ ω + ε_y (5.16), ω ~ N(μ_ω, Σ_ω) (5.17), with ω = [ω_1; …; ω_d] (one block of `kernels` per DoF), Ψ_t
/// block-diagonal with the normalised Gaussian basis b(z) evaluated at the phase z = t / duration, and the state
/// y_t = [q_t; q̇_t] (positions of every DoF, then velocities). The model is immutable; evaluation writes into a
/// ProMpData sized from it (one per thread).
class ProMp {
 public:
  /// \throws std::invalid_argument for inconsistent sizes, a Σ_ω that is not symmetric positive semidefinite,
  /// or a duration ≤ 0.
  ProMp(const ProMpParameters& parameters, int dofs, const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance,
        const Eigen::VectorXd& observation_variance, double duration);

  /// Maximum-likelihood fit (sample mean and covariance of the per-demonstration least-squares weights, 5.18).
  /// Each demonstration is samples × dofs, any number of samples (≥ kernels), spread uniformly over its own duration;
  /// `duration` is the mean length in seconds (used for velocities). Σ_y is the mean squared fitting residual per DoF.
  /// \throws std::invalid_argument for fewer than 2 demonstrations, unequal DoF or non-finite data.
  static ProMp fit(const ProMpParameters& parameters, const std::vector<Eigen::MatrixXd>& demonstrations,
                   double duration);

  /// The ridge least-squares weights of every demonstration (the ω_k of 5.18), fitted one DoF at a time:
  /// ω_{k,j} = (BᵀB + ridge I)⁻¹ Bᵀ y_{k,j}, B the basis at each sample's phase.
  /// \throws std::invalid_argument for no demonstrations, unequal DoF, too few samples or non-finite data.
  static DemonstrationWeights demonstrationWeights(const ProMpParameters& parameters,
                                                   const std::vector<Eigen::MatrixXd>& demonstrations);

  /// The same ProMP with another weight mean μ_ω (Σ_ω, Σ_y and the basis unchanged).
  /// \throws std::invalid_argument for a wrong size or non-finite entries.
  ProMp withMean(const Eigen::VectorXd& mean) const;

  int dofs() const noexcept { return dofs_; }
  int kernels() const noexcept { return parameters_.kernels; }
  const ProMpParameters& parameters() const noexcept { return parameters_; }
  double duration() const noexcept { return duration_; }
  const Eigen::VectorXd& weightMean() const noexcept { return mean_; }
  const Eigen::MatrixXd& weightCovariance() const noexcept { return covariance_; }
  const Eigen::VectorXd& observationVariance() const noexcept { return observation_variance_; }

  /// Basis b(z) (kernels) and its derivative db/dz. Real-time safe: no allocation, no exceptions.
  void basis(double z, Eigen::Ref<Eigen::VectorXd> b, Eigen::Ref<Eigen::VectorXd> db) const noexcept;

  /// Ψ_z (dofs·kernels × 2 dofs, positions then velocities d/dt = (d/dz) / duration) at z clamped to [0, 1], into
  /// data.psi. WrongSize (data of another model) or NotFinite (z), data unchanged.
  /// Real-time safe: no allocation, no exceptions.
  [[nodiscard]] ProMpStatus blockBasis(ProMpData& data, double z) const noexcept;

  /// Mean position Ψ_zᵀ μ_ω and velocity at phase z (clamped to [0, 1]). WrongSize or NotFinite (z), outputs
  /// unchanged. Real-time safe: no allocation, no exceptions.
  [[nodiscard]] ProMpStatus mean(ProMpData& data, double z, Eigen::Ref<Eigen::VectorXd> position,
                                 Eigen::Ref<Eigen::VectorXd> velocity) const noexcept;
  /// Position covariance Ψ_zᵀ Σ_ω Ψ_z (dofs × dofs) at phase z, without Σ_y, computed block by block (Ψ_z is
  /// block-diagonal: entry (i, j) is b_iᵀ Σ_ω^{ij} b_j). WrongSize or NotFinite (z), output unchanged.
  /// Real-time safe: no allocation, no exceptions.
  [[nodiscard]] ProMpStatus covariance(ProMpData& data, double z, Eigen::Ref<Eigen::MatrixXd> out) const noexcept;
  /// Covariance of the state [q; q̇] (2 dofs × 2 dofs) at phase z, without Σ_y, block by block as covariance().
  /// WrongSize or NotFinite (z), output unchanged. Real-time safe: no allocation, no exceptions.
  [[nodiscard]] ProMpStatus stateCovariance(ProMpData& data, double z, Eigen::Ref<Eigen::MatrixXd> out) const noexcept;

  /// Weights drawn from N(μ_ω, Σ_ω).
  Eigen::VectorXd sample(std::mt19937& rng) const;

  /// The ProMP conditioned on observing position y* (and, if `velocity` has dofs entries, velocity ẏ*) at phase z
  /// with observation covariance Σ* (dofs × dofs, or 2 dofs × 2 dofs with velocity): μ' = μ + K (o − Hᵀ μ),
  /// Σ' = Σ − K Hᵀ Σ, K = Σ H (Σ* + Hᵀ Σ H)⁻¹.
  ProMp conditioned(double z, const Eigen::VectorXd& position, const Eigen::MatrixXd& observation_covariance,
                    const Eigen::VectorXd& velocity = Eigen::VectorXd()) const;

 private:
  /// Checks the data's sizes and z; WrongSize or NotFinite.
  ProMpStatus check(const ProMpData& data, double z) const noexcept;
  /// out = Ψ_zᵀ Σ_ω Ψ_z over the first `columns` state columns (dofs: positions; 2 dofs: positions and velocities)
  /// from the basis in data.b, data.db: column c of Σ_ω Ψ_z is the product of Σ_ω's block column of DoF c mod dofs
  /// with that DoF's basis vector, and entry (r, c) the basis vector of row r dotted with its block of that column.
  void projectCovariance(ProMpData& data, int columns, Eigen::Ref<Eigen::MatrixXd> out) const noexcept;

  ProMpParameters parameters_;
  int dofs_;
  Eigen::VectorXd mean_, observation_variance_, centres_, widths_;
  Eigen::MatrixXd covariance_;
  double duration_;
  Eigen::MatrixXd sampling_factor_;  ///< L of Σ_ω + 10⁻¹² I = L Lᵀ
};

/// Scratch buffers of a ProMp's evaluation, sized once from the model: `ProMpData data(promp);`.
struct ProMpData {
  explicit ProMpData(const ProMp& promp);

  Eigen::VectorXd b, db;      ///< Basis b(z) and db/dz (kernels).
  Eigen::VectorXd dt_basis;   ///< db/dt = (db/dz) / duration (kernels).
  Eigen::MatrixXd psi;        ///< Ψ_z (dofs·kernels × 2 dofs): position columns, then velocity columns.
  Eigen::MatrixXd sigma_psi;  ///< Σ_ω Ψ_z (dofs·kernels × 2 dofs).
};

}  // namespace bimanual_skills::primitives
