/// \file
/// Ridge-regularised linear least squares, the one solver behind the fits of the DMP forcing term, the ProMP
/// weights and the contextual ProMP. Offline: allocates and throws.
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::learning {

/// W = argmin ‖X W − Y‖² + ridge Σ_{j ≥ unpenalised} ‖W_j·‖² = (XᵀX + ridge D)⁻¹ XᵀY, D the identity with its first
/// `unpenalised` diagonal entries zero (an intercept column left free). X is samples × features, Y samples × outputs;
/// returns features × outputs. Solved by an LDLᵀ factorisation of the normal matrix.
/// \throws std::invalid_argument for inconsistent sizes, non-finite values, ridge < 0, or a normal matrix that is
/// not positive definite (features not determined by the samples: raise the ridge).
Eigen::MatrixXd ridgeLeastSquares(const Eigen::MatrixXd& X, const Eigen::MatrixXd& Y, double ridge,
                                  int unpenalised = 0);

}  // namespace bimanual_skills::learning
