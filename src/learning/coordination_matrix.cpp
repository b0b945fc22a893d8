#include "bimanual_skills/learning/coordination_matrix.hpp"

#include "bimanual_skills/learning/ridge_regression.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

namespace bimanual_skills::learning {
namespace {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// Checks that `matrices` holds grid.matrices() matrices of one size (d × r, r ≥ 1) and returns r.
int checkMatrices(const CoordinationGrid& grid, const std::vector<Eigen::MatrixXd>& matrices, const char* who) {
  if (static_cast<int>(matrices.size()) != grid.matrices() || matrices.empty()) {
    throw std::invalid_argument(std::string(who) + ": needs " + std::to_string(grid.matrices()) +
                                " coordination matrices, got " + std::to_string(matrices.size()));
  }
  for (const Eigen::MatrixXd& m : matrices) {
    if (m.rows() != matrices.front().rows() || m.cols() != matrices.front().cols() || m.cols() < 1 ||
        m.rows() < m.cols() || !m.allFinite()) {
      throw std::invalid_argument(std::string(who) +
                                  ": coordination matrices must be finite, all d x r with 1 <= r <= d");
    }
  }
  return static_cast<int>(matrices.front().cols());
}

/// The latent weights ω (r n) as W (r × n): row j = ω_jᵀ.
Eigen::MatrixXd latentMatrix(const Eigen::VectorXd& weights, int r, int n) {
  return Eigen::Map<const RowMajorMatrix>(weights.data(), r, n);
}

/// Normalised copy of non-negative weights (not all zero) of the given count.
Eigen::VectorXd normalisedWeights(const Eigen::VectorXd& weights, Eigen::Index count, const char* who) {
  if (weights.size() != count || !weights.allFinite() || (weights.array() < 0.0).any() || !(weights.sum() > 0.0)) {
    throw std::invalid_argument(std::string(who) + ": needs " + std::to_string(count) +
                                " finite, non-negative weights, not all zero");
  }
  return weights / weights.sum();
}

}  // namespace

CoordinationGrid::CoordinationGrid(const Eigen::MatrixXd& basis, const Eigen::MatrixXd& activations)
    : basis_(basis), activations_(activations) {
  if (basis_.rows() < 1 || basis_.cols() < 1 || activations_.rows() != basis_.rows() || activations_.cols() < 1 ||
      !basis_.allFinite() || !activations_.allFinite()) {
    throw std::invalid_argument(
        "CoordinationGrid: needs a finite basis (steps x kernels) and finite activations (steps x matrices) with "
        "the same number of steps");
  }
  const int m = matrices();
  products_.resize(static_cast<std::size_t>(m * m));
  for (int s = 0; s < m; ++s) {
    for (int s2 = s; s2 < m; ++s2) {
      const Eigen::VectorXd a = activations_.col(s).cwiseProduct(activations_.col(s2));
      Eigen::MatrixXd G = basis_.transpose() * a.asDiagonal() * basis_;
      products_[static_cast<std::size_t>(s2 * m + s)] = G;
      products_[static_cast<std::size_t>(s * m + s2)] = std::move(G);
    }
  }
}

CoordinationGrid::CoordinationGrid(const Eigen::MatrixXd& basis)
    : CoordinationGrid(basis, Eigen::MatrixXd::Ones(basis.rows(), 1)) {}

const Eigen::MatrixXd& CoordinationGrid::product(int s, int s2) const {
  if (s < 0 || s2 < 0 || s >= matrices() || s2 >= matrices()) {
    throw std::out_of_range("CoordinationGrid::product: matrix index out of range");
  }
  return products_[static_cast<std::size_t>(s * matrices() + s2)];
}

void blendCoordination(const std::vector<Eigen::MatrixXd>& matrices,
                       const Eigen::Ref<const Eigen::VectorXd>& activations, Eigen::Ref<Eigen::MatrixXd> out) noexcept {
  out.setZero();
  for (std::size_t s = 0; s < matrices.size(); ++s) out += activations[static_cast<Eigen::Index>(s)] * matrices[s];
}

Eigen::MatrixXd coordinatedGram(const CoordinationGrid& grid, const std::vector<Eigen::MatrixXd>& a,
                                const std::vector<Eigen::MatrixXd>& b) {
  const int ra = checkMatrices(grid, a, "coordinatedGram");
  const int rb = checkMatrices(grid, b, "coordinatedGram");
  if (a.front().rows() != b.front().rows()) {
    throw std::invalid_argument("coordinatedGram: both coordinations need the same number of DoF");
  }
  const int n = grid.kernels();
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(ra * n, rb * n);
  for (int s = 0; s < grid.matrices(); ++s) {
    for (int s2 = 0; s2 < grid.matrices(); ++s2) {
      const Eigen::MatrixXd C = a[static_cast<std::size_t>(s)].transpose() * b[static_cast<std::size_t>(s2)];
      const Eigen::MatrixXd& G = grid.product(s, s2);
      for (int i = 0; i < ra; ++i) {
        for (int j = 0; j < rb; ++j) out.block(i * n, j * n, n, n) += C(i, j) * G;
      }
    }
  }
  return out;
}

Eigen::MatrixXd coordinatedDesign(const CoordinationGrid& grid, const std::vector<Eigen::MatrixXd>& matrices) {
  const int r = checkMatrices(grid, matrices, "coordinatedDesign");
  const auto d = matrices.front().rows();
  const int n = grid.kernels();
  Eigen::MatrixXd design(grid.steps() * d, r * n);
  Eigen::MatrixXd omega(d, r);
  for (int t = 0; t < grid.steps(); ++t) {
    blendCoordination(matrices, grid.activations().row(t).transpose(), omega);
    for (int j = 0; j < r; ++j) {
      design.block(t * d, j * n, d, n).noalias() = omega.col(j) * grid.basis().row(t);  // Ω^t ⊗ φ_tᵀ
    }
  }
  return design;
}

Eigen::MatrixXd coordinatedValues(const CoordinationGrid& grid, const std::vector<Eigen::MatrixXd>& matrices,
                                  const Eigen::VectorXd& weights) {
  const int r = checkMatrices(grid, matrices, "coordinatedValues");
  if (weights.size() != r * grid.kernels()) {
    throw std::invalid_argument("coordinatedValues: needs " + std::to_string(r * grid.kernels()) + " latent weights");
  }
  const Eigen::MatrixXd latent = grid.basis() * latentMatrix(weights, r, grid.kernels()).transpose();  // N_t × r
  Eigen::MatrixXd values = Eigen::MatrixXd::Zero(grid.steps(), matrices.front().rows());
  for (int s = 0; s < grid.matrices(); ++s) {
    values.noalias() +=
        grid.activations().col(s).asDiagonal() * latent * matrices[static_cast<std::size_t>(s)].transpose();
  }
  return values;
}

Eigen::VectorXd fitLatentWeights(const CoordinationGrid& grid, const std::vector<Eigen::MatrixXd>& matrices,
                                 const Eigen::MatrixXd& values, double ridge) {
  checkMatrices(grid, matrices, "fitLatentWeights");
  if (values.rows() != grid.steps() || values.cols() != matrices.front().rows()) {
    throw std::invalid_argument("fitLatentWeights: values must be steps x dofs (" + std::to_string(grid.steps()) +
                                " x " + std::to_string(matrices.front().rows()) + ")");
  }
  const Eigen::MatrixXd stacked = values.transpose();  // column-major d × N_t: the d values of each step in turn
  return ridgeLeastSquares(coordinatedDesign(grid, matrices),
                           Eigen::Map<const Eigen::VectorXd>(stacked.data(), stacked.size()), ridge);
}

PcaCoordination pcaCoordination(const Eigen::MatrixXd& samples, int r, const Eigen::VectorXd& column_weights) {
  const auto d = samples.rows();
  if (r < 1 || r > d || samples.cols() < 1 || !samples.allFinite()) {
    throw std::invalid_argument("pcaCoordination: needs finite samples (d x N) and 1 <= r <= d (r = " +
                                std::to_string(r) + ", d = " + std::to_string(d) + ")");
  }
  const Eigen::VectorXd w = column_weights.size() == 0
                                ? Eigen::VectorXd::Constant(samples.cols(), 1.0 / static_cast<double>(samples.cols()))
                                : normalisedWeights(column_weights, samples.cols(), "pcaCoordination");
  const Eigen::VectorXd mean = samples * w;
  const Eigen::MatrixXd centred = samples.colwise() - mean;
  // Left singular vectors and singular values of centred · diag(√(N w)) from its d × d scatter matrix.
  const Eigen::MatrixXd scatter =
      centred * (static_cast<double>(samples.cols()) * w).asDiagonal() * centred.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(scatter);
  PcaCoordination out;
  out.singular_values = eigen.eigenvalues().reverse().cwiseMax(0.0).cwiseSqrt();
  out.omega = eigen.eigenvectors().rightCols(r).rowwise().reverse();
  for (int j = 0; j < r; ++j) {
    Eigen::Index largest = 0;
    out.omega.col(j).cwiseAbs().maxCoeff(&largest);
    if (out.omega(largest, j) < 0.0) out.omega.col(j) *= -1.0;
  }
  return out;
}

void alignCoordinationMatrices(std::vector<Eigen::MatrixXd>& matrices) {
  if (matrices.empty()) return;
  const Eigen::MatrixXd& reference = matrices.front();
  const auto r = reference.cols();
  for (const Eigen::MatrixXd& m : matrices) {
    if (m.rows() != reference.rows() || m.cols() != r) {
      throw std::invalid_argument("alignCoordinationMatrices: all matrices must have the same size");
    }
  }
  for (std::size_t s = 1; s < matrices.size(); ++s) {
    const Eigen::MatrixXd K = reference.transpose() * matrices[s];  // K(i1, i2) = Ω_1(:, i1) · Ω_s(:, i2)
    const Eigen::MatrixXd A = K.cwiseAbs();
    Eigen::MatrixXd rotation = Eigen::MatrixXd::Zero(r, r);  // PCAROT
    std::vector<bool> row_used(static_cast<std::size_t>(r), false), column_used(static_cast<std::size_t>(r), false);
    const auto assign = [&](Eigen::Index i, Eigen::Index j) {
      rotation(i, j) = K(i, j) < 0.0 ? -1.0 : 1.0;
      row_used[static_cast<std::size_t>(i)] = column_used[static_cast<std::size_t>(j)] = true;
    };
    // Lines 7–13: column j goes to the row of its largest |K| when that entry is also the largest of its row.
    for (Eigen::Index j = 0; j < r; ++j) {
      Eigen::Index i = 0;
      const double v = A.col(j).maxCoeff(&i);
      if (v == A.row(i).maxCoeff() && !row_used[static_cast<std::size_t>(i)]) assign(i, j);
    }
    // Completion (rank(PCAROT) < r): greedily the largest |K| among the unassigned rows and columns.
    for (;;) {
      double best = -1.0;
      Eigen::Index bi = -1, bj = -1;
      for (Eigen::Index i = 0; i < r; ++i) {
        for (Eigen::Index j = 0; j < r; ++j) {
          if (!row_used[static_cast<std::size_t>(i)] && !column_used[static_cast<std::size_t>(j)] && A(i, j) > best) {
            best = A(i, j);
            bi = i;
            bj = j;
          }
        }
      }
      if (bi < 0) break;
      assign(bi, bj);
    }
    matrices[s] = matrices[s] * rotation.transpose();
  }
}

namespace {

/// The LDLT of (O Ψᵀ)ᵀ O Ψᵀ, checked for full rank.
Eigen::LDLT<Eigen::MatrixXd> normalEquations(const CoordinationGrid& grid, const std::vector<Eigen::MatrixXd>& matrices,
                                             const char* which) {
  const Eigen::LDLT<Eigen::MatrixXd> normal(coordinatedGram(grid, matrices, matrices));
  const Eigen::VectorXd& D = normal.vectorD();
  if (normal.info() != Eigen::Success || !(D.minCoeff() > 1e-12 * D.cwiseAbs().maxCoeff())) {
    throw std::invalid_argument(std::string("LatentReprojection: the ") + which +
                                " coordination and basis do not have full column rank (a zero or repeated column of "
                                "a coordination matrix, or fewer steps than kernels)");
  }
  return normal;
}

}  // namespace

LatentReprojection::LatentReprojection(const CoordinationGrid& grid, const std::vector<Eigen::MatrixXd>& old_matrices,
                                       const std::vector<Eigen::MatrixXd>& new_matrices, ReprojectionRule rule)
    : rule_(rule) {
  checkMatrices(grid, old_matrices, "LatentReprojection");
  checkMatrices(grid, new_matrices, "LatentReprojection");
  // M = ((Ô Ψ̂ᵀ)ᵀ Ô Ψ̂ᵀ)⁻¹ (Ô Ψ̂ᵀ)ᵀ O Ψᵀ and N = ((O Ψᵀ)ᵀ O Ψᵀ)⁻¹ (O Ψᵀ)ᵀ Ô Ψ̂ᵀ, pseudoinverses of full column rank.
  const Eigen::MatrixXd cross = coordinatedGram(grid, old_matrices, new_matrices);
  M_ = normalEquations(grid, old_matrices, "old").solve(cross);
  M_pinv_ = Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(M_).pseudoInverse();
  N_ = normalEquations(grid, new_matrices, "new").solve(cross.transpose());
}

Eigen::VectorXd LatentReprojection::mean(const Eigen::VectorXd& old_mean) const {
  if (old_mean.size() != M_.rows()) {
    throw std::invalid_argument("LatentReprojection: the old mean needs " + std::to_string(M_.rows()) + " entries");
  }
  return sampleMap() * old_mean;
}

Eigen::MatrixXd LatentReprojection::covariance(const Eigen::VectorXd& old_mean,
                                               const Eigen::MatrixXd& old_covariance) const {
  if (old_covariance.rows() != M_.rows() || old_covariance.cols() != M_.rows()) {
    throw std::invalid_argument("LatentReprojection: the old covariance must be " + std::to_string(M_.rows()) +
                                " square");
  }
  Eigen::MatrixXd covariance;
  if (rule_ == ReprojectionRule::Printed) {
    const Eigen::VectorXd residual = M_ * mean(old_mean) - old_mean;
    covariance = M_pinv_ * (old_covariance + residual * residual.transpose()) * M_pinv_.transpose();
  } else {
    covariance = N_ * old_covariance * N_.transpose();
  }
  return 0.5 * (covariance + covariance.transpose());
}

void CoordinationUpdateParameters::validate() const {
  if (!(eta > 1.0) || !(filter > 0.0) || !(filter <= 1.0) || min_latent_dims < 1) {
    throw std::invalid_argument(
        "CoordinationUpdateParameters: need eta > 1 (infinity: fixed dimension), filter in (0, 1] and "
        "min_latent_dims >= 1");
  }
}

std::vector<Eigen::MatrixXd> weightedExcitation(const CoordinationGrid& grid,
                                                const std::vector<Eigen::MatrixXd>& values,
                                                const Eigen::VectorXd& weights) {
  if (values.empty()) throw std::invalid_argument("weightedExcitation: no rollouts");
  const Eigen::VectorXd p = normalisedWeights(weights, static_cast<Eigen::Index>(values.size()), "weightedExcitation");
  const auto d = values.front().cols();
  Eigen::MatrixXd mean = Eigen::MatrixXd::Zero(grid.steps(), d);
  for (std::size_t k = 0; k < values.size(); ++k) {
    if (values[k].rows() != grid.steps() || values[k].cols() != d || d < 1 || !values[k].allFinite()) {
      throw std::invalid_argument("weightedExcitation: every rollout's values must be finite, steps x dofs (" +
                                  std::to_string(grid.steps()) + " x " + std::to_string(d) + ")");
    }
    mean += p[static_cast<Eigen::Index>(k)] * values[k];
  }
  std::vector<Eigen::MatrixXd> out;
  for (int s = 0; s < grid.matrices(); ++s) {
    out.push_back((grid.activations().col(s).asDiagonal() * mean).transpose());
  }
  return out;
}

CoordinationUpdateResult coordinationMatrixUpdate(const CoordinationGrid& grid,
                                                  const CoordinationUpdateParameters& parameters,
                                                  const std::vector<Eigen::MatrixXd>& matrices,
                                                  const std::vector<Eigen::MatrixXd>& previous_excitation,
                                                  const std::vector<Eigen::MatrixXd>& values,
                                                  const Eigen::VectorXd& weights, const Eigen::VectorXd& mean,
                                                  const Eigen::MatrixXd& covariance) {
  parameters.validate();
  int r = checkMatrices(grid, matrices, "coordinationMatrixUpdate");
  const auto d = matrices.front().rows();
  if (!values.empty() && values.front().cols() != d) {
    throw std::invalid_argument("coordinationMatrixUpdate: the values need one column per DoF (" + std::to_string(d) +
                                ")");
  }
  CoordinationUpdateResult out;
  out.excitation = weightedExcitation(grid, values, weights);  // line 1
  if (!previous_excitation.empty()) {                          // line 2
    if (previous_excitation.size() != out.excitation.size()) {
      throw std::invalid_argument("coordinationMatrixUpdate: one previous excitation per coordination matrix");
    }
    for (std::size_t s = 0; s < out.excitation.size(); ++s) {
      if (previous_excitation[s].rows() != d || previous_excitation[s].cols() != grid.steps()) {
        throw std::invalid_argument("coordinationMatrixUpdate: a previous excitation is not dofs x steps");
      }
      out.excitation[s] = parameters.filter * out.excitation[s] + (1.0 - parameters.filter) * previous_excitation[s];
    }
  }
  // Lines 3–7 on the pooled excitation (with one matrix, F_co itself).
  Eigen::MatrixXd pooled = Eigen::MatrixXd::Zero(d, grid.steps());
  for (const Eigen::MatrixXd& F : out.excitation) pooled += F;
  const PcaCoordination whole = pcaCoordination(pooled, r);
  out.singular_values = whole.singular_values;
  if (r > parameters.min_latent_dims && out.singular_values[0] > parameters.eta * out.singular_values[r - 1]) {
    --r;
    out.reduced = true;
  }
  // Line 8.
  if (grid.matrices() == 1) {
    out.matrices = {whole.omega.leftCols(r)};
  } else {
    for (const Eigen::MatrixXd& F : out.excitation) out.matrices.push_back(pcaCoordination(F, r).omega);
    alignCoordinationMatrices(out.matrices);
  }
  // Line 9.
  const LatentReprojection reprojection(grid, matrices, out.matrices, parameters.reprojection);
  out.mean = reprojection.mean(mean);
  out.covariance = reprojection.covariance(mean, covariance);
  out.sample_map = reprojection.sampleMap();
  return out;
}

}  // namespace bimanual_skills::learning
