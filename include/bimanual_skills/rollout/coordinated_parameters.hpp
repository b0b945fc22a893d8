/// \file
/// A coordinated DMP policy (primitives::DrDmp: N_s coordination matrices and latent weights) as one parameter
/// vector, so that any evaluator (threads, rollout workers, a robot) can run it unchanged: [N_s, r, ω (r × n, latent
/// DoF by latent DoF), vec(Ω_1), …, vec(Ω_Ns)] with each Ω_s (d × r) column by column. Target bimanual_skills_rollout.
#pragma once

#include <Eigen/Core>

#include <vector>

namespace bimanual_skills::rollout {

Eigen::VectorXd encodeCoordinatedPolicy(const std::vector<Eigen::MatrixXd>& coordination,
                                        const Eigen::VectorXd& weights);

/// The inverse of encodeCoordinatedPolicy(); false when `parameters` holds no policy of `dofs` DoF and `basis`
/// weights per latent DoF (1 ≤ N_s ≤ 20, 1 ≤ r ≤ dofs, sizes that fit, finite counts).
bool decodeCoordinatedPolicy(const Eigen::VectorXd& parameters, int dofs, int basis,
                             std::vector<Eigen::MatrixXd>& coordination, Eigen::VectorXd& weights);

}  // namespace bimanual_skills::rollout
