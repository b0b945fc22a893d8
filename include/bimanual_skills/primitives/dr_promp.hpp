/// \file
/// ProMP with dimensionality reduction (DR-ProMP, thesis Sec. 7.1): a ProMP in an r-dimensional latent space of the
/// d DoF, y_t = Ω_2 x_t + ε, x_t = Ψ_tᵀ ω (7.1–7.5), optionally contextual, fitted by weighted EM (7.13–7.19) from a
/// PCA (and contextual least-squares, 7.20) initialisation.
#pragma once

#include "bimanual_skills/learning/latent_trajectory_em.hpp"
#include "bimanual_skills/primitives/promp.hpp"

#include <Eigen/Core>

#include <random>
#include <vector>

namespace bimanual_skills::primitives {

struct DrProMpParameters {
  ProMpParameters promp;            ///< Basis (kernels, width); `ridge` and `covariance_prior` of the initialisation.
  int latent_dims = 4;              ///< r (1 ≤ r ≤ d).
  /// EM iterations, tolerance, floors; Σ_y's floor 10⁻⁸ keeps it invertible for data that are exactly low-rank.
  learning::LatentEmParameters em{50, 1e-8, true, 1e-8, 0.0, 1e-9};

  void validate() const;
};

struct DrProMpData;

/// p(y_t | s) = ∫ N(y_t | Ω Ψ_tᵀ ω, Σ_y) N(ω | μ_ω + K_ω s, Σ_ω) dω (7.5): the latent x_t = Ψ_tᵀ ω is an r-DoF ProMP
/// (its weights ω = [ω_1; …; ω_r], one block of `kernels` per latent DoF, over the phase z = t / duration), mapped to
/// the d DoF by the coordination matrix Ω (d × r), positions and velocities alike (Ω_2 = I_2 ⊗ Ω, 7.1). Immutable;
/// evaluation writes into a DrProMpData.
class DrProMp {
 public:
  /// \throws std::invalid_argument for inconsistent sizes, non-finite values, Σ_ω not positive semidefinite, Σ_y not
  /// symmetric, a duration ≤ 0, or an Ω without full column rank.
  DrProMp(const ProMpParameters& parameters, const Eigen::MatrixXd& coordination, const Eigen::VectorXd& mean,
          const Eigen::MatrixXd& covariance, const Eigen::MatrixXd& observation_covariance, double duration,
          const Eigen::MatrixXd& context_gain = Eigen::MatrixXd());
  /// From the parameters θ of the latent model (the EM's). \throws as above.
  DrProMp(const ProMpParameters& parameters, const learning::LatentTrajectoryModel& model, double duration);

  /// The grid of a trajectory of `samples` samples: the ProMP basis b(z_t) at z_t = t / (samples − 1).
  /// \throws std::invalid_argument for fewer than 2 samples or invalid parameters.
  static learning::CoordinationGrid grid(const ProMpParameters& parameters, int samples);

  /// Weighted EM fit (7.13–7.19) from the PCA initialisation (7.20 with contexts) of equally long demonstrations
  /// (samples × d each, spread uniformly over `duration`), with weights d_k (empty: all 1) and contexts (rows; 0
  /// columns: none). `log_likelihood`, if given, receives the weighted log-likelihood before and after each
  /// iteration. \throws std::invalid_argument for invalid parameters or data.
  static DrProMp fit(const DrProMpParameters& parameters, const std::vector<Eigen::MatrixXd>& demonstrations,
                     double duration, const Eigen::VectorXd& weights = Eigen::VectorXd(),
                     const Eigen::MatrixXd& contexts = Eigen::MatrixXd(),
                     std::vector<double>* log_likelihood = nullptr);

  int dofs() const noexcept { return static_cast<int>(coordination_.rows()); }
  int latentDims() const noexcept { return latent_.dofs(); }
  int kernels() const noexcept { return latent_.kernels(); }
  double duration() const noexcept { return latent_.duration(); }
  const ProMpParameters& parameters() const noexcept { return latent_.parameters(); }
  /// The r-DoF ProMP of the latent state x_t (7.3): N(μ_ω, Σ_ω) over the latent weights (at context 0).
  const ProMp& latent() const noexcept { return latent_; }
  const Eigen::MatrixXd& coordination() const noexcept { return coordination_; }                     ///< Ω
  const Eigen::MatrixXd& observationCovariance() const noexcept { return observation_covariance_; }  ///< Σ_y
  const Eigen::MatrixXd& contextGain() const noexcept { return context_gain_; }  ///< K_ω (0 columns: none)
  /// θ as the EM's latent model.
  learning::LatentTrajectoryModel model() const;

  /// The DR-ProMP of context s (mean μ_ω + K_ω s, no context). \throws std::invalid_argument for a wrong size.
  DrProMp forContext(const Eigen::VectorXd& context) const;
  /// The same trajectory distribution as a d-DoF ProMP: weights (Ω ⊗ I_n) ω, so μ' = (Ω ⊗ I_n) μ_ω,
  /// Σ' = (Ω ⊗ I_n) Σ_ω (Ω ⊗ I_n)ᵀ, and Σ_y's diagonal as its observation variance.
  ProMp fullProMp() const;

  /// Positions (samples × d) of latent weights ω at z_t = t / (samples − 1), through this Ω or another one of the same
  /// size (e.g. Ω perturbed before a rollout, Sec. 7.1.4). \throws std::invalid_argument for wrong sizes.
  Eigen::MatrixXd trajectory(const Eigen::VectorXd& weights, int samples,
                             const Eigen::MatrixXd& coordination = Eigen::MatrixXd()) const;

  /// Mean position Ω Ψ_zᵀ μ_ω and velocity at phase z (clamped to [0, 1]). WrongSize or NotFinite (z), outputs
  /// unchanged. Real-time safe: no allocation, no exceptions.
  [[nodiscard]] ProMpStatus mean(DrProMpData& data, double z, Eigen::Ref<Eigen::VectorXd> position,
                                 Eigen::Ref<Eigen::VectorXd> velocity) const noexcept;
  /// Covariance Ω_2 Σ_x Ω_2ᵀ of the state [q; q̇] (2d × 2d) at phase z, without Σ_y. WrongSize or NotFinite, output
  /// unchanged. Real-time safe: no allocation, no exceptions.
  [[nodiscard]] ProMpStatus stateCovariance(DrProMpData& data, double z,
                                            Eigen::Ref<Eigen::MatrixXd> out) const noexcept;

 private:
  ProMp latent_;
  Eigen::MatrixXd coordination_, observation_covariance_, context_gain_;
};

/// Scratch buffers of a DrProMp's evaluation, sized once from the model: `DrProMpData data(promp);`.
struct DrProMpData {
  explicit DrProMpData(const DrProMp& promp);

  ProMpData latent;                                  ///< The latent ProMP's buffers.
  Eigen::VectorXd latent_position, latent_velocity;  ///< r each.
  Eigen::MatrixXd latent_covariance;                 ///< 2r × 2r.
  Eigen::MatrixXd mapped;                            ///< d × r.
};

}  // namespace bimanual_skills::primitives
