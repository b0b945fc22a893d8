// DR-ProMP (thesis Sec. 7.1): the E-step with the Kronecker structure equals the printed one; the weighted EM never
// decreases the weighted log-likelihood (computed from the dense Γ) and recovers the subspace that generated the
// data; the contextual initialisation is (7.20); with r = d the DR-ProMP reproduces the full ProMP; the latent
// controller (7.6–7.12) reproduces the DR-ProMP's distribution on a double integrator; bad input throws.
#include "bimanual_skills/learning/gaussian.hpp"
#include "bimanual_skills/learning/latent_trajectory_em.hpp"
#include "bimanual_skills/primitives/dr_promp.hpp"
#include "bimanual_skills/primitives/dr_promp_controller.hpp"
#include "testing/random_matrices.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

namespace bl = bimanual_skills::learning;
namespace bp = bimanual_skills::primitives;

using bimanual_skills::testing::randomMatrix;
const auto& orthonormal = bimanual_skills::testing::randomOrthonormal;

namespace {

bl::CoordinationGrid promPGrid(int kernels, int steps) {
  bp::ProMpParameters parameters;
  parameters.kernels = kernels;
  return bp::DrProMp::grid(parameters, steps);
}

/// A random model (orthonormal Ω, Σ_ω, Σ_y of full rank; K_ω with `contexts` columns) and `count` trajectories drawn
/// from it, with weights in [0.2, 1.8] and contexts N(0, I).
struct Problem {
  bl::LatentTrajectoryModel model;
  bl::WeightedTrajectories data;
};

Problem randomProblem(const bl::CoordinationGrid& grid, int d, int r, int contexts, int count, double noise,
                      std::uint32_t seed) {
  std::mt19937 rng(seed);
  const int n = grid.kernels();
  Problem p;
  p.model.coordination = orthonormal(d, r, rng);
  p.model.mean = randomMatrix(r * n, 1, rng);
  const Eigen::MatrixXd B = randomMatrix(r * n, r * n, rng) / std::sqrt(r * n);
  p.model.covariance = B * B.transpose() + 0.05 * Eigen::MatrixXd::Identity(r * n, r * n);
  p.model.noise = noise * Eigen::MatrixXd::Identity(d, d);
  p.model.context_gain = contexts > 0 ? randomMatrix(r * n, contexts, rng) : Eigen::MatrixXd(r * n, 0);
  p.data.contexts = randomMatrix(count, contexts, rng);
  p.data.weights = Eigen::VectorXd::LinSpaced(count, 0.2, 1.8);
  const Eigen::MatrixXd L = bl::choleskyFactor(p.model.covariance);
  bl::GaussianSampler sampler;
  for (int k = 0; k < count; ++k) {
    Eigen::VectorXd mean = p.model.mean;
    if (contexts > 0) mean += p.model.context_gain * p.data.contexts.row(k).transpose();
    Eigen::MatrixXd y = bl::coordinatedValues(grid, {p.model.coordination}, sampler.draw(mean, L, rng));
    y += std::sqrt(noise) * randomMatrix(grid.steps(), d, rng);
    p.data.trajectories.push_back(y);
  }
  return p;
}

/// Largest principal angle between the column spaces of a and b [rad].
double largestPrincipalAngle(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  const Eigen::MatrixXd qa =
      Eigen::HouseholderQR<Eigen::MatrixXd>(a).householderQ() * Eigen::MatrixXd::Identity(a.rows(), a.cols());
  const Eigen::MatrixXd qb =
      Eigen::HouseholderQR<Eigen::MatrixXd>(b).householderQ() * Eigen::MatrixXd::Identity(b.rows(), b.cols());
  const Eigen::VectorXd cosines = Eigen::JacobiSVD<Eigen::MatrixXd>(qa.transpose() * qb).singularValues();
  return std::acos(std::min(1.0, cosines.minCoeff()));
}

}  // namespace

TEST(LatentEm, FastEStepEqualsTheNaiveOne) {
  const bl::CoordinationGrid grid = promPGrid(6, 30);
  for (const int contexts : {0, 2}) {
    // A model away from the data (the EM's first iteration), so the posteriors differ from the data's weights.
    Problem p = randomProblem(grid, 5, 2, contexts, 6, 0.05, 11);
    p.model.covariance *= 3.0;
    p.model.noise(0, 1) = p.model.noise(1, 0) = 0.01;
    const bl::LatentPosterior fast = bl::latentEStep(grid, p.model, p.data);
    const bl::LatentPosterior naive = bl::latentEStepNaive(grid, p.model, p.data);
    EXPECT_LT((fast.means - naive.means).cwiseAbs().maxCoeff(), 1e-8 * (1.0 + naive.means.cwiseAbs().maxCoeff()));
    EXPECT_LT((fast.covariance - naive.covariance).cwiseAbs().maxCoeff(), 1e-10);
    const double fast_ll = bl::latentLogLikelihood(grid, p.model, p.data);
    const double naive_ll = bl::latentLogLikelihoodNaive(grid, p.model, p.data);
    EXPECT_NEAR(fast_ll, naive_ll, 1e-9 * std::abs(naive_ll));
  }
}

TEST(LatentEm, NeverDecreasesTheWeightedLogLikelihood) {
  const bl::CoordinationGrid grid = promPGrid(5, 25);
  for (const int contexts : {0, 1}) {
    const Problem p = randomProblem(grid, 4, 2, contexts, 12, 0.02, 21);
    bl::LatentTrajectoryModel model = bl::latentPcaModel(grid, p.data, 2, bl::LatentPcaParameters());
    if (contexts == 0) model.context_gain = Eigen::MatrixXd(model.mean.size(), 0);
    bl::LatentEmParameters parameters;
    double previous = bl::latentLogLikelihoodNaive(grid, model, p.data);
    const double first = previous;
    for (int i = 0; i < 30; ++i) {
      model = bl::latentMStep(grid, model, p.data, bl::latentEStep(grid, model, p.data), parameters);
      const double current = bl::latentLogLikelihoodNaive(grid, model, p.data);
      EXPECT_GE(current, previous - 1e-9 * std::abs(previous)) << "iteration " << i << ", contexts " << contexts;
      previous = current;
    }
    EXPECT_GT(previous, first + 1.0) << "the EM did not improve on the PCA initialisation";
  }
}

TEST(LatentEm, MStepIsEquations716To719FromDenseProducts) {
  // Independent reference: the M-step written with the dense Ψ_tᵀ = I_r ⊗ φ_tᵀ, step by step, from the printed
  // E-step's posteriors (no contexts, no floors).
  const bl::CoordinationGrid grid = promPGrid(5, 25);
  const Problem p = randomProblem(grid, 4, 2, 0, 12, 0.02, 23);
  bl::LatentTrajectoryModel model = bl::latentPcaModel(grid, p.data, 2, bl::LatentPcaParameters());
  model.context_gain = Eigen::MatrixXd(model.mean.size(), 0);
  const bl::LatentPosterior post = bl::latentEStepNaive(grid, model, p.data);
  const bl::LatentTrajectoryModel out = bl::latentMStep(grid, model, p.data, post, bl::LatentEmParameters());
  const int n = grid.kernels(), r = 2, d = 4, steps = grid.steps();
  const Eigen::VectorXd w = p.data.weights / p.data.weights.sum();
  const auto psiT = [&](int t) {  // r × r n
    Eigen::MatrixXd m = Eigen::MatrixXd::Zero(r, r * n);
    for (int j = 0; j < r; ++j) m.block(j, j * n, 1, n) = grid.basis().row(t);
    return m;
  };
  Eigen::VectorXd mu = post.means * w;
  Eigen::MatrixXd sigma = post.covariance, S = post.covariance, num = Eigen::MatrixXd::Zero(d, r),
                  den = Eigen::MatrixXd::Zero(r, r);
  for (int k = 0; k < post.means.cols(); ++k) {
    sigma += w[k] * (post.means.col(k) - mu) * (post.means.col(k) - mu).transpose();  // (7.16)
    S += w[k] * post.means.col(k) * post.means.col(k).transpose();
    for (int t = 0; t < steps; ++t) {
      num += w[k] * p.data.trajectories[static_cast<std::size_t>(k)].row(t).transpose() *
             (psiT(t) * post.means.col(k)).transpose();
    }
  }
  for (int t = 0; t < steps; ++t) den += psiT(t) * S * psiT(t).transpose();
  const Eigen::MatrixXd omega = num * den.inverse();  // (7.17)
  Eigen::MatrixXd noise = Eigen::MatrixXd::Zero(d, d);
  for (int k = 0; k < post.means.cols(); ++k) {
    for (int t = 0; t < steps; ++t) {
      const Eigen::VectorXd e =
          p.data.trajectories[static_cast<std::size_t>(k)].row(t).transpose() - omega * psiT(t) * post.means.col(k);
      noise += w[k] *
               (omega * psiT(t) * post.covariance * psiT(t).transpose() * omega.transpose() + e * e.transpose()) /
               steps;  // (7.19)
    }
  }
  EXPECT_LT((out.mean - mu).cwiseAbs().maxCoeff(), 1e-10 * (1.0 + mu.cwiseAbs().maxCoeff()));
  EXPECT_LT((out.covariance - sigma).cwiseAbs().maxCoeff(), 1e-10 * sigma.cwiseAbs().maxCoeff());
  EXPECT_LT((out.coordination - omega).cwiseAbs().maxCoeff(), 1e-8 * omega.cwiseAbs().maxCoeff());
  EXPECT_LT((out.noise - noise).cwiseAbs().maxCoeff(), 1e-8 * noise.cwiseAbs().maxCoeff());
}

TEST(LatentEm, RecoversTheGeneratingSubspaceAndNoise) {
  const bl::CoordinationGrid grid = promPGrid(6, 40);
  const Problem p = randomProblem(grid, 6, 2, 0, 60, 1e-3, 31);
  // Start from a random, wrong coordination: the EM has to find the subspace itself.
  std::mt19937 rng(32);
  bl::LatentTrajectoryModel initial = bl::latentPcaModel(grid, p.data, 2, bl::LatentPcaParameters());
  initial.coordination = orthonormal(6, 2, rng);
  initial.noise = 0.1 * Eigen::MatrixXd::Identity(6, 6);
  bl::LatentEmParameters parameters;
  parameters.max_iterations = 200;
  const bl::LatentEmResult result = bl::latentEm(grid, p.data, initial, parameters);
  EXPECT_LT(largestPrincipalAngle(result.model.coordination, p.model.coordination), 0.01);
  EXPECT_GT(largestPrincipalAngle(initial.coordination, p.model.coordination), 0.3)
      << "the start should be far from the answer";
  EXPECT_NEAR(result.model.noise.trace() / 6.0, 1e-3, 1e-4);
}

TEST(LatentEm, ContextualInitialisationIsEquation720) {
  const bl::CoordinationGrid grid = promPGrid(5, 20);
  const Problem p = randomProblem(grid, 4, 2, 2, 9, 0.01, 41);
  bl::LatentPcaParameters parameters;
  parameters.ridge = 1e-3;
  const bl::LatentTrajectoryModel model = bl::latentPcaModel(grid, p.data, 2, parameters);
  // (7.20) written out: [μ, K]ᵀ = (S diag(d) Sᵀ + λ I)⁻¹ S diag(d) W_dᵀ, S = [1 … 1; s_1 … s_N], W_d the fitted
  // latent weights (checked independently: least squares of each trajectory on the model's own Ω).
  const int count = static_cast<int>(p.data.trajectories.size());
  Eigen::MatrixXd S(3, count), W(model.mean.size(), count);
  const Eigen::MatrixXd design = bl::coordinatedDesign(grid, {model.coordination});
  for (int k = 0; k < count; ++k) {
    S.col(k) << 1.0, p.data.contexts.row(k).transpose();
    const Eigen::MatrixXd y = p.data.trajectories[static_cast<std::size_t>(k)].transpose();
    const Eigen::Map<const Eigen::VectorXd> stacked(y.data(), y.size());
    W.col(k) =
        (design.transpose() * design + parameters.ridge * Eigen::MatrixXd::Identity(W.rows(), W.rows())).inverse() *
        design.transpose() * stacked;
  }
  const Eigen::VectorXd d = p.data.weights / p.data.weights.sum();
  const Eigen::MatrixXd coefficients =
      (S * d.asDiagonal() * S.transpose() + parameters.ridge * Eigen::MatrixXd::Identity(3, 3)).inverse() * S *
      d.asDiagonal() * W.transpose();
  EXPECT_LT((model.mean - coefficients.row(0).transpose()).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_LT((model.context_gain - coefficients.bottomRows(2).transpose()).cwiseAbs().maxCoeff(), 1e-8);
}

TEST(LatentEm, RejectsInconsistentInput) {
  const bl::CoordinationGrid grid = promPGrid(5, 20);
  Problem p = randomProblem(grid, 4, 2, 0, 5, 0.01, 51);
  Problem bad = p;
  bad.data.trajectories[1].conservativeResize(19, 4);
  EXPECT_THROW(bl::latentEStep(grid, bad.model, bad.data), std::invalid_argument);
  bad = p;
  bad.data.weights.setZero();
  EXPECT_THROW(bl::latentEStep(grid, bad.model, bad.data), std::invalid_argument);
  bad = p;
  bad.model.noise(0, 0) = -1.0;
  EXPECT_THROW(bl::latentEStep(grid, bad.model, bad.data), std::invalid_argument);
  bad = p;
  bad.model.mean.conservativeResize(3);
  EXPECT_THROW(bl::latentLogLikelihood(grid, bad.model, bad.data), std::invalid_argument);
  EXPECT_THROW(bl::latentPcaModel(grid, p.data, 5, bl::LatentPcaParameters()), std::invalid_argument);
}

TEST(DrProMp, FullDimensionReproducesTheProMp) {
  // 3 DoF, 25 demonstrations from a ProMP (8 kernels) with little observation noise.
  std::mt19937 rng(61);
  constexpr int d = 3, kernels = 8, samples = 60;
  const bl::CoordinationGrid grid = promPGrid(kernels, samples);
  const Eigen::MatrixXd B = randomMatrix(d * kernels, d * kernels, rng) / std::sqrt(d * kernels);
  const Eigen::MatrixXd covariance = 0.05 * B * B.transpose();
  const Eigen::VectorXd mean = randomMatrix(d * kernels, 1, rng);
  const Eigen::MatrixXd L = bl::choleskyFactor(covariance + 1e-9 * Eigen::MatrixXd::Identity(d * kernels, d * kernels));
  bl::GaussianSampler sampler;
  std::vector<Eigen::MatrixXd> demonstrations;
  for (int k = 0; k < 25; ++k) {
    demonstrations.push_back(
        bl::coordinatedValues(grid, {Eigen::MatrixXd::Identity(d, d)}, sampler.draw(mean, L, rng)) +
        1e-3 * randomMatrix(samples, d, rng));
  }
  bp::DrProMpParameters parameters;
  parameters.promp.kernels = kernels;
  parameters.latent_dims = d;
  parameters.em.max_iterations = 200;
  const bp::DrProMp dr = bp::DrProMp::fit(parameters, demonstrations, 2.0);
  const bp::ProMp full = bp::ProMp::fit(parameters.promp, demonstrations, 2.0);
  // The same trajectory distribution: mean and covariance of [q; q̇] at every phase, relative to the ProMP's spread.
  const bp::ProMp lifted = dr.fullProMp();
  bp::DrProMpData data(dr);
  bp::ProMpData full_data(full), lifted_data(lifted);
  Eigen::VectorXd q(d), qd(d), q_full(d), qd_full(d), q_lifted(d), qd_lifted(d);
  Eigen::MatrixXd S(2 * d, 2 * d), S_full(2 * d, 2 * d), S_lifted(2 * d, 2 * d);
  for (const double z : {0.0, 0.1, 0.37, 0.5, 0.8, 1.0}) {
    ASSERT_EQ(dr.mean(data, z, q, qd), bp::ProMpStatus::Success);
    ASSERT_EQ(dr.stateCovariance(data, z, S), bp::ProMpStatus::Success);
    ASSERT_EQ(full.mean(full_data, z, q_full, qd_full), bp::ProMpStatus::Success);
    ASSERT_EQ(full.stateCovariance(full_data, z, S_full), bp::ProMpStatus::Success);
    ASSERT_EQ(lifted.mean(lifted_data, z, q_lifted, qd_lifted), bp::ProMpStatus::Success);
    ASSERT_EQ(lifted.stateCovariance(lifted_data, z, S_lifted), bp::ProMpStatus::Success);
    const Eigen::VectorXd sigma = S_full.diagonal().cwiseSqrt();
    EXPECT_LT(((q - q_full).array() / sigma.head(d).array()).abs().maxCoeff(), 0.02) << "z = " << z;
    EXPECT_LT(((qd - qd_full).array() / sigma.tail(d).array()).abs().maxCoeff(), 0.02) << "z = " << z;
    const Eigen::MatrixXd scale = sigma * sigma.transpose();
    EXPECT_LT(((S - S_full).array() / scale.array()).abs().maxCoeff(), 0.03) << "z = " << z;
    // Ω ⊗ I lifting gives exactly the DR-ProMP's own evaluation.
    EXPECT_LT((q - q_lifted).cwiseAbs().maxCoeff(), 1e-10);
    EXPECT_LT((S - S_lifted).cwiseAbs().maxCoeff(), 1e-10 * (1.0 + S.cwiseAbs().maxCoeff()));
  }
}

TEST(DrProMp, RejectsInconsistentModels) {
  bp::ProMpParameters parameters;
  parameters.kernels = 4;
  const Eigen::MatrixXd omega = Eigen::MatrixXd::Identity(3, 2);
  const Eigen::VectorXd mean = Eigen::VectorXd::Zero(8);
  const Eigen::MatrixXd covariance = Eigen::MatrixXd::Identity(8, 8);
  const Eigen::MatrixXd noise = Eigen::MatrixXd::Identity(3, 3);
  EXPECT_NO_THROW(bp::DrProMp(parameters, omega, mean, covariance, noise, 1.0));
  EXPECT_THROW(bp::DrProMp(parameters, Eigen::MatrixXd::Zero(3, 2), mean, covariance, noise, 1.0),
               std::invalid_argument);
  EXPECT_THROW(bp::DrProMp(parameters, omega, Eigen::VectorXd::Zero(7), covariance, noise, 1.0), std::invalid_argument);
  EXPECT_THROW(bp::DrProMp(parameters, omega, mean, covariance, Eigen::MatrixXd::Identity(2, 2), 1.0),
               std::invalid_argument);
  EXPECT_THROW(bp::DrProMp(parameters, omega, mean, covariance, noise, 0.0), std::invalid_argument);
  const bp::DrProMp model(parameters, omega, mean, covariance, noise, 1.0, Eigen::MatrixXd::Ones(8, 1));
  EXPECT_THROW(model.forContext(Eigen::VectorXd::Zero(2)), std::invalid_argument);
  EXPECT_NEAR(model.forContext(Eigen::VectorXd::Constant(1, 2.0)).latent().weightMean()[3], 2.0, 1e-15);
}

namespace {

/// Propagates the closed loop's moments exactly on the d-DoF system: F = I + dt (A + B Ω K_t Ω_2†), drift
/// dt B Ω κ_t, noise B Σ_u Bᵀ dt, from the DR-ProMP's initial moments. Returns the largest deviation from the
/// DR-ProMP's moments over the movement, relative to its standard deviations: max |Δμ_i| / σ_i, max |ΔΣ_ij| / σ_i σ_j.
std::pair<double, double> propagatedDeviation(const bp::DrProMp& promp, const bp::DrProMpController& controller,
                                              const bp::LinearisedSystem& system) {
  const int d = promp.dofs();
  const double dt = controller.dt();
  bp::DrProMpData data(promp);
  Eigen::VectorXd mu(2 * d), mu_ref(2 * d);
  Eigen::MatrixXd Sigma(2 * d, 2 * d), Sigma_ref(2 * d, 2 * d);
  EXPECT_EQ(promp.mean(data, 0.0, mu.head(d), mu.tail(d)), bp::ProMpStatus::Success);
  EXPECT_EQ(promp.stateCovariance(data, 0.0, Sigma), bp::ProMpStatus::Success);
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(2 * d, 2 * d);
  const Eigen::MatrixXd& omega = promp.coordination();
  std::pair<double, double> deviation(0.0, 0.0);
  for (int k = 0; k < controller.steps(); ++k) {
    const Eigen::MatrixXd K = omega * controller.latent().gain(k) * controller.stateProjection();
    const Eigen::MatrixXd F = I + dt * (system.A + system.B * K);
    mu = F * mu + dt * system.B * (omega * controller.latent().offset(k));
    Sigma = F * Sigma * F.transpose() + dt * system.B * controller.inputCovariance(k) * system.B.transpose();
    const double z = std::min(1.0, (k + 1) * dt / promp.duration());
    EXPECT_EQ(promp.mean(data, z, mu_ref.head(d), mu_ref.tail(d)), bp::ProMpStatus::Success);
    EXPECT_EQ(promp.stateCovariance(data, z, Sigma_ref), bp::ProMpStatus::Success);
    const Eigen::VectorXd sigma = Sigma_ref.diagonal().cwiseSqrt();
    deviation.first = std::max(deviation.first, ((mu - mu_ref).array() / sigma.array()).abs().maxCoeff());
    deviation.second = std::max(deviation.second,
                                ((Sigma - Sigma_ref).array() / (sigma * sigma.transpose()).array()).abs().maxCoeff());
  }
  return deviation;
}

}  // namespace

TEST(DrProMpController, ClosedLoopFollowsTheDistribution) {
  // A DR-ProMP of 4 DoF in 2 latent DoF (random weights), on a double integrator per DoF. As for the full ProMP
  // controller, the position rows q_{t+dt} = q_t + dt q̇_t cannot be reached by the input: the propagated moments
  // stay within O(dt) of the DR-ProMP's, and halving dt halves the deviation (an error in a gain would not vanish).
  // Measured at dt = 1 ms: 0.121 σ (means), 0.046 σ_i σ_j (covariances); bounds 0.15 and 0.06.
  std::mt19937 rng(71);
  constexpr int d = 4, r = 2, kernels = 10;
  constexpr double dt = 1e-3, duration = 1.0;
  bp::ProMpParameters parameters;
  parameters.kernels = kernels;
  const Eigen::MatrixXd omega = orthonormal(d, r, rng);
  const Eigen::MatrixXd B = randomMatrix(r * kernels, r * kernels, rng) / std::sqrt(r * kernels);
  const bp::DrProMp promp(parameters, omega, randomMatrix(r * kernels, 1, rng),
                          0.05 * B * B.transpose() + 1e-4 * Eigen::MatrixXd::Identity(r * kernels, r * kernels),
                          1e-6 * Eigen::MatrixXd::Identity(d, d), duration);
  const bp::LinearisedSystem system = bp::LinearisedSystem::doubleIntegrator(d);
  const bp::DrProMpController controller(promp, {system}, dt, 0.0, 1e-9);
  const auto [mean_deviation, covariance_deviation] = propagatedDeviation(promp, controller, system);
  EXPECT_LT(mean_deviation, 0.15);
  EXPECT_LT(covariance_deviation, 0.06);
  const auto [mean_half, covariance_half] =
      propagatedDeviation(promp, bp::DrProMpController(promp, {system}, 0.5 * dt, 0.0, 1e-9), system);
  EXPECT_NEAR(mean_half / mean_deviation, 0.5, 0.05);
  EXPECT_NEAR(covariance_half / covariance_deviation, 0.5, 0.05);
  // The commands: u = Ω (K_t Ω_2† y + κ_t); Σ_u has rank r, and with α the noise also leaves the latent space.
  bp::DrProMpControllerData scratch(controller);
  Eigen::VectorXd y = Eigen::VectorXd::LinSpaced(2 * d, -0.2, 0.3), u(d);
  ASSERT_EQ(controller.command(scratch, 10, y, u), bp::ProMpControlStatus::Success);
  const Eigen::VectorXd expected =
      omega * (controller.latent().gain(10) * controller.stateProjection() * y + controller.latent().offset(10));
  EXPECT_LT((u - expected).cwiseAbs().maxCoeff(), 1e-12);
  const Eigen::VectorXd eigenvalues =
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(controller.inputCovariance(10)).eigenvalues();
  EXPECT_LT(eigenvalues.head(d - r).cwiseAbs().maxCoeff(), 1e-12 * eigenvalues[d - 1]);
  EXPECT_GT(eigenvalues[d - r], 1e-6 * eigenvalues[d - 1]);
  const bp::DrProMpController exploring(promp, {system}, dt, 0.01, 1e-9);
  EXPECT_LT((exploring.inputCovariance(10) - controller.inputCovariance(10) - 1e-4 * Eigen::MatrixXd::Identity(d, d))
                .cwiseAbs()
                .maxCoeff(),
            1e-12);
  EXPECT_EQ(controller.command(scratch, controller.steps(), y, u), bp::ProMpControlStatus::OutOfSchedule);
  EXPECT_EQ(controller.command(scratch, 0, Eigen::VectorXd::Zero(d), u), bp::ProMpControlStatus::WrongSize);
  y[0] = NAN;
  EXPECT_EQ(controller.command(scratch, 0, y, u), bp::ProMpControlStatus::NotFinite);
  EXPECT_THROW(bp::DrProMpController(promp, {system}, dt, -1.0), std::invalid_argument);
}
