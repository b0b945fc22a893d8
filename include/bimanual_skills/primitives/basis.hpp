/// \file
/// The normalised Gaussian basis shared by the DMP forcing term (thesis eq. 5.15) and the ProMP (eq. 5.16).
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::primitives {

/// b_i(s) = φ_i(s) · scale / Σ_k φ_k(s),  φ_i(s) = exp(−½ (s − c_i)² / w_i), into `b` (centres c, variances w; all
/// of one size). scale = 1 gives the ProMP basis in its phase z; scale = x gives the DMP's g(x) (5.15), which fades
/// out with the phase. All zero if every φ_i underflows. Real-time safe: no allocation, no exceptions.
void normalisedGaussianBasis(double s, const Eigen::Ref<const Eigen::VectorXd>& centres,
                             const Eigen::Ref<const Eigen::VectorXd>& variances, double scale,
                             Eigen::Ref<Eigen::VectorXd> b) noexcept;

/// The basis with scale 1 and its derivative db_i/ds = b_i (φ_i'/φ_i − Σ_k φ_k' / Σ_k φ_k), φ_i'/φ_i = −(s − c_i)/w_i.
/// Real-time safe: no allocation, no exceptions.
void normalisedGaussianBasis(double s, const Eigen::Ref<const Eigen::VectorXd>& centres,
                             const Eigen::Ref<const Eigen::VectorXd>& variances, Eigen::Ref<Eigen::VectorXd> b,
                             Eigen::Ref<Eigen::VectorXd> db) noexcept;

}  // namespace bimanual_skills::primitives
