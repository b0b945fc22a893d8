#include "bimanual_skills/primitives/dr_promp_controller.hpp"

#include "bimanual_skills/learning/gaussian.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::primitives {
namespace {

/// Ω_2† = I_2 ⊗ Ω† (2r × 2d).
Eigen::MatrixXd stateProjection(const Eigen::MatrixXd& omega) {
  const Eigen::MatrixXd pinv = Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(omega).pseudoInverse();
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(2 * pinv.rows(), 2 * pinv.cols());
  out.topLeftCorner(pinv.rows(), pinv.cols()) = pinv;
  out.bottomRightCorner(pinv.rows(), pinv.cols()) = pinv;
  return out;
}

/// The latent systems (7.8): A_x = Ω_2† A Ω_2, B_x = Ω_2† B Ω, c_x = Ω_2† c.
std::vector<LinearisedSystem> latentSystems(const Eigen::MatrixXd& omega, const Eigen::MatrixXd& projection,
                                            const std::vector<LinearisedSystem>& systems) {
  const auto d = omega.rows();
  Eigen::MatrixXd omega2 = Eigen::MatrixXd::Zero(2 * d, 2 * omega.cols());
  omega2.topLeftCorner(d, omega.cols()) = omega;
  omega2.bottomRightCorner(d, omega.cols()) = omega;
  std::vector<LinearisedSystem> out;
  for (std::size_t s = 0; s < systems.size(); ++s) {
    const LinearisedSystem& system = systems[s];
    if (system.A.rows() != 2 * d || system.A.cols() != 2 * d || system.B.rows() != 2 * d || system.B.cols() != d ||
        system.c.size() != 2 * d) {
      throw std::invalid_argument(
          "DrProMpController: system " + std::to_string(s) +
          " needs A (2d x 2d), B (2d x d: one input per DoF) and c (2d), d = " + std::to_string(d));
    }
    out.push_back({projection * system.A * omega2, projection * system.B * omega, projection * system.c});
  }
  return out;
}

}  // namespace

DrProMpController::DrProMpController(const DrProMp& promp, const std::vector<LinearisedSystem>& systems, double dt,
                                     double alpha, double regularisation)
    : coordination_(promp.coordination()),
      projection_(primitives::stateProjection(coordination_)),
      latent_(promp.latent(), latentSystems(coordination_, projection_, systems), dt, regularisation) {
  if (!(alpha >= 0.0) || !std::isfinite(alpha)) throw std::invalid_argument("DrProMpController: alpha must be >= 0");
  for (int k = 0; k < steps(); ++k) {
    Eigen::MatrixXd Sigma_u = coordination_ * latent_.inputCovariance(k) * coordination_.transpose();
    Sigma_u.diagonal().array() += alpha * alpha;
    Sigma_u = 0.5 * (Sigma_u + Sigma_u.transpose());
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(Sigma_u / dt);
    noise_factors_.push_back(eigen.eigenvectors() * eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal());
    input_covariances_.push_back(std::move(Sigma_u));
  }
}

ProMpControlStatus DrProMpController::command(DrProMpControllerData& data, int step,
                                              const Eigen::Ref<const Eigen::VectorXd>& state,
                                              Eigen::Ref<Eigen::VectorXd> u) const noexcept {
  if (step < 0 || step >= steps()) return ProMpControlStatus::OutOfSchedule;
  if (state.size() != projection_.cols() || u.size() != dofs() || data.latent_state.size() != projection_.rows() ||
      data.latent_input.size() != latentDims()) {
    return ProMpControlStatus::WrongSize;
  }
  if (!state.allFinite()) return ProMpControlStatus::NotFinite;
  data.latent_state.noalias() = projection_ * state;
  const ProMpControlStatus status = latent_.command(step, data.latent_state, data.latent_input);
  if (status != ProMpControlStatus::Success) return status;
  u.noalias() = coordination_ * data.latent_input;
  return ProMpControlStatus::Success;
}

ProMpControlStatus DrProMpController::command(DrProMpControllerData& data, int step,
                                              const Eigen::Ref<const Eigen::VectorXd>& state, std::mt19937& rng,
                                              Eigen::Ref<Eigen::VectorXd> u) const noexcept {
  const ProMpControlStatus status = command(data, step, state, u);
  if (status != ProMpControlStatus::Success) return status;
  learning::GaussianSampler().addNoise(noise_factors_[static_cast<std::size_t>(step)], u, rng);
  return ProMpControlStatus::Success;
}

DrProMpControllerData::DrProMpControllerData(const DrProMpController& controller)
    : latent_state(Eigen::VectorXd::Zero(2 * controller.latentDims())),
      latent_input(Eigen::VectorXd::Zero(controller.latentDims())) {}

}  // namespace bimanual_skills::primitives
