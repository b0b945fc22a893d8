#include "bimanual_skills/learning/reps.hpp"

#include <Eigen/Cholesky>
#include <nlopt.hpp>

#include <cmath>
#include <stdexcept>
#include <string>
#include <tuple>

namespace bimanual_skills::learning {
namespace {

/// The dual (6.12) written in κ = η + ω − ν instead of η (κ > 0 by its bounds, so the exponentials stay finite;
/// η = κ + ν − ω ≥ 0 is the one linear constraint), with the largest exponent factored out for stability:
///   h = (κ + ν − ω) ε + Σ_high ω_i χ − Σ_low ν_i ξ + a_max + κ log((1/N) Σ_k e_k),  e_k = exp((a_k − a_max)/κ),
///   ∂h/∂κ = ε + log((1/N) Σ e_k) − Σ_k p_k (a_k − a_max)/κ,
///   ∂h/∂ν_i = ε − ξ − E_p[log g_i − log q],  ∂h/∂ω_i = χ − ε + E_p[log g_i − log q],  p_k = e_k / Σ e.
/// With no constraints, κ = η and this is the REPS dual (6.15).
struct Dual {
  const Eigen::VectorXd* rewards;
  double epsilon;
  const Eigen::VectorXd* log_q;
  const std::vector<DualConstraint>* constraints;
  Eigen::VectorXd a, e;
};

double dual(unsigned n, const double* x, double* gradient, void* data) {
  (void)n;
  auto* d = static_cast<Dual*>(data);
  const double kappa = x[0];
  double repulsion = 0.0, attraction = 0.0, bounds = 0.0;
  d->a = *d->rewards;
  for (std::size_t i = 0; i < d->constraints->size(); ++i) {
    const DualConstraint& c = (*d->constraints)[i];
    const double m = x[1 + i];
    const double sign = c.attractive ? 1.0 : -1.0;
    d->a += sign * m * (c.log_density - *d->log_q);
    (c.attractive ? attraction : repulsion) += m;
    bounds += sign * m * c.bound;
  }
  const double eta = kappa + (repulsion - attraction);
  const double a_max = d->a.maxCoeff();
  const Eigen::ArrayXd shifted = d->a.array() - a_max;
  d->e = (shifted / kappa).exp().matrix();
  const double sum = d->e.sum();
  const double count = static_cast<double>(d->a.size());
  const double value = eta * d->epsilon + bounds + a_max + kappa * std::log(sum / count);
  if (gradient != nullptr) {
    gradient[0] = d->epsilon + std::log(sum / count) - (d->e.array() * shifted).sum() / (kappa * sum);
    for (std::size_t i = 0; i < d->constraints->size(); ++i) {
      const DualConstraint& c = (*d->constraints)[i];
      const double expected = d->e.dot(c.log_density - *d->log_q) / sum;
      gradient[1 + i] = c.attractive ? c.bound - d->epsilon + expected : d->epsilon - c.bound - expected;
    }
  }
  return value;
}

/// η = κ + ν − ω ≥ 0, as ω − ν − κ ≤ 0.
double etaNonNegative(unsigned n, const double* x, double* gradient, void* data) {
  const auto* constraints = static_cast<const std::vector<DualConstraint>*>(data);
  double value = -x[0];
  if (gradient != nullptr) gradient[0] = -1.0;
  for (unsigned i = 1; i < n; ++i) {
    const double sign = (*constraints)[i - 1].attractive ? 1.0 : -1.0;
    value += sign * x[i];
    if (gradient != nullptr) gradient[i] = sign;
  }
  return value;
}

}  // namespace

void RepsParameters::validate() const {
  if (!(epsilon > 0.0) || reuse < 0 || !(covariance_regularisation >= 0.0)) {
    throw std::invalid_argument("RepsParameters: need epsilon > 0, reuse >= 0, covariance_regularisation >= 0");
  }
}

DualSolution solveRepsDual(const Eigen::VectorXd& rewards, double epsilon, const Eigen::VectorXd& log_q,
                           const std::vector<DualConstraint>& constraints) {
  for (const DualConstraint& c : constraints) {
    if (c.log_density.size() != rewards.size() || log_q.size() != rewards.size() || !c.log_density.allFinite() ||
        !std::isfinite(c.bound) || !(c.minimum_multiplier >= 0.0)) {
      throw std::invalid_argument("solveRepsDual: every constraint needs one finite log-density per sample (" +
                                  std::to_string(rewards.size()) + "), a finite bound and a minimum multiplier >= 0");
    }
  }
  if (!constraints.empty() && !log_q.allFinite()) throw std::invalid_argument("solveRepsDual: log q not finite");
  Dual data{&rewards, epsilon, &log_q, &constraints, {}, {}};
  const double spread = rewards.maxCoeff() - rewards.minCoeff();
  const double scale = spread > 0.0 ? spread : 1.0;
  const auto variables = static_cast<unsigned>(1 + constraints.size());
  std::vector<double> x(variables, 0.0), lower(variables, 0.0), upper(variables, 1e10 * scale);
  x[0] = scale;
  lower[0] = 1e-10 * scale;
  for (std::size_t i = 0; i < constraints.size(); ++i) {
    if (!constraints[i].attractive) lower[1 + i] = x[1 + i] = constraints[i].minimum_multiplier;
  }
  if (spread > 0.0 || !constraints.empty()) {
    nlopt::opt optimiser(nlopt::LD_MMA, variables);
    optimiser.set_lower_bounds(lower);
    optimiser.set_upper_bounds(upper);
    optimiser.set_min_objective(dual, &data);
    if (!constraints.empty()) {
      optimiser.add_inequality_constraint(etaNonNegative, const_cast<std::vector<DualConstraint>*>(&constraints),
                                          1e-12);
    }
    optimiser.set_xtol_rel(1e-10);
    optimiser.set_maxeval(1000);
    double value = 0.0;
    try {
      optimiser.optimize(x, value);
    } catch (const std::exception&) {
      // MMA may stop on round-off near the optimum: the last iterate stands.
    }
  }
  DualSolution out;
  dual(variables, x.data(), nullptr, &data);
  out.weights = data.e / data.e.sum();
  out.multipliers = Eigen::Map<const Eigen::VectorXd>(x.data() + 1, static_cast<Eigen::Index>(constraints.size()));
  double repulsion_minus_attraction = 0.0;
  for (std::size_t i = 0; i < constraints.size(); ++i) {
    repulsion_minus_attraction += constraints[i].attractive ? -x[1 + i] : x[1 + i];
  }
  out.eta = x[0] + repulsion_minus_attraction;
  const double n = static_cast<double>(rewards.size());
  for (Eigen::Index k = 0; k < out.weights.size(); ++k) {
    if (out.weights[k] > 0.0) out.kl += out.weights[k] * std::log(n * out.weights[k]);
  }
  return out;
}

double repsDualObjective(const Eigen::VectorXd& rewards, double epsilon, const Eigen::VectorXd& log_q,
                         const std::vector<DualConstraint>& constraints, const Eigen::VectorXd& x,
                         Eigen::VectorXd* gradient) {
  if (x.size() != static_cast<Eigen::Index>(constraints.size()) + 1 || !(x[0] > 0.0)) {
    throw std::invalid_argument("repsDualObjective: x = [kappa > 0, one multiplier per constraint]");
  }
  Dual data{&rewards, epsilon, &log_q, &constraints, {}, {}};
  if (gradient != nullptr) gradient->resize(x.size());
  return dual(static_cast<unsigned>(x.size()), x.data(), gradient != nullptr ? gradient->data() : nullptr, &data);
}

std::pair<Eigen::MatrixXd, Eigen::VectorXd> RolloutBuffer::gather(const Eigen::MatrixXd& samples,
                                                                  const Eigen::VectorXd& rewards) const {
  if (samples.rows() != rewards.size() || samples.rows() < 2 || samples.cols() < 1 || !samples.allFinite() ||
      !rewards.allFinite()) {
    throw std::invalid_argument("policy update: need >= 2 finite samples (rows) with one finite reward each");
  }
  if (!kept_.empty() && kept_.front().first.size() != samples.cols()) {
    throw std::invalid_argument("policy update: the parameter dimension changed between updates");
  }
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
  return {std::move(theta), std::move(r)};
}

void RolloutBuffer::keep(const Eigen::MatrixXd& samples, const Eigen::VectorXd& rewards) {
  for (Eigen::Index k = 0; k < samples.rows(); ++k) kept_.emplace_back(samples.row(k).transpose(), rewards[k]);
  while (static_cast<int>(kept_.size()) > reuse_) kept_.pop_front();
}

Eigen::VectorXd normalisedRewards(const Eigen::VectorXd& rewards) {
  const double spread = rewards.maxCoeff() - rewards.minCoeff();
  return spread > 0.0 ? Eigen::VectorXd((rewards.array() - rewards.minCoeff()) / spread)
                      : Eigen::VectorXd::Zero(rewards.size());
}

Reps::Reps(const RepsParameters& parameters) : parameters_(parameters), buffer_(parameters.reuse) {
  parameters_.validate();
}

Eigen::VectorXd Reps::weights(const Eigen::VectorXd& rewards, double epsilon, double& eta, double& kl) {
  DualSolution solution = solveRepsDual(rewards, epsilon, Eigen::VectorXd(), {});
  eta = solution.eta;
  kl = solution.kl;
  return std::move(solution.weights);
}

RepsUpdate Reps::update(const Eigen::MatrixXd& samples, const Eigen::VectorXd& rewards) {
  auto [theta, r] = buffer_.gather(samples, rewards);
  if (parameters_.normalise_rewards) r = normalisedRewards(r);
  RepsUpdate out;
  out.weights = weights(r, parameters_.epsilon, out.eta, out.kl);
  std::tie(out.mean, out.covariance) = weightedGaussian(theta, out.weights, parameters_.covariance_regularisation);
  buffer_.keep(samples, rewards);
  return out;
}

}  // namespace bimanual_skills::learning
