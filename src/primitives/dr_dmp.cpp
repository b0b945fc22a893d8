#include "bimanual_skills/primitives/dr_dmp.hpp"

#include "bimanual_skills/primitives/basis.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::primitives {
namespace {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// W (r × n) of ω, after checking the sizes against the coordination matrices.
Eigen::MatrixXd latentMatrix(const DrDmpParameters& parameters, const std::vector<Eigen::MatrixXd>& coordination,
                             const Eigen::VectorXd& weights, Eigen::Index dofs) {
  parameters.validate();
  if (static_cast<int>(coordination.size()) != parameters.matrices) {
    throw std::invalid_argument("DrDmp: needs " + std::to_string(parameters.matrices) + " coordination matrices, got " +
                                std::to_string(coordination.size()));
  }
  const auto r = coordination.front().cols();
  for (const Eigen::MatrixXd& omega : coordination) {
    if (omega.rows() != dofs || omega.cols() != r || r < 1 || r > dofs || !omega.allFinite()) {
      throw std::invalid_argument(
          "DrDmp: coordination matrices must be finite, all d x r with 1 <= r <= d (d = " + std::to_string(dofs) + ")");
    }
  }
  const int n = parameters.basisSize();
  if (weights.size() != r * n || !weights.allFinite()) {
    throw std::invalid_argument("DrDmp: needs r*" + std::string(parameters.goal_offsets ? "(kernels + 1)" : "kernels") +
                                " = " + std::to_string(r * n) + " finite latent weights");
  }
  return Eigen::Map<const RowMajorMatrix>(weights.data(), r, n);
}

}  // namespace

void DrDmpParameters::validate() const {
  dmp.validate();
  if (dmp.goal_scaled_forcing) throw std::invalid_argument("DrDmpParameters: goal_scaled_forcing is not supported");
  if (matrices < 1 || !(ridge >= 0.0)) {
    throw std::invalid_argument("DrDmpParameters: matrices must be >= 1 and ridge >= 0");
  }
}

DrDmp::DrDmp(const DrDmpParameters& parameters, const std::vector<Eigen::MatrixXd>& coordination,
             const Eigen::VectorXd& weights, const Eigen::VectorXd& start, const Eigen::VectorXd& goal, double duration)
    : parameters_(parameters),
      shape_(parameters.dmp, Eigen::MatrixXd::Zero(start.size(), parameters.dmp.kernels), start, goal, duration),
      coordination_(coordination),
      weights_(latentMatrix(parameters, coordination, weights, start.size())) {
  const int m = parameters_.matrices;
  blend_centres_ = Eigen::VectorXd::LinSpaced(m, 0.0, 1.0);
  const double spacing = m == 1 ? 1.0 : 1.0 / (m - 1);
  blend_widths_ = Eigen::VectorXd::Constant(m, 0.5 * spacing * spacing);
}

DrDmpFit DrDmp::fit(const DrDmpParameters& parameters, const std::vector<Eigen::MatrixXd>& demonstrations, double dt,
                    int latent_dims, double smoothing_hz) {
  parameters.validate();
  if (demonstrations.empty()) throw std::invalid_argument("DrDmp::fit: no demonstrations");
  const auto samples = demonstrations.front().rows(), d = demonstrations.front().cols();
  if (latent_dims < 1 || latent_dims > d) {
    throw std::invalid_argument("DrDmp::fit: latent_dims must be in [1, " + std::to_string(d) + "]");
  }
  std::vector<Eigen::MatrixXd> forcing;
  Eigen::VectorXd start = Eigen::VectorXd::Zero(d), goal = Eigen::VectorXd::Zero(d);
  for (const Eigen::MatrixXd& y : demonstrations) {
    if (y.rows() != samples || y.cols() != d) {
      throw std::invalid_argument("DrDmp::fit: all demonstrations must have the same number of samples and DoF");
    }
    forcing.push_back(Dmp::demonstratedForcing(parameters.dmp, y, dt, smoothing_hz).topRows(samples - 1));
    start += y.row(0).transpose() / static_cast<double>(demonstrations.size());
    goal += y.row(samples - 1).transpose() / static_cast<double>(demonstrations.size());
  }
  const double duration = dt * static_cast<double>(samples - 1);
  const int steps = static_cast<int>(samples - 1);
  const int n = parameters.dmp.kernels;
  // A model of the kernels alone gives the grid of the fit (the demonstrations reach their own goal: goal weights
  // 0); its coordination is replaced below.
  DrDmpParameters kernels_only = parameters;
  kernels_only.goal_offsets = false;
  std::vector<Eigen::MatrixXd> coordination(static_cast<std::size_t>(parameters.matrices),
                                            Eigen::MatrixXd::Identity(d, latent_dims));
  const DrDmp shape(kernels_only, coordination, Eigen::VectorXd::Zero(latent_dims * n), start, goal, duration);
  const learning::CoordinationGrid grid = shape.grid(dt, steps);
  const auto count = static_cast<Eigen::Index>(forcing.size());
  Eigen::MatrixXd all(d, count * steps);
  for (Eigen::Index k = 0; k < count; ++k)
    all.middleCols(k * steps, steps) = forcing[static_cast<std::size_t>(k)].transpose();
  Eigen::VectorXd singular_values;
  for (int s = 0; s < parameters.matrices; ++s) {
    const learning::PcaCoordination pca =
        learning::pcaCoordination(all, latent_dims, grid.activations().col(s).replicate(count, 1));
    coordination[static_cast<std::size_t>(s)] = pca.omega;
  }
  learning::alignCoordinationMatrices(coordination);
  singular_values = learning::pcaCoordination(all, latent_dims).singular_values;
  const int basis = parameters.basisSize();
  Eigen::MatrixXd latent = Eigen::MatrixXd::Zero(count, latent_dims * basis);
  for (Eigen::Index k = 0; k < count; ++k) {
    const Eigen::VectorXd fitted =
        learning::fitLatentWeights(grid, coordination, forcing[static_cast<std::size_t>(k)], parameters.ridge);
    for (int j = 0; j < latent_dims; ++j) latent.row(k).segment(j * basis, n) = fitted.segment(j * n, n).transpose();
  }
  const Eigen::VectorXd mean = latent.colwise().mean().transpose();
  return {DrDmp(parameters, coordination, mean, start, goal, duration), latent, singular_values,
          learning::weightedExcitation(grid, forcing, Eigen::VectorXd::Ones(count))};
}

Eigen::VectorXd DrDmp::weights() const {
  const RowMajorMatrix rows = weights_;
  return Eigen::Map<const Eigen::VectorXd>(rows.data(), rows.size());
}

Eigen::VectorXd DrDmp::goalOffset(double t) const {
  if (!parameters_.goal_offsets) return Eigen::VectorXd::Zero(dofs());
  Eigen::VectorXd a(matrices());
  activations(t, a);
  Eigen::MatrixXd blended(dofs(), latentDims());
  learning::blendCoordination(coordination_, a, blended);
  const double x = std::exp(-parameters_.dmp.alpha_x * t / duration());
  return (1.0 - x) * blended * weights_.col(kernels()) / (parameters_.dmp.alpha_z * parameters_.dmp.beta_z);
}

DrDmp DrDmp::withWeights(const Eigen::VectorXd& weights) const {
  return DrDmp(parameters_, coordination_, weights, start(), goal(), duration());
}

DrDmp DrDmp::withCoordination(const std::vector<Eigen::MatrixXd>& coordination, const Eigen::VectorXd& weights) const {
  return DrDmp(parameters_, coordination, weights, start(), goal(), duration());
}

learning::CoordinationGrid DrDmp::grid(double dt, int steps) const {
  if (steps < 1 || !(dt > 0.0)) throw std::invalid_argument("DrDmp::grid: needs steps >= 1 and dt > 0");
  Eigen::MatrixXd basis(steps, basisSize()), activation(steps, matrices());
  Eigen::VectorXd g(basisSize()), a(matrices());
  for (int k = 0; k < steps; ++k) {
    const double t = k * dt, x = std::exp(-parameters_.dmp.alpha_x * t / duration());
    shape_.basis(x, g.head(kernels()));
    if (parameters_.goal_offsets) g[kernels()] = 1.0 - x;
    activations(t, a);
    basis.row(k) = g.transpose();
    activation.row(k) = a.transpose();
  }
  return learning::CoordinationGrid(basis, activation);
}

DrDmpState DrDmp::initialState() const {
  DrDmpState state;
  state.dmp = shape_.initialState();
  state.exploration = Eigen::VectorXd::Zero(dofs());
  state.forcing = Eigen::VectorXd::Zero(dofs());
  state.basis = Eigen::VectorXd::Zero(basisSize());
  state.latent = Eigen::VectorXd::Zero(latentDims());
  state.activations = Eigen::VectorXd::Zero(matrices());
  state.blended = Eigen::MatrixXd::Zero(dofs(), latentDims());
  return state;
}

void DrDmp::activations(double t, Eigen::Ref<Eigen::VectorXd> out) const noexcept {
  normalisedGaussianBasis(std::clamp(t / duration(), 0.0, 1.0), blend_centres_, blend_widths_, 1.0, out);
}

DmpStatus DrDmp::step(DrDmpState& state, double dt) const noexcept {
  if (state.exploration.size() != dofs() || state.forcing.size() != dofs() || state.basis.size() != basisSize() ||
      state.latent.size() != latentDims() || state.activations.size() != matrices() || state.blended.rows() != dofs() ||
      state.blended.cols() != latentDims() || !state.exploration.allFinite() || !std::isfinite(state.dmp.x) ||
      !std::isfinite(state.dmp.t)) {
    return DmpStatus::InvalidInput;
  }
  shape_.basis(state.dmp.x, state.basis.head(kernels()));
  if (parameters_.goal_offsets) state.basis[kernels()] = 1.0 - state.dmp.x;
  state.latent.noalias() = weights_ * state.basis;
  activations(state.dmp.t, state.activations);
  learning::blendCoordination(coordination_, state.activations, state.blended);
  state.forcing.noalias() = state.blended * state.latent;
  state.forcing += state.exploration;
  return shape_.step(state.dmp, dt, state.forcing);
}

}  // namespace bimanual_skills::primitives
