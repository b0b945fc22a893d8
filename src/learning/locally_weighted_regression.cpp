#include "bimanual_skills/learning/locally_weighted_regression.hpp"

#include <cmath>
#include <stdexcept>

namespace bimanual_skills::learning {

const char* toString(LwrStatus status) noexcept {
  switch (status) {
    case LwrStatus::Success:
      return "success";
    case LwrStatus::NoActiveField:
      return "no receptive field is active at this input";
    case LwrStatus::WrongSize:
      return "an input or output has the wrong size";
    case LwrStatus::NotFinite:
      return "an input or output contains NaN or Inf";
  }
  return "unknown status";
}

void LwrParameters::validate(int input_dim) const {
  if (width.size() != input_dim || !width.allFinite() || !(width.array() > 0.0).all()) {
    throw std::invalid_argument("LwrParameters: width needs " + std::to_string(input_dim) + " positive entries");
  }
  if (!(activation_to_create > 0.0 && activation_to_create < 1.0) || !(forgetting > 0.0 && forgetting <= 1.0) ||
      !(initial_covariance > 0.0) || max_fields < 1 || !(prediction_cutoff >= 0.0 && prediction_cutoff < 1.0)) {
    throw std::invalid_argument(
        "LwrParameters: need 0 < activation_to_create < 1, 0 < forgetting <= 1, initial_covariance > 0, "
        "max_fields >= 1, 0 <= prediction_cutoff < 1");
  }
}

LocallyWeightedRegression::LocallyWeightedRegression(int input_dim, int output_dim, const LwrParameters& parameters)
    : input_dim_(input_dim), output_dim_(output_dim), parameters_(parameters) {
  if (input_dim < 1 || output_dim < 1)
    throw std::invalid_argument("LocallyWeightedRegression: dimensions must be >= 1");
  parameters_.validate(input_dim);
  const int p = input_dim + 1;
  centres_ = Eigen::MatrixXd::Zero(input_dim, parameters_.max_fields);
  beta_.assign(static_cast<std::size_t>(parameters_.max_fields), Eigen::MatrixXd::Zero(p, output_dim));
  P_.assign(static_cast<std::size_t>(parameters_.max_fields), Eigen::MatrixXd::Zero(p, p));
  z_ = Eigen::VectorXd::Zero(p);
  Pz_ = Eigen::VectorXd::Zero(p);
  error_ = Eigen::VectorXd::Zero(output_dim);
  local_ = Eigen::VectorXd::Zero(output_dim);
}

double LocallyWeightedRegression::activation(int k, const Eigen::Ref<const Eigen::VectorXd>& x) const noexcept {
  const double d2 = ((x - centres_.col(k)).array() / parameters_.width.array()).square().sum();
  return std::exp(-0.5 * d2);
}

LwrStatus LocallyWeightedRegression::update(const Eigen::Ref<const Eigen::VectorXd>& x,
                                            const Eigen::Ref<const Eigen::VectorXd>& y) noexcept {
  if (x.size() != input_dim_ || y.size() != output_dim_) return LwrStatus::WrongSize;
  if (!x.allFinite() || !y.allFinite()) return LwrStatus::NotFinite;
  double strongest = 0.0;
  for (int k = 0; k < count_; ++k) {
    const double w = activation(k, x);
    strongest = std::max(strongest, w);
    if (w < parameters_.prediction_cutoff) continue;
    // Weighted RLS with forgetting on z = [x − c; 1]: P ← (P − w P z zᵀ P / (λ + w zᵀ P z)) / λ,
    // β ← β + w P_new z (y − βᵀ z)ᵀ.
    const auto kk = static_cast<std::size_t>(k);
    z_.head(input_dim_) = x - centres_.col(k);
    z_[input_dim_] = 1.0;
    Pz_.noalias() = P_[kk] * z_;
    const double denominator = parameters_.forgetting + w * z_.dot(Pz_);
    P_[kk].noalias() -= (w / denominator) * Pz_ * Pz_.transpose();
    P_[kk] /= parameters_.forgetting;
    error_ = y;
    error_.noalias() -= beta_[kk].transpose() * z_;
    Pz_.noalias() = P_[kk] * z_;
    beta_[kk].noalias() += w * Pz_ * error_.transpose();
  }
  if (strongest < parameters_.activation_to_create && count_ < parameters_.max_fields) {
    const auto kk = static_cast<std::size_t>(count_);
    centres_.col(count_) = x;
    P_[kk].setIdentity();
    P_[kk] *= parameters_.initial_covariance;
    beta_[kk].setZero();
    beta_[kk].row(input_dim_) = y.transpose();  // start at the sample's value
    ++count_;
  }
  return LwrStatus::Success;
}

LwrStatus LocallyWeightedRegression::predict(const Eigen::Ref<const Eigen::VectorXd>& x,
                                             Eigen::Ref<Eigen::VectorXd> y) noexcept {
  if (x.size() != input_dim_ || y.size() != output_dim_) return LwrStatus::WrongSize;
  if (!x.allFinite()) return LwrStatus::NotFinite;
  y.setZero();
  double total = 0.0;
  for (int k = 0; k < count_; ++k) {
    const double w = activation(k, x);
    if (w < parameters_.prediction_cutoff) continue;
    z_.head(input_dim_) = x - centres_.col(k);
    z_[input_dim_] = 1.0;
    local_.noalias() = beta_[static_cast<std::size_t>(k)].transpose() * z_;
    y += w * local_;
    total += w;
  }
  if (total <= 0.0) return LwrStatus::NoActiveField;
  y /= total;
  return LwrStatus::Success;
}

}  // namespace bimanual_skills::learning
