#include "bimanual_skills/learning/gaussian.hpp"

#include <Eigen/Cholesky>

#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::learning {

Eigen::MatrixXd choleskyFactor(const Eigen::MatrixXd& covariance) {
  const Eigen::LLT<Eigen::MatrixXd> llt(covariance);
  if (covariance.rows() != covariance.cols() || covariance.rows() < 1 || !covariance.allFinite() ||
      llt.info() != Eigen::Success) {
    throw std::invalid_argument("choleskyFactor: the covariance must be square, finite and positive definite");
  }
  return llt.matrixL();
}

Eigen::VectorXd GaussianSampler::draw(const Eigen::VectorXd& mean, const Eigen::MatrixXd& factor, std::mt19937& rng) {
  if (factor.rows() != mean.size() || factor.cols() != mean.size()) {
    throw std::invalid_argument("GaussianSampler: the factor must be " + std::to_string(mean.size()) + " x " +
                                std::to_string(mean.size()));
  }
  Eigen::VectorXd e(mean.size());
  for (Eigen::Index i = 0; i < e.size(); ++i) e[i] = normal_(rng);
  return mean + factor * e;
}

Eigen::MatrixXd GaussianSampler::draw(const Eigen::VectorXd& mean, const Eigen::MatrixXd& factor, int count,
                                      std::mt19937& rng) {
  if (count < 0) throw std::invalid_argument("GaussianSampler: count must be >= 0");
  Eigen::MatrixXd out(count, mean.size());
  for (int k = 0; k < count; ++k) out.row(k) = draw(mean, factor, rng).transpose();
  return out;
}

void GaussianSampler::addNoise(const Eigen::Ref<const Eigen::MatrixXd>& factor, Eigen::Ref<Eigen::VectorXd> out,
                               std::mt19937& rng) noexcept {
  for (Eigen::Index j = 0; j < factor.cols(); ++j) out += factor.col(j) * normal_(rng);
}

std::pair<Eigen::VectorXd, Eigen::MatrixXd> weightedGaussian(const Eigen::MatrixXd& samples,
                                                             const Eigen::VectorXd& weights, double regularisation) {
  Eigen::VectorXd mean = samples.transpose() * weights;
  const Eigen::MatrixXd centred = samples.rowwise() - mean.transpose();
  Eigen::MatrixXd covariance = centred.transpose() * weights.asDiagonal() * centred;
  covariance.diagonal().array() += regularisation;
  return {std::move(mean), std::move(covariance)};
}

std::pair<Eigen::VectorXd, Eigen::MatrixXd> sampleMoments(const Eigen::MatrixXd& samples) {
  if (samples.rows() < 1) throw std::invalid_argument("sampleMoments: needs at least one sample");
  Eigen::VectorXd mean = samples.colwise().mean().transpose();
  const Eigen::MatrixXd centred = samples.rowwise() - mean.transpose();
  Eigen::MatrixXd covariance = centred.transpose() * centred / static_cast<double>(samples.rows());
  return {std::move(mean), std::move(covariance)};
}

Eigen::VectorXd gaussianLogDensity(const Eigen::MatrixXd& samples, const Eigen::VectorXd& mean,
                                   const Eigen::MatrixXd& covariance) {
  const Eigen::LLT<Eigen::MatrixXd> llt(covariance);
  if (llt.info() != Eigen::Success || covariance.rows() != mean.size() || samples.cols() != mean.size()) {
    throw std::invalid_argument("gaussianLogDensity: the covariance must be positive definite, sizes consistent");
  }
  const Eigen::MatrixXd whitened = llt.matrixL().solve((samples.rowwise() - mean.transpose()).transpose());
  const double log_det = 2.0 * llt.matrixL().toDenseMatrix().diagonal().array().log().sum();
  const double constant = -0.5 * (static_cast<double>(mean.size()) * std::log(2.0 * M_PI) + log_det);
  return (constant - 0.5 * whitened.colwise().squaredNorm().array()).matrix().transpose();
}

double gaussianKl(const Eigen::VectorXd& mean_p, const Eigen::MatrixXd& covariance_p, const Eigen::VectorXd& mean_q,
                  const Eigen::MatrixXd& covariance_q) {
  const Eigen::Index k = mean_p.size();
  if (k < 1 || mean_q.size() != k || covariance_p.rows() != k || covariance_p.cols() != k || covariance_q.rows() != k ||
      covariance_q.cols() != k) {
    throw std::invalid_argument("gaussianKl: means of one size k and k x k covariances needed");
  }
  const Eigen::LLT<Eigen::MatrixXd> p(covariance_p), q(covariance_q);
  if (p.info() != Eigen::Success || q.info() != Eigen::Success) {
    throw std::invalid_argument("gaussianKl: both covariances must be positive definite");
  }
  const auto logDet = [](const Eigen::LLT<Eigen::MatrixXd>& llt) {
    return 2.0 * llt.matrixLLT().diagonal().array().log().sum();
  };
  const Eigen::VectorXd difference = mean_q - mean_p;
  const double trace = q.solve(covariance_p).trace();
  const double mahalanobis = difference.dot(q.solve(difference));
  return 0.5 * (trace + mahalanobis - static_cast<double>(k) + logDet(q) - logDet(p));
}

}  // namespace bimanual_skills::learning
