#include "bimanual_skills/primitives/dr_promp.hpp"

#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::primitives {
namespace {

/// Checks the full-space parameters against the latent ProMP's size; returns the latent ProMP.
ProMp latentProMp(const ProMpParameters& parameters, const Eigen::MatrixXd& coordination, const Eigen::VectorXd& mean,
                  const Eigen::MatrixXd& covariance, const Eigen::MatrixXd& observation_covariance, double duration,
                  const Eigen::MatrixXd& context_gain) {
  const auto d = coordination.rows(), r = coordination.cols();
  if (d < 1 || r < 1 || r > d || !coordination.allFinite()) {
    throw std::invalid_argument("DrProMp: the coordination matrix must be finite, d x r with 1 <= r <= d");
  }
  if (Eigen::ColPivHouseholderQR<Eigen::MatrixXd>(coordination).rank() < r) {
    throw std::invalid_argument("DrProMp: the coordination matrix must have full column rank");
  }
  if (observation_covariance.rows() != d || observation_covariance.cols() != d || !observation_covariance.allFinite() ||
      (observation_covariance - observation_covariance.transpose()).cwiseAbs().maxCoeff() >
          1e-9 * (1.0 + observation_covariance.cwiseAbs().maxCoeff())) {
    throw std::invalid_argument("DrProMp: Sigma_y must be a finite symmetric d x d matrix");
  }
  if (context_gain.cols() > 0 && (context_gain.rows() != mean.size() || !context_gain.allFinite())) {
    throw std::invalid_argument("DrProMp: K_w must have r*kernels rows and finite entries");
  }
  return ProMp(parameters, static_cast<int>(r), mean, covariance, Eigen::VectorXd::Zero(r), duration);
}

}  // namespace

void DrProMpParameters::validate() const {
  promp.validate();
  em.validate();
  if (latent_dims < 1) throw std::invalid_argument("DrProMpParameters: latent_dims must be >= 1");
}

DrProMp::DrProMp(const ProMpParameters& parameters, const Eigen::MatrixXd& coordination, const Eigen::VectorXd& mean,
                 const Eigen::MatrixXd& covariance, const Eigen::MatrixXd& observation_covariance, double duration,
                 const Eigen::MatrixXd& context_gain)
    : latent_(latentProMp(parameters, coordination, mean, covariance, observation_covariance, duration, context_gain)),
      coordination_(coordination),
      observation_covariance_(observation_covariance),
      context_gain_(context_gain.cols() > 0 ? context_gain : Eigen::MatrixXd(mean.size(), 0)) {}

DrProMp::DrProMp(const ProMpParameters& parameters, const learning::LatentTrajectoryModel& model, double duration)
    : DrProMp(parameters, model.coordination, model.mean, model.covariance, model.noise, duration, model.context_gain) {
}

learning::CoordinationGrid DrProMp::grid(const ProMpParameters& parameters, int samples) {
  parameters.validate();
  if (samples < 2) throw std::invalid_argument("DrProMp::grid: needs at least 2 samples");
  const int k = parameters.kernels;
  const ProMp shape(parameters, 1, Eigen::VectorXd::Zero(k), Eigen::MatrixXd::Zero(k, k), Eigen::VectorXd::Zero(1),
                    1.0);
  Eigen::MatrixXd basis(samples, k);
  Eigen::VectorXd b(k), db(k);
  for (int t = 0; t < samples; ++t) {
    shape.basis(static_cast<double>(t) / (samples - 1), b, db);
    basis.row(t) = b.transpose();
  }
  return learning::CoordinationGrid(basis);
}

DrProMp DrProMp::fit(const DrProMpParameters& parameters, const std::vector<Eigen::MatrixXd>& demonstrations,
                     double duration, const Eigen::VectorXd& weights, const Eigen::MatrixXd& contexts,
                     std::vector<double>* log_likelihood) {
  parameters.validate();
  if (demonstrations.empty()) throw std::invalid_argument("DrProMp::fit: no demonstrations");
  const auto count = static_cast<Eigen::Index>(demonstrations.size());
  const learning::CoordinationGrid grid =
      DrProMp::grid(parameters.promp, static_cast<int>(demonstrations.front().rows()));
  const learning::WeightedTrajectories data{demonstrations,
                                            weights.size() == 0 ? Eigen::VectorXd::Ones(count) : weights,
                                            contexts.size() == 0 ? Eigen::MatrixXd(count, 0) : contexts};
  learning::LatentPcaParameters pca;
  pca.ridge = parameters.promp.ridge;
  pca.covariance_prior = parameters.promp.covariance_prior;
  pca.noise_floor = std::max(parameters.em.noise_floor, 1e-12);
  const learning::LatentTrajectoryModel initial = learning::latentPcaModel(grid, data, parameters.latent_dims, pca);
  const learning::LatentEmResult result = learning::latentEm(grid, data, initial, parameters.em);
  if (log_likelihood != nullptr) *log_likelihood = result.log_likelihood;
  return DrProMp(parameters.promp, result.model, duration);
}

learning::LatentTrajectoryModel DrProMp::model() const {
  return {coordination_, latent_.weightMean(), latent_.weightCovariance(), observation_covariance_, context_gain_};
}

DrProMp DrProMp::forContext(const Eigen::VectorXd& context) const {
  if (context.size() != context_gain_.cols() || !context.allFinite()) {
    throw std::invalid_argument("DrProMp::forContext: the context needs " + std::to_string(context_gain_.cols()) +
                                " finite entries");
  }
  return DrProMp(parameters(), coordination_, latent_.weightMean() + context_gain_ * context,
                 latent_.weightCovariance(), observation_covariance_, duration());
}

ProMp DrProMp::fullProMp() const {
  const int n = kernels(), d = dofs(), r = latentDims();
  Eigen::MatrixXd T = Eigen::MatrixXd::Zero(d * n, r * n);  // Ω ⊗ I_n
  for (int j = 0; j < d; ++j) {
    for (int i = 0; i < r; ++i) T.block(j * n, i * n, n, n).diagonal().setConstant(coordination_(j, i));
  }
  Eigen::MatrixXd covariance = T * latent_.weightCovariance() * T.transpose();
  covariance = 0.5 * (covariance + covariance.transpose());
  return ProMp(parameters(), d, T * latent_.weightMean(), covariance, observation_covariance_.diagonal(), duration());
}

Eigen::MatrixXd DrProMp::trajectory(const Eigen::VectorXd& weights, int samples,
                                    const Eigen::MatrixXd& coordination) const {
  const Eigen::MatrixXd& omega = coordination.size() == 0 ? coordination_ : coordination;
  if (omega.rows() != coordination_.rows() || omega.cols() != coordination_.cols()) {
    throw std::invalid_argument("DrProMp::trajectory: the coordination matrix must be d x r");
  }
  return learning::coordinatedValues(grid(parameters(), samples), {omega}, weights);
}

ProMpStatus DrProMp::mean(DrProMpData& data, double z, Eigen::Ref<Eigen::VectorXd> position,
                          Eigen::Ref<Eigen::VectorXd> velocity) const noexcept {
  if (position.size() != dofs() || velocity.size() != dofs() || data.latent_position.size() != latentDims() ||
      data.latent_velocity.size() != latentDims()) {
    return ProMpStatus::WrongSize;
  }
  const ProMpStatus status = latent_.mean(data.latent, z, data.latent_position, data.latent_velocity);
  if (status != ProMpStatus::Success) return status;
  position.noalias() = coordination_ * data.latent_position;
  velocity.noalias() = coordination_ * data.latent_velocity;
  return ProMpStatus::Success;
}

ProMpStatus DrProMp::stateCovariance(DrProMpData& data, double z, Eigen::Ref<Eigen::MatrixXd> out) const noexcept {
  const int d = dofs(), r = latentDims();
  if (out.rows() != 2 * d || out.cols() != 2 * d || data.latent_covariance.rows() != 2 * r ||
      data.latent_covariance.cols() != 2 * r || data.mapped.rows() != d || data.mapped.cols() != r) {
    return ProMpStatus::WrongSize;
  }
  const ProMpStatus status = latent_.stateCovariance(data.latent, z, data.latent_covariance);
  if (status != ProMpStatus::Success) return status;
  for (int a = 0; a < 2; ++a) {
    for (int b = 0; b < 2; ++b) {
      data.mapped.noalias() = coordination_ * data.latent_covariance.block(a * r, b * r, r, r);
      out.block(a * d, b * d, d, d).noalias() = data.mapped * coordination_.transpose();
    }
  }
  return ProMpStatus::Success;
}

DrProMpData::DrProMpData(const DrProMp& promp)
    : latent(promp.latent()),
      latent_position(Eigen::VectorXd::Zero(promp.latentDims())),
      latent_velocity(Eigen::VectorXd::Zero(promp.latentDims())),
      latent_covariance(Eigen::MatrixXd::Zero(2 * promp.latentDims(), 2 * promp.latentDims())),
      mapped(Eigen::MatrixXd::Zero(promp.dofs(), promp.latentDims())) {}

}  // namespace bimanual_skills::primitives
