#include "bimanual_skills/learning/reps.hpp"

#include <nlopt.hpp>

#include <cmath>
#include <stdexcept>
#include <vector>

namespace bimanual_skills::learning {
namespace {

/// Dual (6.15) and its derivative, with the maximum reward factored out of the exponentials for stability:
/// h(η) = η ε + r_max + η log((1/N) Σ exp((r_k − r_max)/η)),
/// h'(η) = ε + log((1/N) Σ e_k) − Σ e_k (r_k − r_max) / (η Σ e_k),  e_k = exp((r_k − r_max)/η).
struct Dual {
  const Eigen::VectorXd* rewards;
  double epsilon;
};

double dual(unsigned n, const double* x, double* gradient, void* data) {
  (void)n;
  const auto* d = static_cast<const Dual*>(data);
  const double eta = x[0];
  const double r_max = d->rewards->maxCoeff();
  const Eigen::ArrayXd shifted = d->rewards->array() - r_max;
  const Eigen::ArrayXd e = (shifted / eta).exp();
  const double sum = e.sum();
  const double count = static_cast<double>(d->rewards->size());
  const double value = eta * d->epsilon + r_max + eta * std::log(sum / count);
  if (gradient != nullptr) gradient[0] = d->epsilon + std::log(sum / count) - (e * shifted).sum() / (eta * sum);
  return value;
}

}  // namespace

void RepsParameters::validate() const {
  if (!(epsilon > 0.0) || reuse < 0 || !(covariance_regularisation >= 0.0)) {
    throw std::invalid_argument("RepsParameters: need epsilon > 0, reuse >= 0, covariance_regularisation >= 0");
  }
}

Reps::Reps(const RepsParameters& parameters) : parameters_(parameters) {
  parameters_.validate();
}

Eigen::VectorXd Reps::weights(const Eigen::VectorXd& rewards, double epsilon, double& eta, double& kl) {
  Dual data{&rewards, epsilon};
  const double spread = rewards.maxCoeff() - rewards.minCoeff();
  std::vector<double> x = {spread > 0.0 ? spread : 1.0};
  if (spread > 0.0) {
    nlopt::opt optimiser(nlopt::LD_MMA, 1);
    optimiser.set_lower_bounds(std::vector<double>{1e-10 * spread});
    optimiser.set_upper_bounds(std::vector<double>{1e10 * spread});
    optimiser.set_min_objective(dual, &data);
    optimiser.set_xtol_rel(1e-10);
    optimiser.set_maxeval(1000);
    double value = 0.0;
    try {
      optimiser.optimize(x, value);
    } catch (const std::exception&) {
      // MMA may stop on round-off near the optimum: the last iterate stands.
    }
  }
  eta = x[0];
  const Eigen::ArrayXd d = ((rewards.array() - rewards.maxCoeff()) / eta).exp();
  const Eigen::VectorXd p = (d / d.sum()).matrix();
  const double n = static_cast<double>(rewards.size());
  kl = 0.0;
  for (Eigen::Index k = 0; k < p.size(); ++k) {
    if (p[k] > 0.0) kl += p[k] * std::log(n * p[k]);
  }
  return p;
}

RepsUpdate Reps::update(const Eigen::MatrixXd& samples, const Eigen::VectorXd& rewards) {
  if (samples.rows() != rewards.size() || samples.rows() < 2 || samples.cols() < 1 || !samples.allFinite() ||
      !rewards.allFinite()) {
    throw std::invalid_argument("Reps::update: need >= 2 finite samples (rows) with one reward each");
  }
  if (!kept_.empty() && kept_.front().first.size() != samples.cols()) {
    throw std::invalid_argument("Reps::update: the parameter dimension changed between updates");
  }
  // All samples in use: those kept from earlier updates, then this batch.
  const auto kept = static_cast<Eigen::Index>(kept_.size());
  const Eigen::Index n = kept + samples.rows();
  Eigen::MatrixXd theta(n, samples.cols());
  Eigen::VectorXd r(n);
  for (Eigen::Index k = 0; k < kept; ++k) {
    theta.row(k) = kept_[static_cast<std::size_t>(k)].first.transpose();
    r[k] = kept_[static_cast<std::size_t>(k)].second;
  }
  theta.bottomRows(samples.rows()) = samples;
  r.tail(samples.rows()) = rewards;
  if (parameters_.normalise_rewards) {
    const double spread = r.maxCoeff() - r.minCoeff();
    r = spread > 0.0 ? Eigen::VectorXd((r.array() - r.minCoeff()) / spread) : Eigen::VectorXd::Zero(n);
  }
  RepsUpdate out;
  out.weights = weights(r, parameters_.epsilon, out.eta, out.kl);
  // Weighted maximum likelihood of the Gaussian.
  out.mean = theta.transpose() * out.weights;
  const Eigen::MatrixXd centred = theta.rowwise() - out.mean.transpose();
  out.covariance = centred.transpose() * out.weights.asDiagonal() * centred;
  out.covariance.diagonal().array() += parameters_.covariance_regularisation;
  // Keep the newest `reuse` rollouts for the next update.
  for (Eigen::Index k = 0; k < samples.rows(); ++k) kept_.emplace_back(samples.row(k).transpose(), rewards[k]);
  while (static_cast<int>(kept_.size()) > parameters_.reuse) kept_.pop_front();
  return out;
}

}  // namespace bimanual_skills::learning
