#include "bimanual_skills/learning/covariance_adaptation.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace bimanual_skills::learning {

namespace {
constexpr double kConditionFloor = 1e-14;  ///< The smallest eigenvalue of C over the largest.
}  // namespace

CovarianceAdaptation CovarianceAdaptation::start(const Eigen::MatrixXd& covariance) {
  if (covariance.rows() != covariance.cols() || covariance.rows() < 1 || !covariance.allFinite() ||
      !(covariance.diagonal().array() > 0.0).all()) {
    throw std::invalid_argument("CovarianceAdaptation: needs a finite square covariance with a positive diagonal");
  }
  CovarianceAdaptation state;
  state.shape = covariance;
  state.step_path = state.shape_path = Eigen::VectorXd::Zero(covariance.rows());
  return state;
}

void CovarianceAdaptation::update(const Eigen::VectorXd& old_mean, const Eigen::VectorXd& new_mean,
                                  const Eigen::MatrixXd& samples, const Eigen::VectorXd& weights) {
  const Eigen::Index n = shape.rows();
  if (old_mean.size() != n || new_mean.size() != n || samples.cols() != n || samples.rows() != weights.size() ||
      step_path.size() != n || shape_path.size() != n || !old_mean.allFinite() || !new_mean.allFinite() ||
      !samples.allFinite() || !weights.allFinite() || (weights.array() < 0.0).any() ||
      std::abs(weights.sum() - 1.0) > 1e-9) {
    throw std::invalid_argument(
        "CovarianceAdaptation::update: needs finite means and samples of the state's dimension and normalised "
        "non-negative weights, one per sample");
  }
  const auto dim = static_cast<double>(n);
  const double mu_eff = 1.0 / weights.squaredNorm();
  // Hansen's default learning rates (the tutorial's Table 1 with α_μ = 2).
  const double c_sigma = (mu_eff + 2.0) / (dim + mu_eff + 5.0);
  const double d_sigma = 1.0 + 2.0 * std::max(0.0, std::sqrt((mu_eff - 1.0) / (dim + 1.0)) - 1.0) + c_sigma;
  const double c_c = (4.0 + mu_eff / dim) / (dim + 4.0 + 2.0 * mu_eff / dim);
  const double c_1 = 2.0 / ((dim + 1.3) * (dim + 1.3) + mu_eff);
  const double c_mu = std::min(1.0 - c_1, 2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((dim + 2.0) * (dim + 2.0) + mu_eff));
  const double expected_norm = std::sqrt(dim) * (1.0 - 1.0 / (4.0 * dim) + 1.0 / (21.0 * dim * dim));

  const Eigen::VectorXd y_w = (new_mean - old_mean) / step_size;
  // C's condition number is kept below 1e14 (as Hansen's reference code does) by lifting all its eigenvalues
  // equally: C can lose rank numerically in directions the reward never selects, and C^{-1/2} must stay finite.
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(shape);
  const double lift = std::max(0.0, kConditionFloor * eigen.eigenvalues().maxCoeff() - eigen.eigenvalues().minCoeff());
  shape.diagonal().array() += lift;
  const Eigen::VectorXd inverse_root = (eigen.eigenvalues().array() + lift).sqrt().inverse().matrix();
  const Eigen::VectorXd whitened =
      eigen.eigenvectors() * inverse_root.asDiagonal() * (eigen.eigenvectors().transpose() * y_w);
  step_path = (1.0 - c_sigma) * step_path + std::sqrt(c_sigma * (2.0 - c_sigma) * mu_eff) * whitened;
  ++generations;
  const double unbiased = step_path.norm() / std::sqrt(1.0 - std::pow(1.0 - c_sigma, 2.0 * generations));
  const bool h_sigma = unbiased < (1.4 + 2.0 / (dim + 1.0)) * expected_norm;
  shape_path = (1.0 - c_c) * shape_path + (h_sigma ? std::sqrt(c_c * (2.0 - c_c) * mu_eff) : 0.0) * y_w;

  const Eigen::MatrixXd y = (samples.rowwise() - old_mean.transpose()) / step_size;
  const Eigen::MatrixXd rank_mu = y.transpose() * weights.asDiagonal() * y;
  const double stalled = h_sigma ? 0.0 : c_c * (2.0 - c_c);
  shape = (1.0 - c_1 - c_mu + c_1 * stalled) * shape + c_1 * shape_path * shape_path.transpose() + c_mu * rank_mu;
  shape = 0.5 * (shape + shape.transpose()).eval();
  step_size *= std::exp((c_sigma / d_sigma) * (step_path.norm() / expected_norm - 1.0));
}

void CovarianceAdaptation::moveTo(const Eigen::MatrixXd& sample_map, const Eigen::MatrixXd& covariance) {
  if (sample_map.cols() != shape.rows() || covariance.rows() != sample_map.rows() ||
      covariance.cols() != sample_map.rows() || !sample_map.allFinite() || !covariance.allFinite()) {
    throw std::invalid_argument("CovarianceAdaptation::moveTo: needs an r' x r map and a finite r' x r' covariance");
  }
  shape = covariance / (step_size * step_size);
  step_path = sample_map * step_path;
  shape_path = sample_map * shape_path;
}

Eigen::VectorXd cmaEsWeights(const Eigen::VectorXd& rewards) {
  const Eigen::Index k = rewards.size(), best = std::max<Eigen::Index>(1, k / 2);
  if (k < 1 || !rewards.allFinite()) throw std::invalid_argument("cmaEsWeights: needs finite rewards");
  std::vector<Eigen::Index> order(static_cast<std::size_t>(k));
  for (Eigen::Index i = 0; i < k; ++i) order[static_cast<std::size_t>(i)] = i;
  std::stable_sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) { return rewards[a] > rewards[b]; });
  Eigen::VectorXd weights = Eigen::VectorXd::Zero(k);
  for (Eigen::Index rank = 0; rank < best; ++rank) {
    weights[order[static_cast<std::size_t>(rank)]] =
        std::log(static_cast<double>(best) + 0.5) - std::log(static_cast<double>(rank) + 1.0);
  }
  return weights / weights.sum();
}

Eigen::VectorXd cmaEsStep(const Eigen::VectorXd& mean, CovarianceAdaptation& adaptation, const Eigen::MatrixXd& samples,
                          const Eigen::VectorXd& rewards) {
  const Eigen::VectorXd weights = cmaEsWeights(rewards);
  const Eigen::VectorXd next = samples.transpose() * weights;
  adaptation.update(mean, next, samples, weights);
  return next;
}

}  // namespace bimanual_skills::learning
