#include "bimanual_skills/learning/pi2.hpp"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <stdexcept>

namespace bimanual_skills::learning {

void Pi2Parameters::validate() const {
  if (!(h > 0.0) || !(control_cost >= 0.0) || !(minimum_eigenvalue >= 0.0)) {
    throw std::invalid_argument("Pi2Parameters: need h > 0, control_cost >= 0, minimum_eigenvalue >= 0");
  }
}

Pi2Update pi2Update(const Pi2Parameters& parameters, const Eigen::VectorXd& mean, const Eigen::MatrixXd& covariance,
                    const Eigen::MatrixXd& samples, const Eigen::MatrixXd& costs, const Eigen::MatrixXd& basis) {
  parameters.validate();
  const Eigen::Index K = samples.rows(), steps = basis.rows(), B = basis.cols();
  const Eigen::Index P = mean.size();
  if (K < 2 || B < 1 || P % B != 0 || samples.cols() != P || costs.rows() != K || costs.cols() != steps ||
      covariance.rows() != P || covariance.cols() != P || !samples.allFinite() || !costs.allFinite() ||
      !basis.allFinite() || !mean.allFinite() || !covariance.allFinite() || steps < 1) {
    throw std::invalid_argument(
        "pi2Update: need >= 2 rollouts, samples K x (DoF x kernels), costs K x steps, basis steps x kernels, "
        "a matching mean and covariance, all finite");
  }
  const Eigen::Index dofs = P / B;
  const Eigen::MatrixXd noise = samples.rowwise() - mean.transpose();
  // (M_{t_j} ε_k)_d = g_j (g_jᵀ ε_{k,d}) / (g_jᵀ g_j): the projection of each DoF's noise on the step's basis.
  const Eigen::VectorXd basis_norm = basis.rowwise().squaredNorm().cwiseMax(1e-300);
  Eigen::MatrixXd cost_to_go = Eigen::MatrixXd::Zero(K, steps);
  for (Eigen::Index k = 0; k < K; ++k) {
    double to_go = 0.0, control = 0.0;
    for (Eigen::Index i = steps - 1; i >= 0; --i) {
      to_go += costs(k, i);
      cost_to_go(k, i) = to_go + control;
      if (parameters.control_cost > 0.0) {  // the j > i sum of (5.9): add step i for the steps before it
        double quadratic = 0.0;
        for (Eigen::Index d = 0; d < dofs; ++d) {
          const double projection = basis.row(i).dot(noise.row(k).segment(d * B, B)) / basis_norm[i];
          quadratic += (mean.segment(d * B, B) + projection * basis.row(i).transpose()).squaredNorm();
        }
        control += 0.5 * parameters.control_cost * quadratic;
      }
    }
  }
  Pi2Update out;
  out.probabilities.resize(steps, K);
  Eigen::VectorXd delta = Eigen::VectorXd::Zero(P);
  Eigen::MatrixXd new_covariance = Eigen::MatrixXd::Zero(P, P);
  double time_weights = 0.0;
  for (Eigen::Index i = 0; i < steps; ++i) {
    const Eigen::VectorXd S = cost_to_go.col(i);
    const double spread = S.maxCoeff() - S.minCoeff();
    const Eigen::ArrayXd e = spread > 0.0 ? Eigen::ArrayXd((-parameters.h * (S.array() - S.minCoeff()) / spread).exp())
                                          : Eigen::ArrayXd::Ones(K);
    const Eigen::VectorXd p = (e / e.sum()).matrix();
    out.probabilities.row(i) = p.transpose();
    const auto time_weight = static_cast<double>(steps - i);
    time_weights += time_weight;
    const Eigen::VectorXd weighted_noise = noise.transpose() * p;  // Σ_k P ε_k, then projected per DoF (5.11)
    for (Eigen::Index d = 0; d < dofs; ++d) {
      const double projection = basis.row(i).dot(weighted_noise.segment(d * B, B)) / basis_norm[i];
      delta.segment(d * B, B) += time_weight * projection * basis.row(i).transpose();
    }
    if (parameters.covariance_adaptation) {
      new_covariance.noalias() += time_weight * noise.transpose() * p.asDiagonal() * noise;
    }
  }
  out.mean = mean + delta / time_weights;  // (5.12), (5.13)
  if (parameters.covariance_adaptation) {
    new_covariance /= time_weights;
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(0.5 * (new_covariance + new_covariance.transpose()));
    const Eigen::VectorXd bounded = eigen.eigenvalues().cwiseMax(parameters.minimum_eigenvalue);
    out.covariance = eigen.eigenvectors() * bounded.asDiagonal() * eigen.eigenvectors().transpose();
  } else {
    out.covariance = covariance;
  }
  return out;
}

}  // namespace bimanual_skills::learning
