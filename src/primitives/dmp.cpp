#include "bimanual_skills/primitives/dmp.hpp"

#include "bimanual_skills/learning/ridge_regression.hpp"
#include "bimanual_skills/primitives/basis.hpp"
#include "bimanual_skills/signal/fir_filter.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::primitives {

const char* toString(DmpStatus status) noexcept {
  switch (status) {
    case DmpStatus::Success:
      return "success";
    case DmpStatus::VectorClamped:
      return "the orientation vector left the unit ball and was clamped";
    case DmpStatus::InvalidInput:
      return "invalid input (wrong size, NaN/Inf, non-unit quaternion or dt <= 0)";
  }
  return "unknown status";
}

void DmpParameters::validate() const {
  if (kernels < 1 || kernels > kDmpMaxKernels) {
    throw std::invalid_argument("DmpParameters: kernels must be in [1, " + std::to_string(kDmpMaxKernels) + "]");
  }
  if (!(alpha_z > 0.0) || !(beta_z > 0.0) || !(alpha_x > 0.0) || !(regularisation >= 0.0)) {
    throw std::invalid_argument("DmpParameters: alpha_z, beta_z, alpha_x must be > 0, regularisation >= 0");
  }
}

bool DmpParameters::stableStep(double dt, double tau) const noexcept {
  const double c = alpha_z * dt / tau, k = alpha_z * beta_z * dt * dt / (tau * tau);
  return c > 0.0 && c < 2.0 && 2.0 * c + k < 4.0;
}

Dmp::Dmp(const DmpParameters& parameters, const Eigen::MatrixXd& weights, const Eigen::VectorXd& start,
         const Eigen::VectorXd& goal, double duration)
    : parameters_(parameters), weights_(weights), start_(start), goal_(goal), duration_(duration) {
  parameters_.validate();
  const auto d = start_.size();
  if (d < 1 || goal_.size() != d || weights_.rows() != d || weights_.cols() != parameters_.kernels) {
    throw std::invalid_argument("Dmp: weights must be dofs x kernels and start/goal have dofs entries");
  }
  if (!weights_.allFinite() || !start_.allFinite() || !goal_.allFinite() || !(duration_ > 0.0) ||
      !std::isfinite(duration_)) {
    throw std::invalid_argument("Dmp: weights, start, goal must be finite and the duration > 0");
  }
  // Centres uniform in time t_i = i/(N−1) τ, i.e. c_i = exp(−α_x t_i/τ); widths from the spacing to the next centre.
  const int n = parameters_.kernels;
  centres_.resize(n);
  widths_.resize(n);
  for (int i = 0; i < n; ++i) centres_[i] = std::exp(-parameters_.alpha_x * (n == 1 ? 0.0 : double(i) / (n - 1)));
  for (int i = 0; i < n; ++i) {
    const double spacing =
        n == 1 ? 0.5 : std::abs(centres_[std::min(i + 1, n - 1)] - centres_[std::max(i - 1, 0)]) * 0.5;
    widths_[i] = std::max(0.5 * spacing * spacing, 1e-10);
  }
}

void Dmp::basis(double x, Eigen::Ref<Eigen::VectorXd> g) const noexcept {
  normalisedGaussianBasis(x, centres_, widths_, x, g);
}

Eigen::MatrixXd Dmp::demonstratedForcing(const DmpParameters& parameters, const Eigen::MatrixXd& positions, double dt,
                                         double smoothing_hz) {
  parameters.validate();
  const auto samples = positions.rows();
  const auto d = positions.cols();
  if (samples < 10 || d < 1 || !(dt > 0.0) || !positions.allFinite()) {
    throw std::invalid_argument("Dmp::fit, Dmp::demonstratedForcing: need >= 10 finite samples of >= 1 DoF and dt > 0");
  }
  const Eigen::MatrixXd y = signal::zeroPhaseLowPass(positions, dt, smoothing_hz);
  Eigen::MatrixXd yd = Eigen::MatrixXd::Zero(samples, d), ydd = Eigen::MatrixXd::Zero(samples, d);
  for (Eigen::Index r = 1; r + 1 < samples; ++r) {
    yd.row(r) = (y.row(r + 1) - y.row(r - 1)) / (2.0 * dt);
    ydd.row(r) = (y.row(r + 1) - 2.0 * y.row(r) + y.row(r - 1)) / (dt * dt);
  }
  const double tau = dt * static_cast<double>(samples - 1);
  const Eigen::VectorXd goal = positions.row(samples - 1).transpose();
  Eigen::MatrixXd forcing(samples, d);
  for (Eigen::Index j = 0; j < d; ++j) {
    const Eigen::VectorXd error = (goal[j] - y.col(j).array()).matrix();
    forcing.col(j) = forcingTarget<Eigen::VectorXd>(parameters, tau, error, yd.col(j), ydd.col(j));
  }
  return forcing;
}

Dmp Dmp::fit(const DmpParameters& parameters, const Eigen::MatrixXd& positions, double dt, double smoothing_hz) {
  // f = τ² ÿ − α_z (β_z (g − y) − τ ẏ), divided by (g − y0) for the goal-scaled variant, regressed on g(x).
  Eigen::MatrixXd forcing = demonstratedForcing(parameters, positions, dt, smoothing_hz);
  const auto samples = positions.rows();
  const auto d = positions.cols();
  const double tau = dt * static_cast<double>(samples - 1);
  const Eigen::VectorXd start = positions.row(0).transpose();
  const Eigen::VectorXd goal = positions.row(samples - 1).transpose();
  const Dmp shape(parameters, Eigen::MatrixXd::Zero(d, parameters.kernels), start, goal, tau);
  if (parameters.goal_scaled_forcing) {
    for (Eigen::Index j = 0; j < d; ++j) {
      const double amplitude = goal[j] - start[j];
      forcing.col(j) /= std::abs(amplitude) > 1e-9 ? amplitude : 1.0;
    }
  }
  const Eigen::MatrixXd weights = shape.fitWeights(forcing, dt);
  return Dmp(parameters, weights, start, goal, tau);
}

Eigen::MatrixXd Dmp::fitWeights(const Eigen::MatrixXd& forcing, double dt) const {
  if (forcing.cols() != dofs() || forcing.rows() < 1 || !(dt > 0.0) || !forcing.allFinite()) {
    throw std::invalid_argument("Dmp::fitWeights: need finite forcing values with one column per DoF and dt > 0");
  }
  const int n = parameters_.kernels;
  Eigen::MatrixXd G(forcing.rows(), n);
  Eigen::VectorXd g(n);
  for (Eigen::Index r = 0; r < forcing.rows(); ++r) {
    basis(std::exp(-parameters_.alpha_x * static_cast<double>(r) * dt / duration_), g);
    G.row(r) = g.transpose();
  }
  return learning::ridgeLeastSquares(G, forcing, parameters_.regularisation).transpose();
}

Dmp Dmp::withDuration(double duration) const {
  return Dmp(parameters_, weights_, start_, goal_, duration);
}

Dmp Dmp::withWeights(const Eigen::MatrixXd& weights) const {
  return Dmp(parameters_, weights, start_, goal_, duration_);
}

DmpState Dmp::initialState() const {
  DmpState state;
  state.y = start_;
  state.yd = Eigen::VectorXd::Zero(dofs());
  state.ydd = Eigen::VectorXd::Zero(dofs());
  state.goal = goal_;
  return state;
}

bool Dmp::steppable(const DmpState& state, double dt) const noexcept {
  const int d = dofs();
  return state.y.size() == d && state.yd.size() == d && state.ydd.size() == d && state.goal.size() == d && dt > 0.0 &&
         std::isfinite(dt) && parameters_.stableStep(dt, duration_) && state.y.allFinite() && state.yd.allFinite() &&
         state.goal.allFinite() && std::isfinite(state.x) && std::isfinite(state.t);
}

void Dmp::advance(DmpState& state, double dt) const noexcept {
  state.yd += dt * state.ydd;
  state.y += dt * state.yd;
  state.x *= std::exp(-parameters_.alpha_x * dt / duration_);
  state.t += dt;
}

DmpStatus Dmp::step(DmpState& state, double dt) const noexcept {
  if (!steppable(state, dt)) return DmpStatus::InvalidInput;
  double g_storage[kDmpMaxKernels];
  Eigen::Map<Eigen::VectorXd> g(g_storage, parameters_.kernels);
  basis(state.x, g);
  const double tau = duration_;
  for (int j = 0; j < dofs(); ++j) {
    double f = weights_.row(j).dot(g);
    if (parameters_.goal_scaled_forcing) f *= state.goal[j] - start_[j];
    state.ydd[j] = transformationAcceleration(parameters_, tau, state.goal[j] - state.y[j], state.yd[j], f);
  }
  advance(state, dt);
  return DmpStatus::Success;
}

DmpStatus Dmp::step(DmpState& state, double dt, const Eigen::Ref<const Eigen::VectorXd>& forcing) const noexcept {
  if (!steppable(state, dt) || forcing.size() != dofs() || !forcing.allFinite()) return DmpStatus::InvalidInput;
  for (int j = 0; j < dofs(); ++j) {
    state.ydd[j] =
        transformationAcceleration(parameters_, duration_, state.goal[j] - state.y[j], state.yd[j], forcing[j]);
  }
  advance(state, dt);
  return DmpStatus::Success;
}

}  // namespace bimanual_skills::primitives
