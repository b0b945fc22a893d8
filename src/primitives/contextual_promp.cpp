#include "bimanual_skills/primitives/contextual_promp.hpp"

#include "bimanual_skills/learning/ridge_regression.hpp"

#include <stdexcept>
#include <string>

namespace bimanual_skills::primitives {

ContextualProMp::ContextualProMp(const ProMpParameters& parameters, int dofs, const Eigen::VectorXd& mean,
                                 const Eigen::MatrixXd& context_gain, const Eigen::MatrixXd& covariance,
                                 const Eigen::VectorXd& observation_variance, double duration)
    : base_(parameters, dofs, mean, covariance, observation_variance, duration), context_gain_(context_gain) {
  if (context_gain_.rows() != mean.size() || context_gain_.cols() < 1 || !context_gain_.allFinite()) {
    throw std::invalid_argument(
        "ContextualProMp: the context gain K_omega must be finite, with dofs*kernels rows and at least one column");
  }
}

ContextualProMp ContextualProMp::fit(const ProMpParameters& parameters,
                                     const std::vector<Eigen::MatrixXd>& demonstrations,
                                     const std::vector<Eigen::VectorXd>& contexts, double duration) {
  if (demonstrations.size() < 2) throw std::invalid_argument("ContextualProMp::fit: needs at least 2 demonstrations");
  if (contexts.size() != demonstrations.size()) {
    throw std::invalid_argument("ContextualProMp::fit: needs one context per demonstration");
  }
  const Eigen::Index contexts_size = contexts.front().size();
  for (std::size_t d = 0; d < contexts.size(); ++d) {
    if (contexts[d].size() != contexts_size || contexts_size < 1 || !contexts[d].allFinite()) {
      throw std::invalid_argument("ContextualProMp::fit: context " + std::to_string(d + 1) +
                                  " must be finite, non-empty and of the same size as the first");
    }
  }
  const DemonstrationWeights fitted = ProMp::demonstrationWeights(parameters, demonstrations);
  const auto samples = static_cast<Eigen::Index>(demonstrations.size());
  Eigen::MatrixXd X(samples, contexts_size + 1);
  for (Eigen::Index d = 0; d < samples; ++d) {
    X(d, 0) = 1.0;
    X.row(d).tail(contexts_size) = contexts[static_cast<std::size_t>(d)].transpose();
  }
  Eigen::MatrixXd coefficients;  // (M+1) × n: the mean, then K_omega transposed; the mean is not penalised
  try {
    coefficients = learning::ridgeLeastSquares(X, fitted.weights.transpose(), parameters.context_ridge, 1);
  } catch (const std::invalid_argument&) {
    throw std::invalid_argument(
        "ContextualProMp::fit: the contexts do not determine K_omega (collinear or too few demonstrations); "
        "raise context_ridge");
  }
  const Eigen::MatrixXd residuals = fitted.weights.transpose() - X * coefficients;  // samples × n
  Eigen::MatrixXd covariance = residuals.transpose() * residuals / static_cast<double>(samples);
  covariance.diagonal().array() += parameters.covariance_prior;
  return ContextualProMp(parameters, static_cast<int>(demonstrations.front().cols()), coefficients.row(0).transpose(),
                         coefficients.bottomRows(contexts_size).transpose(), covariance, fitted.observation_variance,
                         duration);
}

ProMp ContextualProMp::forContext(const Eigen::VectorXd& context) const {
  if (context.size() != context_gain_.cols() || !context.allFinite()) {
    throw std::invalid_argument("ContextualProMp::forContext: the context must have " +
                                std::to_string(context_gain_.cols()) + " finite entries");
  }
  return base_.withMean(base_.weightMean() + context_gain_ * context);
}

}  // namespace bimanual_skills::primitives
