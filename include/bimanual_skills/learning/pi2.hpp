/// \file
/// Policy improvement with path integrals (thesis eqs. 5.8–5.13; Theodorou, Buchli and Schaal 2010) for policies
/// linear in basis functions, such as DMP weights, and PI2-CMA (Stulp and Sigaud 2012), which adapts the exploration
/// covariance from the same probabilities. Target bimanual_skills_learning. Off the control loop.
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::learning {

struct Pi2Parameters {
  double h = 10.0;            ///< P ∝ exp(−h (S − min S) / (max S − min S)): 1/λ of (5.10), normalised.
  double control_cost = 0.0;  ///< R = control_cost · I, the (μ + M ε)ᵀ R (μ + M ε) term of (5.9).
  bool covariance_adaptation = false;  ///< PI2-CMA: also update Σ from the probabilities.
  double minimum_eigenvalue = 1e-10;   ///< PI2-CMA: the new Σ's eigenvalues are bounded below by this.

  void validate() const;
};

struct Pi2Update {
  Eigen::VectorXd mean;           ///< μ + δω (5.13).
  Eigen::MatrixXd covariance;     ///< PI2-CMA's new Σ, or the given one.
  Eigen::MatrixXd probabilities;  ///< P(τ_{i,k}) (5.10): time steps × rollouts.
};

/// One PI2 update. The policy is ω ∈ R^{D·B} (D DoF of B basis functions each, DoF-major blocks, as Dmp weights
/// row by row); at time step t_i each DoF's output is g(t_i)ᵀ ω_d with the shared basis g (rows of `basis`,
/// time steps × B). `samples` (K × D·B) are the rollouts' parameters ω_k = μ + ε_k, `costs` (K × time steps) their
/// immediate costs r_{t_i,k} with any terminal cost added to the last step (lower is better).
///   M_{t_i} = g gᵀ / (gᵀ g) per DoF (5.8, R ∝ I),
///   S(τ_{i,k}) = Σ_{j≥i} r_{t_j,k} + ½ Σ_{j>i} (μ + M_{t_j} ε_k)ᵀ R (μ + M_{t_j} ε_k)  (5.9),
///   P(τ_{i,k}) = exp(−h S̃_{i,k}) / Σ_k exp(−h S̃_{i,k}), S̃ the costs-to-go normalised to [0, 1] per step (5.10),
///   δω_{t_i} = Σ_k P(τ_{i,k}) M_{t_i} ε_k  (5.11),
///   δω = Σ_i (N − i) δω_{t_i} / Σ_i (N − i)  (5.12), as printed. The original algorithm (Theodorou et al. 2010,
///   Table 2, step 4) also weights each kernel j by its activations g_j(t_i); on the via-point task of ps_benchmark
///   that variant learned worse (docs/RESULTS.md), so the thesis' form is the one implemented.
/// PI2-CMA: Σ' = Σ_i (N − i) Σ_k P(τ_{i,k}) ε_k ε_kᵀ / Σ_i (N − i), eigenvalues bounded below.
/// \throws std::invalid_argument on inconsistent sizes or non-finite values.
Pi2Update pi2Update(const Pi2Parameters& parameters, const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance,
                    const Eigen::MatrixXd& samples, const Eigen::MatrixXd& costs, const Eigen::MatrixXd& basis);

}  // namespace bimanual_skills::learning
