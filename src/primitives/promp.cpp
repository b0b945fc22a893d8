#include "bimanual_skills/primitives/promp.hpp"

#include "bimanual_skills/learning/gaussian.hpp"
#include "bimanual_skills/learning/ridge_regression.hpp"
#include "bimanual_skills/primitives/basis.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::primitives {

const char* toString(ProMpStatus status) noexcept {
  switch (status) {
    case ProMpStatus::Success:
      return "success";
    case ProMpStatus::WrongSize:
      return "an output or the evaluation data has the wrong size";
    case ProMpStatus::NotFinite:
      return "the phase is NaN or Inf";
  }
  return "unknown status";
}

void ProMpParameters::validate() const {
  if (kernels < 2) throw std::invalid_argument("ProMpParameters: kernels must be >= 2");
  if (!(width >= 0.0) || !(ridge >= 0.0) || !(covariance_prior >= 0.0) || !(context_ridge >= 0.0)) {
    throw std::invalid_argument("ProMpParameters: width, ridge, covariance_prior and context_ridge must be >= 0");
  }
}

ProMp::ProMp(const ProMpParameters& parameters, int dofs, const Eigen::VectorXd& mean,
             const Eigen::MatrixXd& covariance, const Eigen::VectorXd& observation_variance, double duration)
    : parameters_(parameters),
      dofs_(dofs),
      mean_(mean),
      observation_variance_(observation_variance),
      covariance_(covariance),
      duration_(duration) {
  parameters_.validate();
  const int n = dofs * parameters_.kernels;
  if (dofs < 1 || mean_.size() != n || covariance_.rows() != n || covariance_.cols() != n ||
      observation_variance_.size() != dofs) {
    throw std::invalid_argument(
        "ProMp: mean needs dofs*kernels entries, the covariance that square size, and the "
        "observation variance dofs entries");
  }
  if (!mean_.allFinite() || !covariance_.allFinite() || !observation_variance_.allFinite() || !(duration_ > 0.0)) {
    throw std::invalid_argument("ProMp: parameters must be finite and the duration > 0");
  }
  if ((covariance_ - covariance_.transpose()).cwiseAbs().maxCoeff() >
      1e-9 * (1.0 + covariance_.cwiseAbs().maxCoeff())) {
    throw std::invalid_argument("ProMp: the weight covariance must be symmetric");
  }
  const int k = parameters_.kernels;
  centres_ = Eigen::VectorXd::LinSpaced(k, 0.0, 1.0);
  const double spacing = 1.0 / (k - 1);
  widths_ = Eigen::VectorXd::Constant(k, parameters_.width > 0.0 ? parameters_.width : 0.5 * spacing * spacing);
  // Sampling factor of Σ_ω (+ a tiny jitter so a rank-deficient covariance still factorises).
  try {
    sampling_factor_ = learning::choleskyFactor(covariance_ + 1e-12 * Eigen::MatrixXd::Identity(n, n));
  } catch (const std::invalid_argument&) {
    throw std::invalid_argument("ProMp: the weight covariance is not positive semidefinite");
  }
}

ProMpData::ProMpData(const ProMp& promp)
    : b(Eigen::VectorXd::Zero(promp.kernels())),
      db(Eigen::VectorXd::Zero(promp.kernels())),
      dt_basis(Eigen::VectorXd::Zero(promp.kernels())),
      psi(Eigen::MatrixXd::Zero(promp.dofs() * promp.kernels(), 2 * promp.dofs())),
      sigma_psi(Eigen::MatrixXd::Zero(promp.dofs() * promp.kernels(), 2 * promp.dofs())) {}

ProMp ProMp::withMean(const Eigen::VectorXd& mean) const {
  if (mean.size() != mean_.size() || !mean.allFinite()) {
    throw std::invalid_argument("ProMp::withMean: the mean needs dofs*kernels finite entries");
  }
  ProMp out = *this;
  out.mean_ = mean;
  return out;
}

void ProMp::basis(double z, Eigen::Ref<Eigen::VectorXd> b, Eigen::Ref<Eigen::VectorXd> db) const noexcept {
  normalisedGaussianBasis(z, centres_, widths_, b, db);
}

ProMpStatus ProMp::check(const ProMpData& data, double z) const noexcept {
  const int k = parameters_.kernels;
  if (data.b.size() != k || data.db.size() != k || data.dt_basis.size() != k || data.psi.rows() != dofs_ * k ||
      data.psi.cols() != 2 * dofs_ || data.sigma_psi.rows() != data.psi.rows() ||
      data.sigma_psi.cols() != data.psi.cols()) {
    return ProMpStatus::WrongSize;
  }
  return std::isfinite(z) ? ProMpStatus::Success : ProMpStatus::NotFinite;
}

ProMpStatus ProMp::blockBasis(ProMpData& data, double z) const noexcept {
  if (const ProMpStatus status = check(data, z); status != ProMpStatus::Success) return status;
  const int k = parameters_.kernels;
  basis(std::clamp(z, 0.0, 1.0), data.b, data.db);
  data.psi.setZero();
  for (int j = 0; j < dofs_; ++j) {
    data.psi.block(j * k, j, k, 1) = data.b;
    data.psi.block(j * k, dofs_ + j, k, 1) = data.db / duration_;  // d/dt = (d/dz) / duration
  }
  return ProMpStatus::Success;
}

ProMpStatus ProMp::mean(ProMpData& data, double z, Eigen::Ref<Eigen::VectorXd> position,
                        Eigen::Ref<Eigen::VectorXd> velocity) const noexcept {
  if (position.size() != dofs_ || velocity.size() != dofs_) return ProMpStatus::WrongSize;
  if (const ProMpStatus status = check(data, z); status != ProMpStatus::Success) return status;
  const int k = parameters_.kernels;
  basis(std::clamp(z, 0.0, 1.0), data.b, data.db);
  for (int j = 0; j < dofs_; ++j) {
    position[j] = data.b.dot(mean_.segment(j * k, k));
    velocity[j] = data.db.dot(mean_.segment(j * k, k)) / duration_;
  }
  return ProMpStatus::Success;
}

void ProMp::projectCovariance(ProMpData& data, int columns, Eigen::Ref<Eigen::MatrixXd> out) const noexcept {
  const int k = parameters_.kernels;
  data.dt_basis = data.db / duration_;
  const auto vector = [&](int column) -> const Eigen::VectorXd& { return column < dofs_ ? data.b : data.dt_basis; };
  for (int c = 0; c < columns; ++c) {
    const int dof = c % dofs_;
    data.sigma_psi.col(c).noalias() = covariance_.middleCols(dof * k, k) * vector(c);
  }
  for (int c = 0; c < columns; ++c) {
    for (int r = 0; r < columns; ++r) out(r, c) = vector(r).dot(data.sigma_psi.col(c).segment((r % dofs_) * k, k));
  }
}

ProMpStatus ProMp::covariance(ProMpData& data, double z, Eigen::Ref<Eigen::MatrixXd> out) const noexcept {
  if (out.rows() != dofs_ || out.cols() != dofs_) return ProMpStatus::WrongSize;
  if (const ProMpStatus status = check(data, z); status != ProMpStatus::Success) return status;
  basis(std::clamp(z, 0.0, 1.0), data.b, data.db);
  projectCovariance(data, dofs_, out);
  return ProMpStatus::Success;
}

ProMpStatus ProMp::stateCovariance(ProMpData& data, double z, Eigen::Ref<Eigen::MatrixXd> out) const noexcept {
  if (out.rows() != 2 * dofs_ || out.cols() != 2 * dofs_) return ProMpStatus::WrongSize;
  if (const ProMpStatus status = check(data, z); status != ProMpStatus::Success) return status;
  basis(std::clamp(z, 0.0, 1.0), data.b, data.db);
  projectCovariance(data, 2 * dofs_, out);
  return ProMpStatus::Success;
}

Eigen::VectorXd ProMp::sample(std::mt19937& rng) const {
  return learning::GaussianSampler().draw(mean_, sampling_factor_, rng);
}

DemonstrationWeights ProMp::demonstrationWeights(const ProMpParameters& parameters,
                                                 const std::vector<Eigen::MatrixXd>& demonstrations) {
  parameters.validate();
  if (demonstrations.empty()) throw std::invalid_argument("ProMp::demonstrationWeights: no demonstrations");
  const auto dofs = static_cast<int>(demonstrations.front().cols());
  const int k = parameters.kernels;
  const int n = dofs * k;
  if (dofs < 1) throw std::invalid_argument("ProMp::demonstrationWeights: demonstrations need at least one DoF");
  // A model with zero parameters gives the basis.
  const ProMp shape(parameters, dofs, Eigen::VectorXd::Zero(n), Eigen::MatrixXd::Zero(n, n),
                    Eigen::VectorXd::Zero(dofs), 1.0);
  DemonstrationWeights out{Eigen::MatrixXd(n, static_cast<Eigen::Index>(demonstrations.size())),
                           Eigen::VectorXd::Zero(dofs)};
  double residual_samples = 0.0;
  Eigen::VectorXd b(k), db(k);
  for (std::size_t d = 0; d < demonstrations.size(); ++d) {
    const Eigen::MatrixXd& y = demonstrations[d];
    if (y.cols() != dofs || y.rows() < k || !y.allFinite()) {
      throw std::invalid_argument("ProMp::demonstrationWeights: demonstration " + std::to_string(d + 1) +
                                  " must be finite, with the same DoF and at least `kernels` samples");
    }
    Eigen::MatrixXd B(y.rows(), k);
    for (Eigen::Index r = 0; r < y.rows(); ++r) {
      shape.basis(static_cast<double>(r) / static_cast<double>(y.rows() - 1), b, db);
      B.row(r) = b.transpose();
    }
    const Eigen::MatrixXd w = learning::ridgeLeastSquares(B, y, parameters.ridge);  // kernels × dofs
    for (int j = 0; j < dofs; ++j) {
      out.weights.block(j * k, static_cast<Eigen::Index>(d), k, 1) = w.col(j);
      out.observation_variance[j] += (B * w.col(j) - y.col(j)).squaredNorm();
    }
    residual_samples += static_cast<double>(y.rows());
  }
  out.observation_variance /= residual_samples;
  return out;
}

ProMp ProMp::fit(const ProMpParameters& parameters, const std::vector<Eigen::MatrixXd>& demonstrations,
                 double duration) {
  if (demonstrations.size() < 2) throw std::invalid_argument("ProMp::fit: needs at least 2 demonstrations");
  const DemonstrationWeights fitted = demonstrationWeights(parameters, demonstrations);
  auto [mean, covariance] = learning::sampleMoments(fitted.weights.transpose());
  covariance.diagonal().array() += parameters.covariance_prior;
  return ProMp(parameters, static_cast<int>(demonstrations.front().cols()), mean, covariance,
               fitted.observation_variance, duration);
}

ProMp ProMp::conditioned(double z, const Eigen::VectorXd& position, const Eigen::MatrixXd& observation_covariance,
                         const Eigen::VectorXd& velocity) const {
  const bool with_velocity = velocity.size() == dofs_;
  const int m = with_velocity ? 2 * dofs_ : dofs_;
  if (position.size() != dofs_ || (velocity.size() != 0 && !with_velocity) || observation_covariance.rows() != m ||
      observation_covariance.cols() != m || !position.allFinite() || !observation_covariance.allFinite() ||
      !velocity.allFinite()) {
    throw std::invalid_argument(
        "ProMp::conditioned: the observation must have dofs positions (and optionally dofs "
        "velocities) with a matching square covariance");
  }
  ProMpData data(*this);
  if (blockBasis(data, z) != ProMpStatus::Success) {
    throw std::invalid_argument("ProMp::conditioned: the phase must be finite");
  }
  const Eigen::MatrixXd H = data.psi.leftCols(m);
  Eigen::VectorXd observed(m);
  observed.head(dofs_) = position;
  if (with_velocity) observed.tail(dofs_) = velocity;
  const Eigen::MatrixXd SH = covariance_ * H;
  const Eigen::MatrixXd K = SH * (observation_covariance + H.transpose() * SH).inverse();
  const Eigen::VectorXd mean = mean_ + K * (observed - H.transpose() * mean_);
  Eigen::MatrixXd covariance = covariance_ - K * SH.transpose();
  covariance = 0.5 * (covariance + covariance.transpose());
  return ProMp(parameters_, dofs_, mean, covariance, observation_variance_, duration_);
}

}  // namespace bimanual_skills::primitives
