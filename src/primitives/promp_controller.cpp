#include "bimanual_skills/primitives/promp_controller.hpp"

#include "bimanual_skills/learning/gaussian.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::primitives {

LinearisedSystem LinearisedSystem::doubleIntegrator(int dofs) {
  if (dofs < 1) throw std::invalid_argument("LinearisedSystem::doubleIntegrator: dofs must be >= 1");
  LinearisedSystem system{Eigen::MatrixXd::Zero(2 * dofs, 2 * dofs), Eigen::MatrixXd::Zero(2 * dofs, dofs),
                          Eigen::VectorXd::Zero(2 * dofs)};
  system.A.topRightCorner(dofs, dofs).setIdentity();
  system.B.bottomRows(dofs).setIdentity();
  return system;
}

const char* toString(ProMpControlStatus status) noexcept {
  switch (status) {
    case ProMpControlStatus::Success:
      return "Success";
    case ProMpControlStatus::WrongSize:
      return "WrongSize";
    case ProMpControlStatus::NotFinite:
      return "NotFinite";
    case ProMpControlStatus::OutOfSchedule:
      return "OutOfSchedule";
  }
  return "Unknown";
}

ProMpController::ProMpController(const ProMp& promp, const std::vector<LinearisedSystem>& systems, double dt,
                                 double regularisation)
    : dt_(dt) {
  if (!(dt > 0.0) || !(dt <= promp.duration())) {
    throw std::invalid_argument("ProMpController: dt must be > 0 and at most the ProMP's duration");
  }
  if (!(regularisation >= 0.0) || !std::isfinite(regularisation)) {
    throw std::invalid_argument("ProMpController: the regularisation must be finite and >= 0");
  }
  const int steps = std::max(1, static_cast<int>(std::lround(promp.duration() / dt)));
  const auto count = static_cast<int>(systems.size());
  if (count != 1 && count != steps) {
    throw std::invalid_argument("ProMpController: needs 1 linearised system or one per step (" + std::to_string(steps) +
                                "), got " + std::to_string(count));
  }
  const int n = 2 * promp.dofs();
  const Eigen::Index inputs = systems.front().B.cols();
  std::vector<Eigen::MatrixXd> pseudo_inverses;
  for (int s = 0; s < count; ++s) {
    const LinearisedSystem& system = systems[static_cast<std::size_t>(s)];
    if (system.A.rows() != n || system.A.cols() != n || system.B.rows() != n || system.B.cols() != inputs ||
        inputs < 1 || system.c.size() != n) {
      throw std::invalid_argument("ProMpController: system " + std::to_string(s) +
                                  " needs A (2 dofs x 2 dofs), B (2 dofs x inputs, the same inputs for all) and "
                                  "c (2 dofs)");
    }
    if (!system.A.allFinite() || !system.B.allFinite() || !system.c.allFinite()) {
      throw std::invalid_argument("ProMpController: system " + std::to_string(s) + " has non-finite entries");
    }
    const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> decomposition(system.B);
    if (decomposition.rank() == 0) {
      throw std::invalid_argument("ProMpController: B of system " + std::to_string(s) + " is zero");
    }
    pseudo_inverses.push_back(decomposition.pseudoInverse());
  }

  Eigen::MatrixXd weight_covariance = promp.weightCovariance();
  weight_covariance.diagonal().array() += regularisation;
  ProMpData data(promp);
  const auto evaluate = [&](int k, Eigen::MatrixXd& psi, Eigen::VectorXd& mean) {
    if (promp.blockBasis(data, std::min(1.0, k * dt / promp.duration())) != ProMpStatus::Success) {
      throw std::invalid_argument("ProMpController: could not evaluate the ProMP's basis");
    }
    psi = data.psi;
    mean.noalias() = psi.transpose() * promp.weightMean();
  };
  Eigen::MatrixXd psi, psi_next;
  Eigen::VectorXd mean, mean_next;
  evaluate(0, psi, mean);
  const Eigen::MatrixXd identity = Eigen::MatrixXd::Identity(n, n);
  for (int k = 0; k < steps; ++k) {
    evaluate(k + 1, psi_next, mean_next);
    const Eigen::MatrixXd sigma_psi_next = weight_covariance * psi_next;
    const Eigen::MatrixXd Sigma = psi.transpose() * weight_covariance * psi;   // Σ_t
    const Eigen::MatrixXd C = psi.transpose() * sigma_psi_next;                // C_t
    const Eigen::MatrixXd Sigma_next = psi_next.transpose() * sigma_psi_next;  // Σ_{t+dt}
    const Eigen::LLT<Eigen::MatrixXd> llt(Sigma);
    if (llt.info() != Eigen::Success) {
      throw std::invalid_argument("ProMpController: the ProMP's state covariance at step " + std::to_string(k) +
                                  " is not positive definite; raise the regularisation");
    }
    const Eigen::MatrixXd F = llt.solve(C).transpose();  // C_tᵀ Σ_t⁻¹
    Eigen::MatrixXd Sigma_s_dt = Sigma_next - F * C;
    Sigma_s_dt = 0.5 * (Sigma_s_dt + Sigma_s_dt.transpose());
    const LinearisedSystem& system = systems[static_cast<std::size_t>(count == 1 ? 0 : k)];
    const Eigen::MatrixXd& B_pinv = pseudo_inverses[static_cast<std::size_t>(count == 1 ? 0 : k)];
    gains_.push_back(B_pinv * (F - identity - dt * system.A) / dt);
    offsets_.push_back(B_pinv * ((mean_next - F * mean) / dt - system.c));
    Eigen::MatrixXd Sigma_u = B_pinv * (Sigma_s_dt / dt) * B_pinv.transpose();
    Sigma_u = 0.5 * (Sigma_u + Sigma_u.transpose());
    // Factor L of Σ_u / dt (L Lᵀ = Σ_u / dt) from its eigen-decomposition: Σ_u may be only semidefinite.
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(Sigma_u / dt);
    noise_factors_.push_back(eigen.eigenvectors() * eigen.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal());
    input_covariances_.push_back(Sigma_u);
    psi.swap(psi_next);
    mean.swap(mean_next);
  }
}

ProMpControlStatus ProMpController::command(int step, const Eigen::Ref<const Eigen::VectorXd>& state,
                                            Eigen::Ref<Eigen::VectorXd> u) const noexcept {
  if (step < 0 || step >= steps()) return ProMpControlStatus::OutOfSchedule;
  if (state.size() != stateSize() || u.size() != inputs()) return ProMpControlStatus::WrongSize;
  if (!state.allFinite()) return ProMpControlStatus::NotFinite;
  const auto k = static_cast<std::size_t>(step);
  u.noalias() = gains_[k] * state;
  u += offsets_[k];
  return ProMpControlStatus::Success;
}

ProMpControlStatus ProMpController::command(int step, const Eigen::Ref<const Eigen::VectorXd>& state, std::mt19937& rng,
                                            Eigen::Ref<Eigen::VectorXd> u) const noexcept {
  const ProMpControlStatus status = command(step, state, u);
  if (status != ProMpControlStatus::Success) return status;
  learning::GaussianSampler().addNoise(noise_factors_[static_cast<std::size_t>(step)], u, rng);
  return ProMpControlStatus::Success;
}

}  // namespace bimanual_skills::primitives
