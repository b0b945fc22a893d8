/// \file
/// Probabilistic movement primitives (thesis eqs. 5.16–5.18): a Gaussian over basis weights fitted to several
/// demonstrations, sampling, and conditioning on via-points.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <random>
#include <vector>

namespace bimanual_skills::primitives {

struct ProMpParameters {
  int kernels = 20;                ///< Gaussian basis functions per DoF, centres uniform in the phase z ∈ [0, 1].
  double width = 0.0;              ///< Basis variance in z²; 0: (spacing)² / 2.
  double ridge = 1e-6;             ///< Ridge of each demonstration's least-squares weights.
  double covariance_prior = 1e-6;  ///< Added to Σ_ω's diagonal (few demonstrations give a singular sample covariance).

  void validate() const;
};

/// y_t = Ψ_tᵀ ω + ε_y (5.16), ω ~ N(μ_ω, Σ_ω) (5.17), with ω = [ω_1; …; ω_d] (one block of `kernels` per DoF), Ψ_t
/// block-diagonal with the normalised Gaussian basis b(z) evaluated at the phase z = t / duration. Evaluation uses
/// internal scratch buffers: one ProMp object per thread.
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

  int dofs() const noexcept { return dofs_; }
  int kernels() const noexcept { return parameters_.kernels; }
  double duration() const noexcept { return duration_; }
  const Eigen::VectorXd& weightMean() const noexcept { return mean_; }
  const Eigen::MatrixXd& weightCovariance() const noexcept { return covariance_; }
  const Eigen::VectorXd& observationVariance() const noexcept { return observation_variance_; }

  /// Basis b(z) (kernels) and its derivative db/dz. Real-time safe.
  void basis(double z, Eigen::Ref<Eigen::VectorXd> b, Eigen::Ref<Eigen::VectorXd> db) const noexcept;

  /// Mean position Ψ_zᵀ μ_ω and velocity at phase z (clamped to [0, 1]). Real-time safe: no allocation.
  void mean(double z, Eigen::Ref<Eigen::VectorXd> position, Eigen::Ref<Eigen::VectorXd> velocity) const noexcept;
  /// Position covariance Ψ_zᵀ Σ_ω Ψ_z (dofs × dofs) at phase z, without Σ_y. Real-time safe: no allocation.
  void covariance(double z, Eigen::Ref<Eigen::MatrixXd> out) const noexcept;

  /// Weights drawn from N(μ_ω, Σ_ω).
  Eigen::VectorXd sample(std::mt19937& rng) const;

  /// The ProMP conditioned on observing position y* (and, if `velocity` has dofs entries, velocity ẏ*) at phase z
  /// with observation covariance Σ* (dofs × dofs, or 2 dofs × 2 dofs with velocity): μ' = μ + K (o − Hᵀ μ),
  /// Σ' = Σ − K Hᵀ Σ, K = Σ H (Σ* + Hᵀ Σ H)⁻¹.
  ProMp conditioned(double z, const Eigen::VectorXd& position, const Eigen::MatrixXd& observation_covariance,
                    const Eigen::VectorXd& velocity = Eigen::VectorXd()) const;

 private:
  /// Ψ_z (dofs·kernels × dofs) positions, and the velocity one, into the scratch members.
  void blockBasis(double z) const noexcept;

  ProMpParameters parameters_;
  int dofs_;
  Eigen::VectorXd mean_, observation_variance_, centres_;
  Eigen::MatrixXd covariance_;
  double duration_, width_;
  Eigen::LLT<Eigen::MatrixXd> sampler_;
  mutable Eigen::VectorXd b_, db_;
  mutable Eigen::MatrixXd psi_, scratch_;
};

}  // namespace bimanual_skills::primitives
