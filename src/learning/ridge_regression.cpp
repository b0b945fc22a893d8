#include "bimanual_skills/learning/ridge_regression.hpp"

#include <Eigen/Cholesky>

#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::learning {

Eigen::MatrixXd ridgeLeastSquares(const Eigen::MatrixXd& X, const Eigen::MatrixXd& Y, double ridge, int unpenalised) {
  if (X.rows() != Y.rows() || X.cols() < 1 || Y.cols() < 1 || unpenalised < 0 || unpenalised > X.cols()) {
    throw std::invalid_argument("ridgeLeastSquares: X (" + std::to_string(X.rows()) + " x " + std::to_string(X.cols()) +
                                ") and Y (" + std::to_string(Y.rows()) + " x " + std::to_string(Y.cols()) +
                                ") need as many rows, and 0 <= unpenalised <= columns of X");
  }
  if (!X.allFinite() || !Y.allFinite() || !(ridge >= 0.0) || !std::isfinite(ridge)) {
    throw std::invalid_argument("ridgeLeastSquares: X, Y and the ridge must be finite, the ridge >= 0");
  }
  Eigen::MatrixXd normal = X.transpose() * X;
  normal.diagonal().tail(X.cols() - unpenalised).array() += ridge;
  const Eigen::LDLT<Eigen::MatrixXd> solver(normal);
  const Eigen::VectorXd& D = solver.vectorD();
  if (solver.info() != Eigen::Success || !(D.minCoeff() > 1e-14 * D.cwiseAbs().maxCoeff())) {
    throw std::invalid_argument(
        "ridgeLeastSquares: the normal matrix is not positive definite (the samples do not determine every "
        "coefficient); raise the ridge");
  }
  return solver.solve(X.transpose() * Y);
}

}  // namespace bimanual_skills::learning
