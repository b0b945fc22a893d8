#include "bimanual_skills/learning/latent_trajectory_em.hpp"

#include "bimanual_skills/learning/ridge_regression.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>

#include <cmath>
#include <stdexcept>
#include <string>

namespace bimanual_skills::learning {
namespace {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// W (r × n, row j = ω_jᵀ) of latent weights ω.
Eigen::MatrixXd latentMatrix(const Eigen::VectorXd& weights, int r, int n) {
  return Eigen::Map<const RowMajorMatrix>(weights.data(), r, n);
}

/// vec_rows(W): ω of a latent weight matrix.
Eigen::VectorXd latentVector(const Eigen::MatrixXd& W) {
  const RowMajorMatrix rows = W;
  return Eigen::Map<const Eigen::VectorXd>(rows.data(), rows.size());
}

/// Q ⊗ G.
Eigen::MatrixXd kronecker(const Eigen::MatrixXd& Q, const Eigen::MatrixXd& G) {
  Eigen::MatrixXd out(Q.rows() * G.rows(), Q.cols() * G.cols());
  for (Eigen::Index i = 0; i < Q.rows(); ++i) {
    for (Eigen::Index j = 0; j < Q.cols(); ++j) out.block(i * G.rows(), j * G.cols(), G.rows(), G.cols()) = Q(i, j) * G;
  }
  return out;
}

/// The r × r matrix of tr(S_ij G) for the n × n blocks S_ij of S: Σ_t Ψ_tᵀ S Ψ_t.
Eigen::MatrixXd blockTraces(const Eigen::MatrixXd& S, const Eigen::MatrixXd& G, int r) {
  const auto n = G.rows();
  Eigen::MatrixXd out(r, r);
  for (int i = 0; i < r; ++i) {
    for (int j = 0; j < r; ++j) out(i, j) = S.block(i * n, j * n, n, n).cwiseProduct(G).sum();
  }
  return out;
}

Eigen::LLT<Eigen::MatrixXd> positiveDefinite(const Eigen::MatrixXd& matrix, const char* what) {
  Eigen::LLT<Eigen::MatrixXd> llt(matrix);
  if (llt.info() != Eigen::Success) {
    throw std::invalid_argument(std::string("latent trajectory model: ") + what + " is not positive definite");
  }
  return llt;
}

/// Everything the E-step, the M-step and the log-likelihood share, checked and computed once.
struct Prepared {
  int n, r, d, steps, contexts;
  Eigen::VectorXd p;                  ///< Normalised weights.
  Eigen::MatrixXd noise_inverse;      ///< Σ_y⁻¹.
  Eigen::MatrixXd projection;         ///< P = Ωᵀ Σ_y⁻¹ (r × d).
  Eigen::MatrixXd H;                  ///< (Ωᵀ Σ_y⁻¹ Ω) ⊗ G.
  Eigen::MatrixXd L;                  ///< Σ_ω = L Lᵀ.
  Eigen::LLT<Eigen::MatrixXd> inner;  ///< I + Lᵀ H L.
  double log_det_noise = 0.0;

  Prepared(const CoordinationGrid& grid, const LatentTrajectoryModel& model, const WeightedTrajectories& data) {
    if (grid.matrices() != 1) {
      throw std::invalid_argument("latent trajectory EM: the grid must have one coordination matrix");
    }
    n = grid.kernels();
    model.validate(n);
    r = model.latentDims();
    d = model.dofs();
    steps = grid.steps();
    contexts = static_cast<int>(model.context_gain.cols());
    data.validate(steps, d, contexts);
    p = data.weights / data.weights.sum();
    const Eigen::LLT<Eigen::MatrixXd> noise = positiveDefinite(model.noise, "Σ_y");
    noise_inverse = noise.solve(Eigen::MatrixXd::Identity(d, d));
    log_det_noise = 2.0 * noise.matrixLLT().diagonal().array().log().sum();
    projection = model.coordination.transpose() * noise_inverse;
    H = kronecker(projection * model.coordination, grid.product(0, 0));
    L = positiveDefinite(model.covariance, "Σ_ω").matrixL();
    inner.compute(Eigen::MatrixXd::Identity(r * n, r * n) + L.transpose() * H * L);
  }

  /// m_k = μ_ω + K_ω s_k.
  Eigen::VectorXd priorMean(const LatentTrajectoryModel& model, const WeightedTrajectories& data, int k) const {
    Eigen::VectorXd m = model.mean;
    if (contexts > 0) m.noalias() += model.context_gain * data.contexts.row(k).transpose();
    return m;
  }

  /// Aᵀ R⁻¹ vec(E) for values E (N_t × d): vec_rows(P Eᵀ Φ).
  Eigen::VectorXd whitenedProjection(const CoordinationGrid& grid, const Eigen::MatrixXd& values) const {
    return latentVector(projection * (values.transpose() * grid.basis()));
  }

  /// Σ_post = L (I + Lᵀ H L)⁻¹ Lᵀ.
  Eigen::MatrixXd posteriorCovariance() const {
    Eigen::MatrixXd covariance = L * inner.solve(L.transpose());
    return 0.5 * (covariance + covariance.transpose());
  }
};

/// The stacked trajectory [y_1; …; y_{N_t}].
Eigen::VectorXd stacked(const Eigen::MatrixXd& trajectory) {
  const Eigen::MatrixXd transposed = trajectory.transpose();
  return Eigen::Map<const Eigen::VectorXd>(transposed.data(), transposed.size());
}

/// The dense Γ = I ⊗ Σ_y + A Σ_ω Aᵀ, its Cholesky factorisation and A Σ_ω.
struct Dense {
  Eigen::MatrixXd A, A_sigma;
  Eigen::LLT<Eigen::MatrixXd> gamma;
  Dense(const CoordinationGrid& grid, const LatentTrajectoryModel& model, int steps, int d) {
    A = coordinatedDesign(grid, {model.coordination});
    A_sigma = A * model.covariance;
    Eigen::MatrixXd G = A_sigma * A.transpose();
    for (int t = 0; t < steps; ++t) G.block(t * d, t * d, d, d) += model.noise;
    gamma.compute(G);
    if (gamma.info() != Eigen::Success)
      throw std::invalid_argument("latent trajectory model: Γ is not positive definite");
  }
};

}  // namespace

void LatentTrajectoryModel::validate(int kernels) const {
  const auto d = coordination.rows(), r = coordination.cols();
  const auto size = r * kernels;
  if (d < 1 || r < 1 || r > d || kernels < 1) {
    throw std::invalid_argument("LatentTrajectoryModel: Omega must be d x r with 1 <= r <= d");
  }
  if (mean.size() != size || covariance.rows() != size || covariance.cols() != size) {
    throw std::invalid_argument("LatentTrajectoryModel: mu_w needs r*kernels = " + std::to_string(size) +
                                " entries and Sigma_w that square size");
  }
  if (noise.rows() != d || noise.cols() != d) {
    throw std::invalid_argument("LatentTrajectoryModel: Sigma_y must be d x d (" + std::to_string(d) + ")");
  }
  if (context_gain.cols() > 0 && context_gain.rows() != size) {
    throw std::invalid_argument("LatentTrajectoryModel: K_w must have r*kernels rows");
  }
  if (!coordination.allFinite() || !mean.allFinite() || !covariance.allFinite() || !noise.allFinite() ||
      !context_gain.allFinite()) {
    throw std::invalid_argument("LatentTrajectoryModel: parameters must be finite");
  }
}

void WeightedTrajectories::validate(int steps, int dofs, int context_size) const {
  const auto count = static_cast<Eigen::Index>(trajectories.size());
  if (count < 1) throw std::invalid_argument("WeightedTrajectories: no trajectories");
  for (std::size_t k = 0; k < trajectories.size(); ++k) {
    if (trajectories[k].rows() != steps || trajectories[k].cols() != dofs || !trajectories[k].allFinite()) {
      throw std::invalid_argument("WeightedTrajectories: trajectory " + std::to_string(k) + " must be finite, " +
                                  std::to_string(steps) + " steps x " + std::to_string(dofs) + " DoF");
    }
  }
  if (weights.size() != count || !weights.allFinite() || (weights.array() < 0.0).any() || !(weights.sum() > 0.0)) {
    throw std::invalid_argument("WeightedTrajectories: one finite weight >= 0 per trajectory, not all zero");
  }
  if (contexts.cols() != context_size || (context_size > 0 && contexts.rows() != count) || !contexts.allFinite()) {
    throw std::invalid_argument("WeightedTrajectories: contexts must be trajectories x " +
                                std::to_string(context_size) + " (the model's K_w columns), finite");
  }
}

void LatentEmParameters::validate() const {
  if (max_iterations < 0 || !(tolerance >= 0.0) || !(noise_floor >= 0.0) || !(covariance_floor >= 0.0) ||
      !(context_ridge >= 0.0)) {
    throw std::invalid_argument("LatentEmParameters: iterations, tolerance, floors and ridge must be >= 0");
  }
}

void LatentPcaParameters::validate() const {
  if (!(ridge >= 0.0) || !(covariance_prior >= 0.0) || !(noise_floor >= 0.0)) {
    throw std::invalid_argument("LatentPcaParameters: ridge, covariance_prior and noise_floor must be >= 0");
  }
}

LatentPosterior latentEStep(const CoordinationGrid& grid, const LatentTrajectoryModel& model,
                            const WeightedTrajectories& data) {
  const Prepared prepared(grid, model, data);
  LatentPosterior out;
  out.covariance = prepared.posteriorCovariance();
  out.means.resize(prepared.r * prepared.n, static_cast<Eigen::Index>(data.trajectories.size()));
  for (int k = 0; k < out.means.cols(); ++k) {
    const Eigen::VectorXd m = prepared.priorMean(model, data, k);
    const Eigen::VectorXd c =
        prepared.whitenedProjection(grid, data.trajectories[static_cast<std::size_t>(k)]) - prepared.H * m;
    out.means.col(k) = m + out.covariance * c;
  }
  return out;
}

LatentPosterior latentEStepNaive(const CoordinationGrid& grid, const LatentTrajectoryModel& model,
                                 const WeightedTrajectories& data) {
  const Prepared prepared(grid, model, data);
  const Dense dense(grid, model, prepared.steps, prepared.d);
  LatentPosterior out;
  out.covariance = model.covariance - dense.A_sigma.transpose() * dense.gamma.solve(dense.A_sigma);
  out.covariance = 0.5 * (out.covariance + out.covariance.transpose());
  out.means.resize(prepared.r * prepared.n, static_cast<Eigen::Index>(data.trajectories.size()));
  for (int k = 0; k < out.means.cols(); ++k) {
    const Eigen::VectorXd m = prepared.priorMean(model, data, k);
    const Eigen::VectorXd e = stacked(data.trajectories[static_cast<std::size_t>(k)]) - dense.A * m;
    out.means.col(k) = m + dense.A_sigma.transpose() * dense.gamma.solve(e);
  }
  return out;
}

LatentTrajectoryModel latentMStep(const CoordinationGrid& grid, const LatentTrajectoryModel& model,
                                  const WeightedTrajectories& data, const LatentPosterior& posterior,
                                  const LatentEmParameters& parameters) {
  parameters.validate();
  const Prepared prepared(grid, model, data);
  const int n = prepared.n, r = prepared.r, d = prepared.d, M = prepared.contexts;
  const auto count = static_cast<Eigen::Index>(data.trajectories.size());
  if (posterior.means.rows() != r * n || posterior.means.cols() != count || posterior.covariance.rows() != r * n ||
      posterior.covariance.cols() != r * n) {
    throw std::invalid_argument("latentMStep: the posterior does not match the model and data");
  }
  const Eigen::VectorXd& p = prepared.p;
  const Eigen::MatrixXd& G = grid.product(0, 0);
  LatentTrajectoryModel out = model;
  // (7.15) and (7.18): weighted least squares of μ_k on [1; s_k].
  if (M > 0) {
    Eigen::MatrixXd X(count, 1 + M);
    X.col(0).setOnes();
    X.rightCols(M) = data.contexts;
    const Eigen::VectorXd root = p.cwiseSqrt();
    const Eigen::MatrixXd coefficients = ridgeLeastSquares(
        root.asDiagonal() * X, root.asDiagonal() * posterior.means.transpose(), parameters.context_ridge, 1);
    out.mean = coefficients.row(0).transpose();
    out.context_gain = coefficients.bottomRows(M).transpose();
  } else {
    out.mean = posterior.means * p;
  }
  // (7.16).
  Eigen::MatrixXd residuals = posterior.means.colwise() - out.mean;
  if (M > 0) residuals.noalias() -= out.context_gain * data.contexts.transpose();
  out.covariance = posterior.covariance + residuals * p.asDiagonal() * residuals.transpose();
  out.covariance = 0.5 * (out.covariance + out.covariance.transpose());
  out.covariance.diagonal().array() += parameters.covariance_floor;
  // (7.17).
  std::vector<Eigen::MatrixXd> latent(static_cast<std::size_t>(count));  // W_k of μ_k
  for (Eigen::Index k = 0; k < count; ++k)
    latent[static_cast<std::size_t>(k)] = latentMatrix(posterior.means.col(k), r, n);
  if (parameters.update_coordination) {
    Eigen::MatrixXd cross = Eigen::MatrixXd::Zero(d, r);
    for (Eigen::Index k = 0; k < count; ++k) {
      cross.noalias() += p[k] * (data.trajectories[static_cast<std::size_t>(k)].transpose() * grid.basis()) *
                         latent[static_cast<std::size_t>(k)].transpose();
    }
    const Eigen::MatrixXd S = posterior.covariance + posterior.means * p.asDiagonal() * posterior.means.transpose();
    const Eigen::MatrixXd second = blockTraces(S, G, r);
    out.coordination = cross * Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(second).pseudoInverse();
  }
  // (7.19) with the new Ω.
  const Eigen::MatrixXd& omega = out.coordination;
  Eigen::MatrixXd noise = omega * blockTraces(posterior.covariance, G, r) * omega.transpose();
  for (Eigen::Index k = 0; k < count; ++k) {
    const Eigen::MatrixXd E = data.trajectories[static_cast<std::size_t>(k)] -
                              grid.basis() * latent[static_cast<std::size_t>(k)].transpose() * omega.transpose();
    noise.noalias() += p[k] * E.transpose() * E;
  }
  out.noise = noise / static_cast<double>(prepared.steps);
  out.noise = 0.5 * (out.noise + out.noise.transpose());
  out.noise.diagonal().array() += parameters.noise_floor;
  return out;
}

double latentLogLikelihood(const CoordinationGrid& grid, const LatentTrajectoryModel& model,
                           const WeightedTrajectories& data) {
  const Prepared prepared(grid, model, data);
  const Eigen::MatrixXd posterior_covariance = prepared.posteriorCovariance();
  const double log_det_gamma =
      prepared.steps * prepared.log_det_noise + 2.0 * prepared.inner.matrixLLT().diagonal().array().log().sum();
  const double constant = static_cast<double>(prepared.steps * prepared.d) * std::log(2.0 * M_PI) + log_det_gamma;
  double total = 0.0;
  for (int k = 0; k < static_cast<int>(data.trajectories.size()); ++k) {
    const Eigen::VectorXd m = prepared.priorMean(model, data, k);
    const Eigen::MatrixXd E =
        data.trajectories[static_cast<std::size_t>(k)] -
        grid.basis() * latentMatrix(m, prepared.r, prepared.n).transpose() * model.coordination.transpose();
    const Eigen::VectorXd c = prepared.whitenedProjection(grid, E);
    const double quadratic = (E * prepared.noise_inverse).cwiseProduct(E).sum() - c.dot(posterior_covariance * c);
    total += data.weights[k] * -0.5 * (constant + quadratic);
  }
  return total;
}

double latentLogLikelihoodNaive(const CoordinationGrid& grid, const LatentTrajectoryModel& model,
                                const WeightedTrajectories& data) {
  const Prepared prepared(grid, model, data);
  const Dense dense(grid, model, prepared.steps, prepared.d);
  const double log_det_gamma = 2.0 * dense.gamma.matrixLLT().diagonal().array().log().sum();
  const double constant = static_cast<double>(prepared.steps * prepared.d) * std::log(2.0 * M_PI) + log_det_gamma;
  double total = 0.0;
  for (int k = 0; k < static_cast<int>(data.trajectories.size()); ++k) {
    const Eigen::VectorXd e =
        stacked(data.trajectories[static_cast<std::size_t>(k)]) - dense.A * prepared.priorMean(model, data, k);
    total += data.weights[k] * -0.5 * (constant + e.dot(dense.gamma.solve(e)));
  }
  return total;
}

LatentEmResult latentEm(const CoordinationGrid& grid, const WeightedTrajectories& data,
                        const LatentTrajectoryModel& initial, const LatentEmParameters& parameters) {
  parameters.validate();
  LatentEmResult out;
  out.model = initial;
  out.log_likelihood.push_back(latentLogLikelihood(grid, out.model, data));
  for (int i = 0; i < parameters.max_iterations; ++i) {
    const LatentPosterior posterior = latentEStep(grid, out.model, data);
    out.model = latentMStep(grid, out.model, data, posterior, parameters);
    out.iterations = i + 1;
    const double previous = out.log_likelihood.back();
    out.log_likelihood.push_back(latentLogLikelihood(grid, out.model, data));
    if (out.log_likelihood.back() - previous < parameters.tolerance * (1.0 + std::abs(out.log_likelihood.back()))) {
      break;
    }
  }
  return out;
}

LatentTrajectoryModel latentPcaModel(const CoordinationGrid& grid, const WeightedTrajectories& data, int r,
                                     const LatentPcaParameters& parameters) {
  parameters.validate();
  if (grid.matrices() != 1) throw std::invalid_argument("latentPcaModel: the grid must have one coordination matrix");
  if (data.trajectories.empty()) throw std::invalid_argument("latentPcaModel: no trajectories");
  const int steps = grid.steps(), n = grid.kernels();
  const auto d = static_cast<int>(data.trajectories.front().cols());
  const auto M = static_cast<int>(data.contexts.cols());
  data.validate(steps, d, M);
  const auto count = static_cast<Eigen::Index>(data.trajectories.size());
  const Eigen::VectorXd p = data.weights / data.weights.sum();
  // Ω: principal directions of every y_t^k, each weighted by its trajectory's d_k.
  Eigen::MatrixXd samples(d, count * steps);
  Eigen::VectorXd column_weights(count * steps);
  for (Eigen::Index k = 0; k < count; ++k) {
    samples.middleCols(k * steps, steps) = data.trajectories[static_cast<std::size_t>(k)].transpose();
    column_weights.segment(k * steps, steps).setConstant(p[k]);
  }
  LatentTrajectoryModel model;
  model.coordination = pcaCoordination(samples, r, column_weights).omega;
  const std::vector<Eigen::MatrixXd> matrices = {model.coordination};
  Eigen::MatrixXd weights(r * n, count);
  for (Eigen::Index k = 0; k < count; ++k) {
    weights.col(k) = fitLatentWeights(grid, matrices, data.trajectories[static_cast<std::size_t>(k)], parameters.ridge);
  }
  if (M > 0) {  // (7.20)
    Eigen::MatrixXd S(count, 1 + M);
    S.col(0).setOnes();
    S.rightCols(M) = data.contexts;
    const Eigen::VectorXd root = p.cwiseSqrt();
    const Eigen::MatrixXd coefficients =
        ridgeLeastSquares(root.asDiagonal() * S, root.asDiagonal() * weights.transpose(), parameters.ridge);
    model.mean = coefficients.row(0).transpose();
    model.context_gain = coefficients.bottomRows(M).transpose();
  } else {
    model.mean = weights * p;
    model.context_gain = Eigen::MatrixXd(r * n, 0);
  }
  Eigen::MatrixXd residuals = weights.colwise() - model.mean;
  if (M > 0) residuals.noalias() -= model.context_gain * data.contexts.transpose();
  model.covariance = residuals * p.asDiagonal() * residuals.transpose();
  model.covariance.diagonal().array() += parameters.covariance_prior;
  model.noise = Eigen::MatrixXd::Zero(d, d);
  for (Eigen::Index k = 0; k < count; ++k) {
    const Eigen::MatrixXd E =
        data.trajectories[static_cast<std::size_t>(k)] - coordinatedValues(grid, matrices, weights.col(k));
    model.noise.noalias() += p[k] / steps * E.transpose() * E;
  }
  model.noise.diagonal().array() += parameters.noise_floor;
  return model;
}

void latentMarginal(const CoordinationGrid& grid, const LatentTrajectoryModel& model, int step,
                    const Eigen::VectorXd& context, Eigen::VectorXd& mean, Eigen::MatrixXd& covariance) {
  const int n = grid.kernels();
  model.validate(n);
  if (step < 0 || step >= grid.steps() || context.size() != model.context_gain.cols()) {
    throw std::invalid_argument("latentMarginal: step outside the grid or a context of the wrong size");
  }
  const int r = model.latentDims();
  Eigen::VectorXd m = model.mean;
  if (context.size() > 0) m.noalias() += model.context_gain * context;
  const Eigen::VectorXd phi = grid.basis().row(step).transpose();
  mean = model.coordination * (latentMatrix(m, r, n) * phi);
  Eigen::MatrixXd latent(r, r);
  for (int i = 0; i < r; ++i) {
    for (int j = 0; j < r; ++j) latent(i, j) = phi.dot(model.covariance.block(i * n, j * n, n, n) * phi);
  }
  covariance = model.coordination * latent * model.coordination.transpose() + model.noise;
}

}  // namespace bimanual_skills::learning
