/// \file
/// Stochastic feedback controller that reproduces a ProMP's state distribution on a linearised system
/// (thesis eqs. 5.19–5.23; Paraschos et al. 2013, "Probabilistic Movement Primitives", NIPS, Sec. 2.3 and appendix).
#pragma once

#include "bimanual_skills/primitives/promp.hpp"

#include <Eigen/Core>

#include <random>
#include <vector>

namespace bimanual_skills::primitives {

/// Linearised robot dynamics (5.19): y_{t+dt} = (I + dt A_t) y_t + B_t dt u + c_t dt, state y = [q; q̇] (positions
/// of every DoF, then velocities, as the ProMP's), input u.
struct LinearisedSystem {
  Eigen::MatrixXd A;  ///< 2 dofs × 2 dofs.
  Eigen::MatrixXd B;  ///< 2 dofs × inputs.
  Eigen::VectorXd c;  ///< 2 dofs.

  /// q̈ = u on every DoF: A = [[0, I], [0, 0]], B = [0; I], c = 0.
  static LinearisedSystem doubleIntegrator(int dofs);
};

/// Outcome of a real-time controller call.
enum class ProMpControlStatus { Success, WrongSize, NotFinite, OutOfSchedule };

/// Human-readable name of a status, for logs outside the real-time path.
const char* toString(ProMpControlStatus status) noexcept;

/// Time-varying gains of u = K_t y_t + κ_t + ε_u, ε_u ~ N(0, Σ_u / dt) (5.20), computed offline at the control rate
/// so that the closed loop (5.21) keeps the state distributed as the ProMP's N(μ_t, Σ_t) (5.22).
///
/// Matching is done on the one-step transition, exactly as (5.22) is written. The ProMP gives the joint Gaussian of
/// consecutive states, with μ_t = Ψ_tᵀ μ_ω, Σ_t = Ψ_tᵀ Σ̃_ω Ψ_t and the cross-covariance C_t = Ψ_tᵀ Σ̃_ω Ψ_{t+dt}, so
/// y_{t+dt} | y_t ~ N(μ_{t+dt} + F_t (y_t − μ_t), Σ_s dt) with F_t = C_tᵀ Σ_t⁻¹ and
///   Σ_s dt = Σ_{t+dt} − C_tᵀ Σ_t⁻¹ C_t                                       (Paraschos et al.; the thesis
///                                                                               prints C_tᵀ Σ_t C_t, a typo).
/// Setting the closed-loop matrix I + dt (A_t + B_t K_t) to F_t and the drift to the conditional mean gives
///   K_t = B_t† (F_t − I − dt A_t) / dt,
///   κ_t = B_t† ((μ_{t+dt} − F_t μ_t) / dt − c_t),
///   Σ_u = B_t† Σ_s B_t†ᵀ                                                      (5.23),
/// and with ε_u ~ N(0, Σ_u / dt) the state noise B_t dt ε_u has covariance B_t Σ_u B_tᵀ dt, the part of Σ_s dt in
/// the range of B_t. Then F_t Σ_t F_tᵀ + Σ_s dt = Σ_{t+dt}: where F_t − I − dt A_t and Σ_s lie in the range of B_t
/// the distribution is reproduced exactly at every step. For a double integrator the position rows are fixed by the
/// system (q_{t+dt} = q_t + dt q̇_t) and differ from the ProMP's by O(dt²) per step. As dt → 0, F_t = I +
/// dt Ψ̇_tᵀ Σ̃_ω Ψ_t Σ_t⁻¹ + O(dt²) and Σ_s = O(dt) for a ProMP's smooth paths, so K_t tends to the paper's
/// continuous-time K_t = B†(Ψ̇_tᵀ Σ_ω Ψ_t − A_t Σ_t − Σ_s / 2) Σ_t⁻¹ (printed with Ψ̇ on both sides in the thesis) and
/// κ_t to B†(Ψ̇_tᵀ μ_ω − (A_t + B_t K_t) Ψ_tᵀ μ_ω − c_t).
///
/// Regularisation: Σ_t must be invertible; it is computed from Σ̃_ω = Σ_ω + λ I (λ = `regularisation`), the
/// covariance of a slightly wider ProMP, so Σ_t, C_t and Σ_{t+dt} stay one consistent Gaussian process and Σ_s
/// stays positive semidefinite. Σ_t is then positive definite wherever the position and velocity bases are
/// independent; ProMp::fit's covariance_prior already plays this role, so λ may be 0 for a fitted ProMP.
///
/// Steps k = 0 … steps() − 1 at t = k dt, phase z = t / duration (clamped to 1), steps() = round(duration / dt).
class ProMpController {
 public:
  /// `systems` holds one linearisation for all steps, or one per step.
  /// \throws std::invalid_argument for dt ≤ 0 or larger than the ProMP's duration, λ < 0 or non-finite, a
  /// system count other than 1 or steps(), matrices of the wrong size or with non-finite entries, unequal input
  /// counts, a zero B_t, or a Σ_t that is not positive definite (the message names the step; raise λ).
  ProMpController(const ProMp& promp, const std::vector<LinearisedSystem>& systems, double dt,
                  double regularisation = 1e-9);

  int steps() const noexcept { return static_cast<int>(gains_.size()); }
  double dt() const noexcept { return dt_; }
  int stateSize() const noexcept { return static_cast<int>(gains_.front().cols()); }
  int inputs() const noexcept { return static_cast<int>(gains_.front().rows()); }
  /// K_t, κ_t and Σ_u of a step. \throws std::out_of_range for a step outside [0, steps()).
  const Eigen::MatrixXd& gain(int step) const { return gains_.at(static_cast<std::size_t>(step)); }
  const Eigen::VectorXd& offset(int step) const { return offsets_.at(static_cast<std::size_t>(step)); }
  const Eigen::MatrixXd& inputCovariance(int step) const {
    return input_covariances_.at(static_cast<std::size_t>(step));
  }

  /// Mean command u = K_t y + κ_t of a step (5.20 without ε_u). Returns OutOfSchedule, WrongSize or NotFinite
  /// (u unchanged) for a bad step, sizes or state. Real-time safe: no allocation, no exceptions.
  [[nodiscard]] ProMpControlStatus command(int step, const Eigen::Ref<const Eigen::VectorXd>& state,
                                           Eigen::Ref<Eigen::VectorXd> u) const noexcept;
  /// Stochastic command u = K_t y + κ_t + ε_u (5.20), ε_u ~ N(0, Σ_u / dt) drawn from `rng` through a factor of
  /// Σ_u / dt computed at construction. Statuses as the mean command. Real-time safe: no allocation, no exceptions.
  [[nodiscard]] ProMpControlStatus command(int step, const Eigen::Ref<const Eigen::VectorXd>& state, std::mt19937& rng,
                                           Eigen::Ref<Eigen::VectorXd> u) const noexcept;

 private:
  double dt_;
  std::vector<Eigen::MatrixXd> gains_, input_covariances_, noise_factors_;
  std::vector<Eigen::VectorXd> offsets_;
};

}  // namespace bimanual_skills::primitives
