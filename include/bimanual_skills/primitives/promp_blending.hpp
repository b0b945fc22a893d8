/// \file
/// Blending of ProMPs by the product of their state distributions with phase-dependent activations
/// (thesis Sec. 5.2.2, "combination by product"; Paraschos et al. 2013, "Probabilistic Movement Primitives", Sec. 2.2).
#pragma once

#include "bimanual_skills/primitives/promp.hpp"

#include <Eigen/Core>

#include <vector>

namespace bimanual_skills::primitives {

/// A distribution N(μ_t, Σ_t) over the state y_t = [q_t; q̇_t] (positions, then velocities) at a list of phases.
struct TrajectoryDistribution {
  Eigen::VectorXd phases;                    ///< z_t ∈ [0, 1], one per time step.
  std::vector<Eigen::VectorXd> means;        ///< μ_t, 2 dofs each.
  std::vector<Eigen::MatrixXd> covariances;  ///< Σ_t, 2 dofs × 2 dofs each.
};

/// Blends ProMPs by the product of their state distributions weighted by activations α_i(z_t) ≥ 0:
///   Σ_t = (Σ_i α_i(z_t) Σ_{i,t}⁻¹)⁻¹,   μ_t = Σ_t Σ_i α_i(z_t) Σ_{i,t}⁻¹ μ_{i,t},
/// with μ_{i,t} = Ψ_tᵀ μ_ω^i and Σ_{i,t} = Ψ_tᵀ Σ_ω^i Ψ_t the state mean and covariance of ProMP i at phase z_t
/// (without Σ_y; each ProMP's velocities use its own duration). Row t of `activations` (phases × ProMPs) holds the
/// α_i(z_t); ProMPs with α_i = 0 do not enter that step, so their Σ_{i,t} need not be invertible.
/// \throws std::invalid_argument for no ProMPs, unequal DoF, an activation matrix of the wrong size, negative or
/// non-finite activations, a row without a positive activation, non-finite phases, or a Σ_{i,t} with α_i > 0 that is
/// not positive definite.
TrajectoryDistribution blend(const std::vector<ProMp>& promps, const Eigen::VectorXd& phases,
                             const Eigen::MatrixXd& activations);

}  // namespace bimanual_skills::primitives
