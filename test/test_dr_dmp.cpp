// DR-DMP (thesis Sec. 7.2) and its coordination matrices: the Kronecker-structured products equal the dense ones;
// PCA gives the SVD's directions; Alg. 7.3 aligns permuted and sign-flipped bases; the reprojection (7.34–7.36) is
// the printed pseudoinverse, its least-squares variant stays bounded where the printed one amplifies, and both keep
// the forcing-term distribution when Ω does not change (or only turns within its span); CMU drops a dimension exactly
// when σ_1/σ_r > η; a DR-DMP with one matrix is the DMP with weights Ω W and blends several matrices by (7.39); the
// fixed-coordination learner is REPS; bad input throws.
#include "bimanual_skills/learning/coordinated_reps.hpp"
#include "bimanual_skills/learning/coordination_matrix.hpp"
#include "bimanual_skills/learning/gaussian.hpp"
#include "bimanual_skills/learning/reps.hpp"
#include "bimanual_skills/primitives/dmp.hpp"
#include "bimanual_skills/primitives/dr_dmp.hpp"
#include "testing/random_matrices.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/QR>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

namespace bl = bimanual_skills::learning;
namespace bp = bimanual_skills::primitives;

using bimanual_skills::testing::randomMatrix;
const auto& orthonormal = bimanual_skills::testing::randomOrthonormal;

namespace {

/// A DR-DMP's grid: `kernels` DMP kernels and `matrices` activations over `steps` steps of 10 ms.
bl::CoordinationGrid dmpGrid(int dofs, int kernels, int matrices, int steps) {
  bp::DrDmpParameters parameters;
  parameters.dmp.kernels = kernels;
  parameters.matrices = matrices;
  const std::vector<Eigen::MatrixXd> omega(static_cast<std::size_t>(matrices), Eigen::MatrixXd::Identity(dofs, 1));
  const bp::DrDmp dmp(parameters, omega, Eigen::VectorXd::Zero(kernels), Eigen::VectorXd::Zero(dofs),
                      Eigen::VectorXd::Ones(dofs), 0.01 * steps);
  return dmp.grid(0.01, steps);
}

/// The distribution of the stacked values O Ψᵀ ω, ω ~ N(mean, covariance), from the dense design.
std::pair<Eigen::VectorXd, Eigen::MatrixXd> valueDistribution(const bl::CoordinationGrid& grid,
                                                              const std::vector<Eigen::MatrixXd>& omega,
                                                              const Eigen::VectorXd& mean,
                                                              const Eigen::MatrixXd& covariance) {
  const Eigen::MatrixXd A = bl::coordinatedDesign(grid, omega);
  return {A * mean, A * covariance * A.transpose()};
}

}  // namespace

TEST(CoordinationMatrix, StructuredProductsEqualTheDenseOnes) {
  std::mt19937 rng(1);
  const bl::CoordinationGrid grid = dmpGrid(5, 6, 3, 40);
  const std::vector<Eigen::MatrixXd> a = {randomMatrix(5, 2, rng), randomMatrix(5, 2, rng), randomMatrix(5, 2, rng)};
  const std::vector<Eigen::MatrixXd> b = {randomMatrix(5, 3, rng), randomMatrix(5, 3, rng), randomMatrix(5, 3, rng)};
  // Dense reference built step by step from the blend (7.39) and Ψ_tᵀ = I_r ⊗ φ_tᵀ.
  const auto dense = [&](const std::vector<Eigen::MatrixXd>& m) {
    const int r = static_cast<int>(m.front().cols()), n = grid.kernels();
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(grid.steps() * 5, r * n);
    for (int t = 0; t < grid.steps(); ++t) {
      Eigen::MatrixXd omega = Eigen::MatrixXd::Zero(5, r);
      for (int s = 0; s < 3; ++s) omega += grid.activations()(t, s) * m[static_cast<std::size_t>(s)];
      Eigen::MatrixXd psi_t = Eigen::MatrixXd::Zero(r, r * n);
      for (int j = 0; j < r; ++j) psi_t.block(j, j * n, 1, n) = grid.basis().row(t);
      A.middleRows(t * 5, 5) = omega * psi_t;
    }
    return A;
  };
  const Eigen::MatrixXd Aa = dense(a), Ab = dense(b);
  EXPECT_LT((bl::coordinatedDesign(grid, a) - Aa).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((bl::coordinatedGram(grid, a, b) - Aa.transpose() * Ab).cwiseAbs().maxCoeff(), 1e-10);
  const Eigen::VectorXd w = randomMatrix(static_cast<int>(Aa.cols()), 1, rng);
  const Eigen::VectorXd stacked = Aa * w;
  const Eigen::MatrixXd values = bl::coordinatedValues(grid, a, w);
  for (int t = 0; t < grid.steps(); ++t) {
    EXPECT_LT((values.row(t).transpose() - stacked.segment(t * 5, 5)).cwiseAbs().maxCoeff(), 1e-12);
  }
  // Least squares on exact values returns the weights.
  EXPECT_LT((bl::fitLatentWeights(grid, a, values, 0.0) - w).cwiseAbs().maxCoeff(), 1e-6);
  // The activations are normalised (7.38).
  EXPECT_LT((grid.activations().rowwise().sum().array() - 1.0).abs().maxCoeff(), 1e-12);
}

TEST(CoordinationMatrix, PcaGivesTheLeadingSingularDirections) {
  std::mt19937 rng(2);
  const Eigen::MatrixXd samples =
      orthonormal(6, 6, rng) * Eigen::VectorXd::LinSpaced(6, 6.0, 1.0).asDiagonal() * randomMatrix(6, 200, rng);
  const bl::PcaCoordination pca = bl::pcaCoordination(samples, 3);
  const Eigen::MatrixXd centred = samples.colwise() - samples.rowwise().mean();
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(centred, Eigen::ComputeThinU);
  EXPECT_LT((pca.singular_values - svd.singularValues()).cwiseAbs().maxCoeff(), 1e-8 * svd.singularValues()[0]);
  for (int j = 0; j < 3; ++j) {
    EXPECT_NEAR(std::abs(pca.omega.col(j).dot(svd.matrixU().col(j))), 1.0, 1e-10) << j;
  }
  EXPECT_LT((pca.omega.transpose() * pca.omega - Eigen::MatrixXd::Identity(3, 3)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_THROW(bl::pcaCoordination(samples, 7), std::invalid_argument);
  EXPECT_THROW(bl::pcaCoordination(samples, 2, Eigen::VectorXd::Zero(200)), std::invalid_argument);
}

TEST(CoordinationMatrix, AlignmentUndoesPermutationsAndSignFlips) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::MatrixXd reference = orthonormal(7, 4, rng);
    std::vector<int> order = {0, 1, 2, 3};
    std::shuffle(order.begin(), order.end(), rng);
    Eigen::MatrixXd scrambled(7, 4);
    for (int j = 0; j < 4; ++j) scrambled.col(j) = (j % 2 == 0 ? -1.0 : 1.0) * reference.col(order[j]);
    scrambled += 0.05 * randomMatrix(7, 4, rng);
    std::vector<Eigen::MatrixXd> matrices = {reference, scrambled, -reference};
    bl::alignCoordinationMatrices(matrices);
    EXPECT_EQ(matrices[0], reference);
    EXPECT_LT((matrices[1] - reference).cwiseAbs().maxCoeff(), 0.2) << "trial " << trial;
    EXPECT_LT((matrices[2] - reference).cwiseAbs().maxCoeff(), 1e-15);
  }
  // Columns that all point towards the same reference column (no mutual best match for all of them): the completion
  // still assigns every column once, so the result is a signed permutation of the input.
  const Eigen::MatrixXd reference = Eigen::MatrixXd::Identity(3, 3);
  Eigen::MatrixXd crowded(3, 3);
  crowded << 0.9, 0.8, 0.7, 0.3, 0.5, 0.1, 0.3, 0.3, 0.7;
  std::vector<Eigen::MatrixXd> matrices = {reference, crowded};
  bl::alignCoordinationMatrices(matrices);
  const Eigen::MatrixXd P = crowded.fullPivLu().solve(matrices[1]);
  EXPECT_LT((P.cwiseAbs().colwise().sum().array() - 1.0).abs().maxCoeff(), 1e-12);
  EXPECT_LT((P.cwiseAbs().rowwise().sum().array() - 1.0).abs().maxCoeff(), 1e-12);
  EXPECT_GT(matrices[1](0, 0), 0.0);
}

TEST(CoordinationMatrix, ReprojectionIsThePrintedPseudoinverse) {
  std::mt19937 rng(4);
  const bl::CoordinationGrid grid = dmpGrid(5, 6, 2, 40);
  const std::vector<Eigen::MatrixXd> old_omega = {orthonormal(5, 3, rng), orthonormal(5, 3, rng)};
  const std::vector<Eigen::MatrixXd> new_omega = {orthonormal(5, 2, rng), orthonormal(5, 2, rng)};
  const bl::LatentReprojection reprojection(grid, old_omega, new_omega);
  const Eigen::MatrixXd M =
      Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(bl::coordinatedDesign(grid, old_omega)).pseudoInverse() *
      bl::coordinatedDesign(grid, new_omega);
  EXPECT_LT((reprojection.matrix() - M).cwiseAbs().maxCoeff(), 1e-8 * (1.0 + M.cwiseAbs().maxCoeff()));
  const Eigen::VectorXd mu = randomMatrix(18, 1, rng);
  const Eigen::MatrixXd B = randomMatrix(18, 18, rng);
  const Eigen::MatrixXd Sigma = B * B.transpose();
  const Eigen::MatrixXd M_pinv = Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(M).pseudoInverse();
  const Eigen::VectorXd mean = M_pinv * mu;  // (7.35)
  const Eigen::VectorXd residual = M * mean - mu;
  const Eigen::MatrixXd covariance = M_pinv * (Sigma + residual * residual.transpose()) * M_pinv.transpose();  // (7.36)
  EXPECT_LT((reprojection.mean(mu) - mean).cwiseAbs().maxCoeff(), 1e-8 * (1.0 + mean.cwiseAbs().maxCoeff()));
  EXPECT_LT((reprojection.covariance(mu, Sigma) - covariance).cwiseAbs().maxCoeff(),
            1e-8 * (1.0 + covariance.cwiseAbs().maxCoeff()));
}

TEST(CoordinationMatrix, ReprojectionKeepsTheForcingDistribution) {
  std::mt19937 rng(5);
  const bl::CoordinationGrid grid = dmpGrid(6, 8, 2, 50);
  const std::vector<Eigen::MatrixXd> omega = {orthonormal(6, 3, rng), orthonormal(6, 3, rng)};
  const Eigen::VectorXd mu = 10.0 * randomMatrix(24, 1, rng);
  const Eigen::MatrixXd B = randomMatrix(24, 24, rng);
  const Eigen::MatrixXd Sigma = B * B.transpose();
  const auto [f_mean, f_covariance] = valueDistribution(grid, omega, mu, Sigma);
  const double scale = f_covariance.cwiseAbs().maxCoeff();
  const Eigen::MatrixXd R = orthonormal(3, 3, rng);
  const std::vector<Eigen::MatrixXd> turned = {omega[0] * R, omega[1] * R};
  for (const bl::ReprojectionRule rule : {bl::ReprojectionRule::Printed, bl::ReprojectionRule::LeastSquares}) {
    const int which = static_cast<int>(rule);
    // The same Ω: the same μ_ω and Σ_ω.
    const bl::LatentReprojection same(grid, omega, omega, rule);
    EXPECT_LT((same.mean(mu) - mu).cwiseAbs().maxCoeff(), 1e-8 * mu.cwiseAbs().maxCoeff()) << which;
    EXPECT_LT((same.covariance(mu, Sigma) - Sigma).cwiseAbs().maxCoeff(), 1e-8 * Sigma.cwiseAbs().maxCoeff()) << which;
    // Ω turned within its span (another basis of the same latent space, as a new PCA may return): new μ_ω, Σ_ω, but
    // the same distribution of the forcing terms.
    const bl::LatentReprojection reprojection(grid, omega, turned, rule);
    const auto [g_mean, g_covariance] =
        valueDistribution(grid, turned, reprojection.mean(mu), reprojection.covariance(mu, Sigma));
    EXPECT_GT((reprojection.mean(mu) - mu).cwiseAbs().maxCoeff(), 1.0) << which;
    EXPECT_LT((g_mean - f_mean).cwiseAbs().maxCoeff(), 1e-8 * f_mean.cwiseAbs().maxCoeff()) << which;
    EXPECT_LT((g_covariance - f_covariance).cwiseAbs().maxCoeff(), 1e-8 * scale) << which;
  }
}

TEST(CoordinationMatrix, LeastSquaresReprojectionStaysBoundedWherePrintedAmplifies) {
  std::mt19937 rng(7);
  const bl::CoordinationGrid grid = dmpGrid(6, 8, 1, 50);
  const Eigen::MatrixXd basis = orthonormal(6, 6, rng);
  // The new coordination keeps two old directions and turns the third almost out of the old span.
  const std::vector<Eigen::MatrixXd> old_omega = {basis.leftCols(3)};
  Eigen::MatrixXd new_omega = basis.leftCols(3);
  new_omega.col(2) = (1e-3 * basis.col(2) + basis.col(4)).normalized();
  const Eigen::VectorXd mu = randomMatrix(24, 1, rng);
  const Eigen::MatrixXd B = randomMatrix(24, 24, rng);
  const Eigen::MatrixXd Sigma = B * B.transpose();
  const bl::LatentReprojection printed(grid, old_omega, {new_omega}, bl::ReprojectionRule::Printed);
  const bl::LatentReprojection least(grid, old_omega, {new_omega}, bl::ReprojectionRule::LeastSquares);
  EXPECT_GT(printed.mean(mu).norm(), 100.0 * mu.norm());
  EXPECT_LT(least.mean(mu).norm(), 1.01 * mu.norm());
  EXPECT_LT(least.covariance(mu, Sigma).norm(), 1.01 * Sigma.norm());
  // The least-squares mean gives the values closest to the old ones: its residual is orthogonal to the new span.
  const Eigen::MatrixXd A_old = bl::coordinatedDesign(grid, old_omega),
                        A_new = bl::coordinatedDesign(grid, {new_omega});
  EXPECT_LT((A_new.transpose() * (A_new * least.mean(mu) - A_old * mu)).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(CoordinationMatrix, CmuDropsADimensionExactlyWhenTheRatioExceedsEta) {
  std::mt19937 rng(6);
  constexpr int d = 4, steps = 60;
  const bl::CoordinationGrid grid = dmpGrid(d, 6, 1, steps);
  // An excitation with singular values 10, 5, 2, 0.5 after centring: time profiles orthonormal and of zero mean.
  Eigen::MatrixXd profiles = randomMatrix(steps, d, rng);
  profiles.rowwise() -= profiles.colwise().mean();
  profiles = Eigen::HouseholderQR<Eigen::MatrixXd>(profiles).householderQ() * Eigen::MatrixXd::Identity(steps, d);
  profiles.rowwise() -= profiles.colwise().mean();  // still orthonormal: the columns already had zero mean
  const Eigen::MatrixXd U = orthonormal(d, d, rng);
  const Eigen::Vector4d sigma(10.0, 5.0, 2.0, 0.5);
  const Eigen::MatrixXd values = (U * sigma.asDiagonal() * profiles.transpose()).transpose().rowwise() +
                                 Eigen::RowVectorXd::LinSpaced(d, 1.0, 3.0);  // plus a constant, removed by (7.26)
  const std::vector<Eigen::MatrixXd> rollouts = {values, values};
  const Eigen::Vector2d weights(0.3, 0.7);
  const std::vector<Eigen::MatrixXd> omega = {orthonormal(d, 3, rng)};
  const Eigen::VectorXd mean = randomMatrix(18, 1, rng);
  const Eigen::MatrixXd covariance = Eigen::MatrixXd::Identity(18, 18);
  bl::CoordinationUpdateParameters parameters;
  for (const auto& [eta, reduced] : {std::pair{4.99, true}, std::pair{5.01, false}}) {  // σ_1/σ_3 = 5
    parameters.eta = eta;
    const bl::CoordinationUpdateResult result =
        bl::coordinationMatrixUpdate(grid, parameters, omega, {}, rollouts, weights, mean, covariance);
    EXPECT_LT((result.singular_values - sigma).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_EQ(result.reduced, reduced) << "eta " << eta;
    EXPECT_EQ(result.matrices.front().cols(), reduced ? 2 : 3);
    EXPECT_EQ(result.mean.size(), reduced ? 12 : 18);
    // The new Ω spans the leading left singular vectors.
    const Eigen::MatrixXd& omega_new = result.matrices.front();
    for (int j = 0; j < omega_new.cols(); ++j) EXPECT_NEAR(std::abs(omega_new.col(j).dot(U.col(j))), 1.0, 1e-9);
  }
  parameters.eta = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(bl::coordinationMatrixUpdate(grid, parameters, omega, {}, rollouts, weights, mean, covariance).reduced);
  // Filtering (line 2): with α = 0.25 the excitation is ¼ new + ¾ previous.
  parameters.filter = 0.25;
  const std::vector<Eigen::MatrixXd> previous = {Eigen::MatrixXd::Ones(d, steps)};
  const bl::CoordinationUpdateResult filtered =
      bl::coordinationMatrixUpdate(grid, parameters, omega, previous, rollouts, weights, mean, covariance);
  EXPECT_LT((filtered.excitation.front() - (0.25 * values.transpose() + 0.75 * previous.front())).cwiseAbs().maxCoeff(),
            1e-12);
  EXPECT_THROW(
      bl::coordinationMatrixUpdate(grid, parameters, omega, {}, rollouts, Eigen::Vector2d(-1.0, 2.0), mean, covariance),
      std::invalid_argument);
}

TEST(DrDmp, OneMatrixIsTheDmpWithWeightsOmegaW) {
  std::mt19937 rng(7);
  constexpr int d = 5, r = 2, n = 12;
  bp::DrDmpParameters parameters;
  parameters.dmp.kernels = n;
  const Eigen::MatrixXd omega = orthonormal(d, r, rng);
  const Eigen::MatrixXd W = 50.0 * randomMatrix(r, n, rng);
  Eigen::VectorXd w(r * n);
  for (int j = 0; j < r; ++j) w.segment(j * n, n) = W.row(j).transpose();
  const Eigen::VectorXd start = randomMatrix(d, 1, rng), goal = randomMatrix(d, 1, rng);
  const bp::DrDmp dr(parameters, {omega}, w, start, goal, 1.5);
  const bp::Dmp dmp(parameters.dmp, omega * W, start, goal, 1.5);
  bp::DrDmpState state = dr.initialState();
  bp::DmpState reference = dmp.initialState();
  for (int k = 0; k < 150; ++k) {
    ASSERT_EQ(dr.step(state, 0.01), bp::DmpStatus::Success);
    ASSERT_EQ(dmp.step(reference, 0.01), bp::DmpStatus::Success);
  }
  EXPECT_LT((state.dmp.y - reference.y).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_LT((state.dmp.yd - reference.yd).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_LT((state.dmp.y - goal).cwiseAbs().maxCoeff(), 0.05);
  // Exploration is added to the forcing term.
  state = dr.initialState();
  bp::DrDmpState explored = dr.initialState();
  explored.exploration = Eigen::VectorXd::Constant(d, 3.0);
  ASSERT_EQ(dr.step(state, 0.01), bp::DmpStatus::Success);
  ASSERT_EQ(dr.step(explored, 0.01), bp::DmpStatus::Success);
  EXPECT_LT((explored.forcing - state.forcing - explored.exploration).cwiseAbs().maxCoeff(), 1e-12);
  explored.exploration[0] = NAN;
  EXPECT_EQ(dr.step(explored, 0.01), bp::DmpStatus::InvalidInput);
}

TEST(DrDmp, SeveralMatricesAreBlendedByTheirActivations) {
  std::mt19937 rng(8);
  constexpr int d = 4, r = 2, n = 8;
  bp::DrDmpParameters parameters;
  parameters.dmp.kernels = n;
  parameters.matrices = 3;
  const std::vector<Eigen::MatrixXd> omega = {orthonormal(d, r, rng), orthonormal(d, r, rng), orthonormal(d, r, rng)};
  const Eigen::VectorXd w = 20.0 * randomMatrix(r * n, 1, rng);
  const bp::DrDmp dr(parameters, omega, w, Eigen::VectorXd::Zero(d), Eigen::VectorXd::Ones(d), 1.0);
  const bl::CoordinationGrid grid = dr.grid(0.01, 100);
  const Eigen::MatrixXd values = bl::coordinatedValues(grid, omega, w);
  bp::DrDmpState state = dr.initialState();
  for (int k = 0; k < 100; ++k) {
    // Reference: Ω^t = Σ_s φ_s(t) Ω_s with φ_s normalised Gaussians at 0, ½, 1 (variance ⅛) of t/τ.
    const double s = k * 0.01;
    Eigen::Vector3d phi;
    for (int i = 0; i < 3; ++i) phi[i] = std::exp(-0.5 * (s - 0.5 * i) * (s - 0.5 * i) / 0.125);
    phi /= phi.sum();
    Eigen::MatrixXd blended = Eigen::MatrixXd::Zero(d, r);
    for (int i = 0; i < 3; ++i) blended += phi[i] * omega[static_cast<std::size_t>(i)];
    Eigen::VectorXd g(n);
    const bp::Dmp shape(parameters.dmp, Eigen::MatrixXd::Zero(d, n), Eigen::VectorXd::Zero(d), Eigen::VectorXd::Ones(d),
                        1.0);
    shape.basis(state.dmp.x, g);
    Eigen::MatrixXd W(r, n);
    for (int j = 0; j < r; ++j) W.row(j) = w.segment(j * n, n).transpose();
    ASSERT_EQ(dr.step(state, 0.01), bp::DmpStatus::Success);
    EXPECT_LT((state.forcing - blended * W * g).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + state.forcing.norm()));
    EXPECT_LT((state.forcing - values.row(k).transpose()).cwiseAbs().maxCoeff(), 1e-6 * (1.0 + state.forcing.norm()))
        << "step " << k;
  }
}

TEST(DrDmp, FitWithFullDimensionReproducesTheDmp) {
  constexpr int d = 4;
  Eigen::MatrixXd demonstration(201, d);
  for (int i = 0; i < 201; ++i) {
    const double s = i / 200.0;
    for (int j = 0; j < d; ++j)
      demonstration(i, j) = (j + 1) * 0.3 * (10 * std::pow(s, 3) - 15 * std::pow(s, 4) + 6 * std::pow(s, 5)) +
                            0.2 * std::sin(M_PI * s * (j + 1)) * s;
  }
  bp::DrDmpParameters parameters;
  parameters.dmp.kernels = 25;
  for (const int matrices : {1, 2}) {
    parameters.matrices = matrices;
    const bp::DrDmpFit fit = bp::DrDmp::fit(parameters, {demonstration}, 0.01, d);
    // Reference: the DMP fitted to the same demonstration (the same forcing targets and basis, all samples).
    const bp::Dmp dmp = bp::Dmp::fit(parameters.dmp, demonstration, 0.01);
    bp::DrDmpState state = fit.dmp.initialState();
    bp::DmpState reference = dmp.initialState();
    double worst = 0.0, worst_reference = 0.0, apart = 0.0;
    for (int k = 1; k <= 200; ++k) {
      ASSERT_EQ(fit.dmp.step(state, 0.01), bp::DmpStatus::Success);
      ASSERT_EQ(dmp.step(reference, 0.01), bp::DmpStatus::Success);
      worst = std::max(worst, (state.dmp.y - demonstration.row(k).transpose()).cwiseAbs().maxCoeff());
      worst_reference =
          std::max(worst_reference, (reference.y - demonstration.row(k).transpose()).cwiseAbs().maxCoeff());
      apart = std::max(apart, (state.dmp.y - reference.y).cwiseAbs().maxCoeff());
    }
    EXPECT_LT(worst, 0.01) << matrices << " matrices";
    EXPECT_LT(worst, 1.05 * worst_reference + 1e-4) << matrices << " matrices";
    EXPECT_LT(apart, 1e-3) << matrices << " matrices";
    EXPECT_EQ(fit.latent_weights.rows(), 1);
    EXPECT_EQ(static_cast<int>(fit.excitation.size()), matrices);
  }
  EXPECT_THROW(bp::DrDmp::fit(parameters, {demonstration}, 0.01, d + 1), std::invalid_argument);
  bp::DrDmpParameters scaled = parameters;
  scaled.dmp.goal_scaled_forcing = true;
  EXPECT_THROW(bp::DrDmp::fit(scaled, {demonstration}, 0.01, 2), std::invalid_argument);
}

// The goal weights w_g of DrDmpParameters::goal_offsets are a goal moved through a first-order filter: with one
// matrix, the DR-DMP whose latent DoF each end in w_g follows, to rounding, the DR-DMP without them whose goal is
// g + (1 − x) Ω w_g / (α_z β_z) at every step; the grid's last basis column is 1 − x; fit() leaves the goal weights 0
// and the kernels' weights as without them.
TEST(DrDmp, GoalWeightsMoveTheGoalThroughTheCoordination) {
  std::mt19937 rng(12);
  constexpr int d = 5, r = 3, n = 10;
  bp::DrDmpParameters plain;
  plain.dmp.kernels = n;
  bp::DrDmpParameters with_goals = plain;
  with_goals.goal_offsets = true;
  EXPECT_EQ(with_goals.basisSize(), n + 1);
  const Eigen::MatrixXd omega = orthonormal(d, r, rng);
  const Eigen::VectorXd kernels = 30.0 * randomMatrix(r * n, 1, rng), goal_weights = 40.0 * randomMatrix(r, 1, rng);
  Eigen::VectorXd w(r * (n + 1));
  for (int j = 0; j < r; ++j) {
    w.segment(j * (n + 1), n) = kernels.segment(j * n, n);
    w[j * (n + 1) + n] = goal_weights[j];
  }
  const Eigen::VectorXd start = randomMatrix(d, 1, rng), goal = randomMatrix(d, 1, rng);
  const bp::DrDmp moved(with_goals, {omega}, w, start, goal, 1.5);
  const Eigen::VectorXd offset = omega * goal_weights / (plain.dmp.alpha_z * plain.dmp.beta_z);
  const double x07 = std::exp(-plain.dmp.alpha_x * 0.7 / 1.5);
  EXPECT_LT((moved.goalOffset(0.7) - (1.0 - x07) * offset).cwiseAbs().maxCoeff(), 1e-12);
  const bp::DrDmp reference(plain, {omega}, kernels, start, goal, 1.5);
  bp::DrDmpState state = moved.initialState(), expected = reference.initialState();
  for (int k = 0; k < 300; ++k) {
    expected.dmp.goal = goal + (1.0 - expected.dmp.x) * offset;
    ASSERT_EQ(moved.step(state, 0.01), bp::DmpStatus::Success);
    ASSERT_EQ(reference.step(expected, 0.01), bp::DmpStatus::Success);
  }
  EXPECT_LT((state.dmp.y - expected.dmp.y).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((state.dmp.y - goal - offset).cwiseAbs().maxCoeff(), 0.02);  // it went to the moved goal
  EXPECT_GT(offset.norm(), 0.1);

  const bl::CoordinationGrid grid = moved.grid(0.01, 50);
  ASSERT_EQ(grid.kernels(), n + 1);
  for (int k = 0; k < 50; ++k) {
    EXPECT_NEAR(grid.basis()(k, n), 1.0 - std::exp(-plain.dmp.alpha_x * 0.01 * k / 1.5), 1e-15);
  }
  EXPECT_EQ(grid.basis().leftCols(n), reference.grid(0.01, 50).basis());
  EXPECT_EQ(bp::DrDmp(plain, {omega}, kernels, start, goal, 1.5).goalOffset(0.3), Eigen::VectorXd::Zero(d));
  EXPECT_THROW(bp::DrDmp(with_goals, {omega}, kernels, start, goal, 1.5), std::invalid_argument);

  Eigen::MatrixXd demonstration(151, d);
  for (int i = 0; i < 151; ++i) {
    const double s = i / 150.0;
    for (int j = 0; j < d; ++j) demonstration(i, j) = (j + 1) * 0.2 * s * s * (3.0 - 2.0 * s) + 0.1 * std::sin(4.0 * s);
  }
  const bp::DrDmpFit fit_plain = bp::DrDmp::fit(plain, {demonstration}, 0.01, r);
  const bp::DrDmpFit fit_goals = bp::DrDmp::fit(with_goals, {demonstration}, 0.01, r);
  const Eigen::VectorXd fitted = fit_goals.dmp.weights();
  ASSERT_EQ(fitted.size(), r * (n + 1));
  for (int j = 0; j < r; ++j) {
    EXPECT_EQ(fitted[j * (n + 1) + n], 0.0);
    EXPECT_EQ(fitted.segment(j * (n + 1), n), fit_plain.dmp.weights().segment(j * n, n));
  }
}

TEST(CoordinatedReps, FixedCoordinationIsReps) {
  std::mt19937 rng(9);
  const bl::CoordinationGrid grid = dmpGrid(3, 4, 1, 20);
  bl::CoordinatedRepsParameters parameters;
  parameters.reps.reuse = 10;
  const bl::CoordinatedPolicy initial{
      {orthonormal(3, 2, rng)}, Eigen::VectorXd::Zero(8), Eigen::MatrixXd::Identity(8, 8), {}};
  bl::CoordinatedReps learner(parameters, grid, initial);
  bl::Reps reps(parameters.reps);
  for (int u = 0; u < 4; ++u) {
    const Eigen::MatrixXd samples = randomMatrix(15, 8, rng);
    const Eigen::VectorXd rewards = -samples.rowwise().squaredNorm();
    const std::vector<Eigen::MatrixXd> values(15, Eigen::MatrixXd::Zero(20, 3));
    learner.update(samples, values, rewards);
    const bl::RepsUpdate expected = reps.update(samples, rewards);
    EXPECT_EQ(learner.policy().mean, expected.mean);
    EXPECT_EQ(learner.policy().covariance, expected.covariance);
  }
}

TEST(CoordinatedReps, CovarianceMemoryBlendsTheSampledCovarianceIn) {
  // Fewer rollouts (6) than latent weights (8): REPS' covariance has rank 5 plus the ridge; with the memory λ the new
  // covariance is (1 − λ) times it plus λ times the one sampled from, and keeps every direction.
  std::mt19937 rng(11);
  const bl::CoordinationGrid grid = dmpGrid(3, 4, 1, 20);
  const Eigen::MatrixXd sampled = 2.0 * Eigen::MatrixXd::Identity(8, 8);
  const bl::CoordinatedPolicy initial{{orthonormal(3, 2, rng)}, Eigen::VectorXd::Zero(8), sampled, {}};
  bl::CoordinatedRepsParameters plain;
  bl::CoordinatedRepsParameters remembering = plain;
  remembering.covariance_memory = 0.9;
  bl::CoordinatedReps without(plain, grid, initial), with(remembering, grid, initial);
  const Eigen::MatrixXd samples = randomMatrix(6, 8, rng);
  const Eigen::VectorXd rewards = -samples.rowwise().squaredNorm();
  const std::vector<Eigen::MatrixXd> values(6, Eigen::MatrixXd::Zero(20, 3));
  without.update(samples, values, rewards);
  with.update(samples, values, rewards);
  EXPECT_EQ(with.policy().mean, without.policy().mean);
  EXPECT_LT((with.policy().covariance - (0.1 * without.policy().covariance + 0.9 * sampled)).cwiseAbs().maxCoeff(),
            1e-12);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> lost(without.policy().covariance),
      kept(with.policy().covariance);
  EXPECT_LT(lost.eigenvalues().minCoeff(), 1e-6);
  EXPECT_GE(kept.eigenvalues().minCoeff(), 0.9 * 2.0 - 1e-12);
  remembering.covariance_memory = 1.0;
  EXPECT_THROW(bl::CoordinatedReps(remembering, grid, initial), std::invalid_argument);
}

TEST(CoordinatedReps, AdaptedCovarianceIsCmaDrivenByRepsWeights) {
  // Fixed: REPS' mean, and Σ_ω the σ² C of a CovarianceAdaptation fed REPS' weights and mean (plus the ridge).
  std::mt19937 rng(12);
  const bl::CoordinationGrid grid = dmpGrid(3, 4, 1, 20);
  bl::CoordinatedRepsParameters parameters;
  parameters.covariance_rule = bl::CovarianceRule::Adapted;
  const bl::CoordinatedPolicy initial{
      {orthonormal(3, 2, rng)}, Eigen::VectorXd::Zero(8), Eigen::MatrixXd::Identity(8, 8), {}};
  bl::CoordinatedReps learner(parameters, grid, initial);
  bl::Reps reps(parameters.reps);
  bl::CovarianceAdaptation reference = bl::CovarianceAdaptation::start(initial.covariance);
  Eigen::VectorXd mean = initial.mean;
  for (int u = 0; u < 4; ++u) {
    const Eigen::MatrixXd samples = randomMatrix(15, 8, rng);
    const Eigen::VectorXd rewards = -samples.rowwise().squaredNorm();
    learner.update(samples, std::vector<Eigen::MatrixXd>(15, Eigen::MatrixXd::Zero(20, 3)), rewards);
    const bl::RepsUpdate expected = reps.update(samples, rewards);
    reference.update(mean, expected.mean, samples, expected.weights);
    mean = expected.mean;
    EXPECT_EQ(learner.policy().mean, expected.mean);
    Eigen::MatrixXd covariance = reference.covariance();
    covariance.diagonal().array() += parameters.reps.covariance_regularisation;
    EXPECT_LT((learner.policy().covariance - covariance).cwiseAbs().maxCoeff(), 1e-12);
  }
  bl::CoordinatedRepsParameters bad = parameters;
  bad.covariance_memory = 0.5;
  EXPECT_THROW(bl::CoordinatedReps(bad, grid, initial), std::invalid_argument);
  bad = parameters;
  bad.rule = bl::CoordinationRule::Em;
  EXPECT_THROW(
      bl::CoordinatedReps(bad, grid,
                          {initial.coordination, initial.mean, initial.covariance, Eigen::MatrixXd::Identity(3, 3)}),
      std::invalid_argument);
}

TEST(CoordinatedReps, AdaptedCovarianceFollowsTheCoordinationWhenItDropsADimension) {
  // Cmu with η = 1.0001 drops a dimension at every update: the adapted state moves into the r − 1 coordinates and the
  // next updates sample from it.
  std::mt19937 rng(13);
  constexpr int d = 4, n = 5, steps = 30;
  const bl::CoordinationGrid grid = dmpGrid(d, n, 1, steps);
  bl::CoordinatedRepsParameters parameters;
  parameters.rule = bl::CoordinationRule::Cmu;
  parameters.update.eta = 1.0001;
  parameters.covariance_rule = bl::CovarianceRule::Adapted;
  parameters.reps.reuse = 10;
  bl::CoordinatedReps learner(
      parameters, grid,
      {{orthonormal(d, 3, rng)}, Eigen::VectorXd::Zero(3 * n), Eigen::MatrixXd::Identity(3 * n, 3 * n), {}});
  bl::GaussianSampler sampler;
  for (int u = 0; u < 3; ++u) {
    const bl::CoordinatedPolicy& policy = learner.policy();
    const Eigen::MatrixXd samples = sampler.draw(policy.mean, bl::choleskyFactor(policy.covariance), 10, rng);
    std::vector<Eigen::MatrixXd> values;
    Eigen::VectorXd rewards(10);
    for (int k = 0; k < 10; ++k) {
      values.push_back(bl::coordinatedValues(grid, policy.coordination, samples.row(k).transpose()));
      rewards[k] = -values.back().squaredNorm();
    }
    const bl::CoordinatedRepsReport report = learner.update(samples, values, rewards);
    EXPECT_EQ(learner.policy().latentDims(), 2 - u) << "update " << u;
    EXPECT_TRUE(report.reduced);
    EXPECT_EQ(learner.policy().covariance.rows(), learner.policy().mean.size());
    EXPECT_TRUE(learner.policy().covariance.allFinite());
    if (learner.policy().latentDims() == 1) break;
  }
}

TEST(CoordinatedReps, CmuCarriesKeptRolloutsIntoTheNewCoordinates) {
  // Rollouts whose forcing lies in a 2-D subspace; the learner starts in another one with r = 3 and η = ∞: after an
  // update Ω spans the rollouts' subspace (plus one direction), and kept samples are mapped by M†.
  std::mt19937 rng(10);
  constexpr int d = 5, n = 6, steps = 40;
  const bl::CoordinationGrid grid = dmpGrid(d, n, 1, steps);
  const Eigen::MatrixXd target = orthonormal(d, 2, rng);
  bl::CoordinatedRepsParameters parameters;
  parameters.rule = bl::CoordinationRule::Cmu;
  parameters.reps.reuse = 20;
  bl::CoordinatedReps learner(
      parameters, grid,
      {{orthonormal(d, 3, rng)}, Eigen::VectorXd::Zero(3 * n), Eigen::MatrixXd::Identity(3 * n, 3 * n), {}});
  Eigen::MatrixXd samples = randomMatrix(20, 3 * n, rng);
  std::vector<Eigen::MatrixXd> values;
  for (int k = 0; k < 20; ++k) values.push_back(bl::coordinatedValues(grid, {target}, randomMatrix(2 * n, 1, rng)));
  learner.update(samples, values, Eigen::VectorXd::LinSpaced(20, -1.0, 0.0));
  const Eigen::MatrixXd& omega = learner.policy().coordination.front();
  ASSERT_EQ(omega.cols(), 3);
  // The first two columns span the rollouts' subspace.
  const Eigen::MatrixXd projected = target * target.transpose() * omega.leftCols(2);
  EXPECT_LT((projected - omega.leftCols(2)).cwiseAbs().maxCoeff(), 1e-8);
  // A second update with the new coordinates works with the kept, mapped samples.
  EXPECT_NO_THROW(learner.update(randomMatrix(20, 3 * n, rng), values, Eigen::VectorXd::LinSpaced(20, -1.0, 0.0)));
  EXPECT_THROW(learner.update(randomMatrix(20, 2 * n, rng), values, Eigen::VectorXd::Zero(20)), std::invalid_argument);
}
