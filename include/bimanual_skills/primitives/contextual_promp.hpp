/// \file
/// Contextual ProMP (thesis Sec. 7.1.1): the weight mean depends linearly on a context vector s,
/// p(ω | s) = N(ω | μ_ω + K_ω s, Σ_ω).
#pragma once

#include "bimanual_skills/primitives/promp.hpp"

#include <Eigen/Core>

#include <vector>

namespace bimanual_skills::primitives {

/// A ProMP whose weight mean is μ_ω + K_ω s for a context s ∈ ℝ^M (e.g. a goal or via-point position), with Σ_ω
/// independent of s. forContext(s) gives the ordinary ProMp of one context.
class ContextualProMp {
 public:
  /// `mean` μ_ω and `covariance` Σ_ω as for ProMp, `context_gain` K_ω (dofs·kernels × M, M ≥ 1).
  /// \throws std::invalid_argument as ProMp's constructor, or for a K_ω of the wrong size or with non-finite entries.
  ContextualProMp(const ProMpParameters& parameters, int dofs, const Eigen::VectorXd& mean,
                  const Eigen::MatrixXd& context_gain, const Eigen::MatrixXd& covariance,
                  const Eigen::VectorXd& observation_variance, double duration);

  /// Fit from demonstrations (as ProMp::fit) each with its context s_k: the weights ω_k of every demonstration
  /// (ProMp::demonstrationWeights) are regressed on [1; s_k] by least squares with parameters.context_ridge on
  /// K_ω only, [μ_ω K_ω]ᵀ = (XᵀX + λ diag(0, I))⁻¹ Xᵀ W with rows [1, s_kᵀ] of X and ω_kᵀ of W; Σ_ω is the
  /// maximum-likelihood covariance of the residuals ω_k − μ_ω − K_ω s_k plus parameters.covariance_prior I.
  /// \throws std::invalid_argument for fewer than 2 demonstrations, a context count that differs from the
  /// demonstrations', contexts of unequal or zero size, non-finite data, or contexts that do not determine K_ω
  /// (collinear, or too few demonstrations, with context_ridge = 0).
  static ContextualProMp fit(const ProMpParameters& parameters, const std::vector<Eigen::MatrixXd>& demonstrations,
                             const std::vector<Eigen::VectorXd>& contexts, double duration);

  int dofs() const noexcept { return base_.dofs(); }
  int contextSize() const noexcept { return static_cast<int>(context_gain_.cols()); }
  const ProMpParameters& parameters() const noexcept { return base_.parameters(); }
  double duration() const noexcept { return base_.duration(); }
  const Eigen::VectorXd& weightMean() const noexcept { return base_.weightMean(); }  ///< μ_ω (the mean at s = 0)
  const Eigen::MatrixXd& contextGain() const noexcept { return context_gain_; }      ///< K_ω
  const Eigen::MatrixXd& weightCovariance() const noexcept { return base_.weightCovariance(); }
  const Eigen::VectorXd& observationVariance() const noexcept { return base_.observationVariance(); }

  /// The ProMP of context s: N(μ_ω + K_ω s, Σ_ω).
  /// \throws std::invalid_argument for a context of the wrong size or with non-finite entries.
  ProMp forContext(const Eigen::VectorXd& context) const;

 private:
  ProMp base_;  ///< The ProMP at s = 0.
  Eigen::MatrixXd context_gain_;
};

}  // namespace bimanual_skills::primitives
