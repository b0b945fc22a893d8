/// \file
/// Multivariate Gaussians shared by the primitives and the policy-search updates: drawing samples of N(μ, L Lᵀ),
/// sample and weighted moments, log densities. Offline unless marked real-time safe.
#pragma once

#include <Eigen/Core>

#include <random>
#include <utility>

namespace bimanual_skills::learning {

/// Lower Cholesky factor L of a covariance (L Lᵀ = Σ). \throws std::invalid_argument unless Σ is square, finite and
/// positive definite.
Eigen::MatrixXd choleskyFactor(const Eigen::MatrixXd& covariance);

/// Draws of N(μ, L Lᵀ) from an injected generator. The standard normal it draws e ~ N(0, I) from is a member, so a
/// sampler kept across calls continues one stream of normals (std::normal_distribution produces them in pairs).
class GaussianSampler {
 public:
  /// θ = μ + L e, the entries of e drawn in order. \throws std::invalid_argument for inconsistent sizes.
  Eigen::VectorXd draw(const Eigen::VectorXd& mean, const Eigen::MatrixXd& factor, std::mt19937& rng);
  /// `count` draws as the rows of a count × dim matrix (each row one draw(), in order).
  Eigen::MatrixXd draw(const Eigen::VectorXd& mean, const Eigen::MatrixXd& factor, int count, std::mt19937& rng);
  /// out += L e, accumulated column by column. Real-time safe: no allocation, no exceptions (sizes are the
  /// caller's: out.size() == L.rows()).
  void addNoise(const Eigen::Ref<const Eigen::MatrixXd>& factor, Eigen::Ref<Eigen::VectorXd> out,
                std::mt19937& rng) noexcept;
  /// One standard normal draw.
  double standardNormal(std::mt19937& rng) noexcept { return normal_(rng); }

 private:
  std::normal_distribution<double> normal_{0.0, 1.0};
};

/// Weighted maximum-likelihood Gaussian of the rows of `samples` with normalised `weights`:
/// μ = Σ p_k θ_k, Σ = Σ p_k (θ_k − μ)(θ_k − μ)ᵀ + regularisation·I.
std::pair<Eigen::VectorXd, Eigen::MatrixXd> weightedGaussian(const Eigen::MatrixXd& samples,
                                                             const Eigen::VectorXd& weights, double regularisation);

/// Sample mean and (biased, 1/N) covariance of the rows of `samples`: the maximum-likelihood Gaussian.
/// \throws std::invalid_argument for no samples.
std::pair<Eigen::VectorXd, Eigen::MatrixXd> sampleMoments(const Eigen::MatrixXd& samples);

/// log N(θ_k | μ, Σ) for every row θ_k of `samples`. \throws std::invalid_argument if Σ is not positive definite.
Eigen::VectorXd gaussianLogDensity(const Eigen::MatrixXd& samples, const Eigen::VectorXd& mean,
                                   const Eigen::MatrixXd& covariance);

/// KL(N(μ_p, Σ_p) ‖ N(μ_q, Σ_q)) = ½ [tr(Σ_q⁻¹ Σ_p) + (μ_q − μ_p)ᵀ Σ_q⁻¹ (μ_q − μ_p) − k + ln(|Σ_q| / |Σ_p|)], k the
/// dimension. \throws std::invalid_argument for inconsistent sizes or covariances that are not positive definite.
double gaussianKl(const Eigen::VectorXd& mean_p, const Eigen::MatrixXd& covariance_p, const Eigen::VectorXd& mean_q,
                  const Eigen::MatrixXd& covariance_q);

}  // namespace bimanual_skills::learning
