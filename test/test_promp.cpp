// ProMPs (thesis 5.16–5.18): the fitted distribution matches the demonstrations' mean and spread, conditioning
// passes through its via-point, samples follow the distribution, the state covariance matches finite differences
// of sampled paths, bad input throws or is a status, evaluation does not allocate. Blending by the product of
// Gaussians reduces to its active ProMP, averages equal-covariance means and switches with the activations. The
// contextual ProMP (Sec. 7.1.1) recovers a known linear context mapping.
#include "bimanual_skills/primitives/contextual_promp.hpp"
#include "bimanual_skills/primitives/promp.hpp"
#include "bimanual_skills/primitives/promp_blending.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>

#include <cmath>
#include <random>
#include <vector>

namespace bp = bimanual_skills::primitives;
using bimanual_skills::testing::NoAllocGuard;

namespace {

constexpr int kSamples = 200;
constexpr double kSpread = 0.1;  // standard deviation of the bump amplitude across demonstrations

double base(double z, int j) {
  return (0.3 + 0.2 * j) * std::sin(M_PI * z) + 0.1 * j * z;
}
double bump(double z) {
  return std::exp(-std::pow((z - 0.5) / 0.15, 2));
}

/// 30 demonstrations of 2 DoF: a base path plus a bump whose amplitude varies with σ = kSpread.
std::vector<Eigen::MatrixXd> demonstrations(std::vector<double>& amplitudes) {
  std::mt19937 rng(21);
  std::normal_distribution<double> amplitude(0.0, kSpread);
  std::vector<Eigen::MatrixXd> out;
  for (int d = 0; d < 30; ++d) {
    const double a = amplitude(rng);
    amplitudes.push_back(a);
    Eigen::MatrixXd y(kSamples, 2);
    for (int r = 0; r < kSamples; ++r) {
      const double z = r / double(kSamples - 1);
      for (int j = 0; j < 2; ++j) y(r, j) = base(z, j) + a * bump(z);
    }
    out.push_back(y);
  }
  return out;
}

}  // namespace

TEST(ProMp, FitMatchesTheDemonstrationsMeanAndSpread) {
  std::vector<double> amplitudes;
  const bp::ProMp promp = bp::ProMp::fit(bp::ProMpParameters(), demonstrations(amplitudes), 2.0);
  bp::ProMpData data(promp);
  double mean_a = 0.0, var_a = 0.0;
  for (double a : amplitudes) mean_a += a / amplitudes.size();
  for (double a : amplitudes) var_a += (a - mean_a) * (a - mean_a) / amplitudes.size();
  Eigen::VectorXd y(2), yd(2), b(promp.kernels()), db(promp.kernels());
  Eigen::MatrixXd cov(2, 2);
  for (double z : {0.1, 0.3, 0.5, 0.7, 0.9}) {
    ASSERT_EQ(promp.mean(data, z, y, yd), bp::ProMpStatus::Success);
    for (int j = 0; j < 2; ++j) EXPECT_NEAR(y[j], base(z, j) + mean_a * bump(z), 5e-3) << "z " << z;
    ASSERT_EQ(promp.covariance(data, z, cov), bp::ProMpStatus::Success);
    // Σ_ω = var(a) ω_b ω_bᵀ + prior I (ω_b the bump's weights), so the variance at z is var(a) bump(z)² plus the
    // prior's ‖b(z)‖²: within 10 % at every phase, also where the bump (and a wrong covariance) is near zero.
    promp.basis(z, b, db);
    const double expected = var_a * bump(z) * bump(z) + promp.parameters().covariance_prior * b.squaredNorm();
    EXPECT_NEAR(cov(0, 0), expected, 0.1 * expected) << "z " << z;
  }
  // Velocity: d/dt of the mean path (duration 2 s), inside the phase range (normalised bases are poor at its ends).
  const double z = 0.25;
  const double bump_slope = -2.0 * (z - 0.5) / (0.15 * 0.15) * bump(z);
  ASSERT_EQ(promp.mean(data, z, y, yd), bp::ProMpStatus::Success);
  EXPECT_NEAR(yd[0], (0.3 * M_PI * std::cos(M_PI * z) + mean_a * bump_slope) / 2.0, 0.02);
  EXPECT_LT(promp.observationVariance().maxCoeff(), 1e-4);
}

TEST(ProMp, ConditioningPassesThroughTheViaPoint) {
  std::vector<double> amplitudes;
  const bp::ProMp promp = bp::ProMp::fit(bp::ProMpParameters(), demonstrations(amplitudes), 2.0);
  bp::ProMpData data(promp);
  Eigen::VectorXd y(2), yd(2);
  Eigen::MatrixXd cov(2, 2), cov_after(2, 2);
  ASSERT_EQ(promp.mean(data, 0.4, y, yd), bp::ProMpStatus::Success);
  ASSERT_EQ(promp.covariance(data, 0.4, cov), bp::ProMpStatus::Success);
  const Eigen::VectorXd via = y + Eigen::VectorXd::Constant(2, 0.08);
  const bp::ProMp through = promp.conditioned(0.4, via, 1e-8 * Eigen::MatrixXd::Identity(2, 2));
  ASSERT_EQ(through.mean(data, 0.4, y, yd), bp::ProMpStatus::Success);
  EXPECT_LE((y - via).cwiseAbs().maxCoeff(), 1e-3);
  ASSERT_EQ(through.covariance(data, 0.4, cov_after), bp::ProMpStatus::Success);
  EXPECT_LT(cov_after(0, 0), 1e-2 * cov(0, 0));
  // With a velocity too.
  const Eigen::VectorXd via_velocity = Eigen::VectorXd::Constant(2, 0.1);
  const bp::ProMp both = promp.conditioned(0.6, via, 1e-8 * Eigen::MatrixXd::Identity(4, 4), via_velocity);
  ASSERT_EQ(both.mean(data, 0.6, y, yd), bp::ProMpStatus::Success);
  EXPECT_LE((y - via).cwiseAbs().maxCoeff(), 2e-3);
  EXPECT_LE((yd - via_velocity).cwiseAbs().maxCoeff(), 2e-2);
}

TEST(ProMp, SamplesFollowTheDistribution) {
  std::vector<double> amplitudes;
  const bp::ProMp promp = bp::ProMp::fit(bp::ProMpParameters(), demonstrations(amplitudes), 2.0);
  std::mt19937 rng(3);
  const int n = 4000;
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(promp.weightMean().size());
  for (int k = 0; k < n; ++k) sum += promp.sample(rng);
  const Eigen::VectorXd sd = promp.weightCovariance().diagonal().cwiseSqrt();
  EXPECT_LE(((sum / n - promp.weightMean()).array() / sd.array()).abs().maxCoeff(), 5.0 / std::sqrt(double(n)));
}

TEST(ProMp, BadInputAndNoAllocation) {
  std::vector<double> amplitudes;
  std::vector<Eigen::MatrixXd> demos = demonstrations(amplitudes);
  EXPECT_THROW(bp::ProMp::fit(bp::ProMpParameters(), {demos[0]}, 2.0), std::invalid_argument);
  demos[3](5, 1) = std::nan("");
  EXPECT_THROW(bp::ProMp::fit(bp::ProMpParameters(), demos, 2.0), std::invalid_argument);
  demos = demonstrations(amplitudes);
  const bp::ProMp promp = bp::ProMp::fit(bp::ProMpParameters(), demos, 2.0);
  bp::ProMpData data(promp);
  EXPECT_THROW(promp.conditioned(0.5, Eigen::VectorXd::Zero(3), Eigen::MatrixXd::Identity(3, 3)),
               std::invalid_argument);
  EXPECT_THROW(promp.withMean(Eigen::VectorXd::Zero(3)), std::invalid_argument);
  Eigen::VectorXd y(2), yd(2), wrong(3);
  Eigen::MatrixXd cov(2, 2), state_cov(4, 4);
  NoAllocGuard guard;
  for (double z = 0.0; z <= 1.0; z += 0.1) {
    ASSERT_EQ(promp.mean(data, z, y, yd), bp::ProMpStatus::Success);
    ASSERT_EQ(promp.covariance(data, z, cov), bp::ProMpStatus::Success);
    ASSERT_EQ(promp.stateCovariance(data, z, state_cov), bp::ProMpStatus::Success);
  }
  // Bad input is a status: wrong output sizes, a non-finite phase.
  EXPECT_NE(promp.mean(data, 0.5, wrong, yd), bp::ProMpStatus::Success);
  EXPECT_NE(promp.covariance(data, 0.5, state_cov), bp::ProMpStatus::Success);
  EXPECT_NE(promp.stateCovariance(data, 0.5, cov), bp::ProMpStatus::Success);
  EXPECT_NE(promp.covariance(data, std::nan(""), cov), bp::ProMpStatus::Success);
}

TEST(ProMp, StateCovarianceMatchesFiniteDifferencesOfSampledPaths) {
  // Reference: sample weights, take each sample's mean path (positions only) and its central difference in time;
  // the empirical covariance of [q; q̇] must match stateCovariance within its sampling error.
  std::vector<double> amplitudes;
  const bp::ProMp promp = bp::ProMp::fit(bp::ProMpParameters(), demonstrations(amplitudes), 2.0);
  bp::ProMpData data(promp);
  const double z = 0.4, h = 1e-5;
  const int n = 4000;
  std::mt19937 rng(11);
  Eigen::MatrixXd states(4, n);
  Eigen::VectorXd y(2), yd(2), ahead(2), behind(2);
  for (int s = 0; s < n; ++s) {
    const bp::ProMp path = promp.withMean(promp.sample(rng));
    ASSERT_EQ(path.mean(data, z, y, yd), bp::ProMpStatus::Success);
    ASSERT_EQ(path.mean(data, z + h, ahead, yd), bp::ProMpStatus::Success);
    ASSERT_EQ(path.mean(data, z - h, behind, yd), bp::ProMpStatus::Success);
    states.col(s) << y, (ahead - behind) / (2.0 * h * promp.duration());
  }
  const Eigen::MatrixXd centred = states.colwise() - states.rowwise().mean();
  const Eigen::MatrixXd empirical = centred * centred.transpose() / n;
  Eigen::MatrixXd expected(4, 4), positions(2, 2);
  ASSERT_EQ(promp.stateCovariance(data, z, expected), bp::ProMpStatus::Success);
  ASSERT_EQ(promp.covariance(data, z, positions), bp::ProMpStatus::Success);
  EXPECT_LE((expected.topLeftCorner(2, 2) - positions).cwiseAbs().maxCoeff(), 1e-12);
  // Standard error of a sample covariance entry: sqrt((σ_ii σ_jj + σ_ij²) / n); 5 of them.
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      const double se = std::sqrt((expected(i, i) * expected(j, j) + expected(i, j) * expected(i, j)) / n);
      EXPECT_NEAR(empirical(i, j), expected(i, j), 5.0 * se) << "entry " << i << ", " << j;
    }
  }
}

TEST(ProMpBlending, OneActiveProMpIsThatProMp) {
  std::vector<double> amplitudes;
  const bp::ProMp a = bp::ProMp::fit(bp::ProMpParameters(), demonstrations(amplitudes), 2.0);
  // A second ProMP with another mean and a very different covariance: a through a via-point.
  const bp::ProMp b = a.conditioned(0.5, Eigen::VectorXd::Constant(2, 0.6), 1e-4 * Eigen::MatrixXd::Identity(2, 2));
  const Eigen::VectorXd phases = Eigen::VectorXd::LinSpaced(11, 0.0, 1.0);
  for (int active = 0; active < 2; ++active) {
    Eigen::MatrixXd activations = Eigen::MatrixXd::Zero(phases.size(), 2);
    activations.col(active).setOnes();
    const bp::TrajectoryDistribution blended = bp::blend({a, b}, phases, activations);
    const bp::ProMp& reference = active == 0 ? a : b;
    bp::ProMpData data(reference);
    Eigen::VectorXd mean(4);
    Eigen::MatrixXd covariance(4, 4);
    for (Eigen::Index t = 0; t < phases.size(); ++t) {
      ASSERT_EQ(reference.mean(data, phases[t], mean.head(2), mean.tail(2)), bp::ProMpStatus::Success);
      ASSERT_EQ(reference.stateCovariance(data, phases[t], covariance), bp::ProMpStatus::Success);
      EXPECT_LE((blended.means[t] - mean).cwiseAbs().maxCoeff(), 1e-9) << "phase " << phases[t];
      EXPECT_LE((blended.covariances[t] - covariance).cwiseAbs().maxCoeff(), 1e-9 * covariance.cwiseAbs().maxCoeff())
          << "phase " << phases[t];
    }
  }
}

TEST(ProMpBlending, EqualCovariancesAverageTheMeans) {
  // b = a shifted by 0.5 on every weight: the normalised bases sum to 1, so b's positions are a's + 0.5, its
  // velocities a's, and both have the same covariance. The product with activations α_a, α_b then has the
  // activation-weighted mean and the covariance Σ / (α_a + α_b).
  std::vector<double> amplitudes;
  const bp::ProMp a = bp::ProMp::fit(bp::ProMpParameters(), demonstrations(amplitudes), 2.0);
  const bp::ProMp b = a.withMean((a.weightMean().array() + 0.5).matrix());
  const Eigen::VectorXd phases = Eigen::VectorXd::LinSpaced(21, 0.0, 1.0);
  Eigen::MatrixXd halves = Eigen::MatrixXd::Constant(phases.size(), 2, 0.5);
  Eigen::MatrixXd switching(phases.size(), 2);  // a smooth switch from a to b around z = 0.5
  for (Eigen::Index t = 0; t < phases.size(); ++t) {
    switching(t, 1) = 1.0 / (1.0 + std::exp(-(phases[t] - 0.5) / 0.05));
    switching(t, 0) = 1.0 - switching(t, 1);
  }
  bp::ProMpData data(a);
  Eigen::VectorXd mean(4);
  Eigen::MatrixXd covariance(4, 4);
  for (const Eigen::MatrixXd& activations : {halves, switching, Eigen::MatrixXd(2.0 * halves)}) {
    const bp::TrajectoryDistribution blended = bp::blend({a, b}, phases, activations);
    for (Eigen::Index t = 0; t < phases.size(); ++t) {
      ASSERT_EQ(a.mean(data, phases[t], mean.head(2), mean.tail(2)), bp::ProMpStatus::Success);
      ASSERT_EQ(a.stateCovariance(data, phases[t], covariance), bp::ProMpStatus::Success);
      const double total = activations.row(t).sum();
      mean.head(2).array() += 0.5 * activations(t, 1) / total;
      EXPECT_LE((blended.means[t] - mean).cwiseAbs().maxCoeff(), 1e-8) << "phase " << phases[t];
      EXPECT_LE((blended.covariances[t] - covariance / total).cwiseAbs().maxCoeff(),
                1e-8 * covariance.cwiseAbs().maxCoeff())
          << "phase " << phases[t];
    }
  }
}

TEST(ProMpBlending, PassesFromOneToTheOtherWhereActivationsSwitch) {
  std::vector<double> amplitudes;
  const bp::ProMp a = bp::ProMp::fit(bp::ProMpParameters(), demonstrations(amplitudes), 2.0);
  const bp::ProMp b = a.withMean((a.weightMean().array() - 0.4).matrix())
                          .conditioned(0.9, Eigen::VectorXd::Constant(2, -0.5), 1e-4 * Eigen::MatrixXd::Identity(2, 2));
  const Eigen::VectorXd phases = Eigen::VectorXd::LinSpaced(101, 0.0, 1.0);
  Eigen::MatrixXd activations(phases.size(), 2);
  for (Eigen::Index t = 0; t < phases.size(); ++t) {
    activations(t, 1) = 1.0 / (1.0 + std::exp(-(phases[t] - 0.5) / 0.03));
    activations(t, 0) = 1.0 - activations(t, 1);
  }
  const bp::TrajectoryDistribution blended = bp::blend({a, b}, phases, activations);
  bp::ProMpData data(a);
  Eigen::VectorXd mean_a(4), mean_b(4);
  for (Eigen::Index t = 0; t < phases.size(); ++t) {
    ASSERT_EQ(a.mean(data, phases[t], mean_a.head(2), mean_a.tail(2)), bp::ProMpStatus::Success);
    ASSERT_EQ(b.mean(data, phases[t], mean_b.head(2), mean_b.tail(2)), bp::ProMpStatus::Success);
    const double gap = (mean_a.head(2) - mean_b.head(2)).cwiseAbs().maxCoeff();
    // Away from the switch (activation of the other below ~1e-3) the blend is that ProMP, to 1 % of the gap.
    if (phases[t] <= 0.3) {
      EXPECT_LE((blended.means[t] - mean_a).head(2).cwiseAbs().maxCoeff(), 0.01 * gap) << "phase " << phases[t];
    }
    if (phases[t] >= 0.7) {
      EXPECT_LE((blended.means[t] - mean_b).head(2).cwiseAbs().maxCoeff(), 0.01 * gap) << "phase " << phases[t];
    }
    // Without jumps: the switch takes several steps of 0.01.
    if (t > 0) {
      EXPECT_LE((blended.means[t] - blended.means[t - 1]).head(2).cwiseAbs().maxCoeff(), 0.2 * gap);
    }
  }
}

TEST(ProMpBlending, BadInput) {
  std::vector<double> amplitudes;
  const bp::ProMp a = bp::ProMp::fit(bp::ProMpParameters(), demonstrations(amplitudes), 2.0);
  const Eigen::VectorXd phases = Eigen::VectorXd::LinSpaced(3, 0.0, 1.0);
  EXPECT_THROW(bp::blend({}, phases, Eigen::MatrixXd::Ones(3, 0)), std::invalid_argument);
  EXPECT_THROW(bp::blend({a, a}, phases, Eigen::MatrixXd::Ones(3, 1)), std::invalid_argument);
  EXPECT_THROW(bp::blend({a, a}, phases, Eigen::MatrixXd::Zero(3, 2)), std::invalid_argument);
  EXPECT_THROW(bp::blend({a, a}, phases, -Eigen::MatrixXd::Ones(3, 2)), std::invalid_argument);
  const bp::ProMp rigid(bp::ProMpParameters(), 2, a.weightMean(), Eigen::MatrixXd::Zero(40, 40),
                        a.observationVariance(), 2.0);
  EXPECT_THROW(bp::blend({a, rigid}, phases, Eigen::MatrixXd::Ones(3, 2)), std::invalid_argument);
  Eigen::MatrixXd only_a = Eigen::MatrixXd::Zero(3, 2);
  only_a.col(0).setOnes();
  EXPECT_NO_THROW(bp::blend({a, rigid}, phases, only_a));  // a singular ProMP with no activation does not enter
}

namespace {

double minimumJerk(double z) {
  return z * z * z * (10.0 - 15.0 * z + 6.0 * z * z);
}

}  // namespace

TEST(ContextualProMp, RecoversTheContextMappingForAnUnseenContext) {
  // 30 demonstrations: the base path of the tests above, shifted by a minimum-jerk ramp to a goal offset s_j per
  // DoF (the context s ∈ ℝ², so the true K_ω maps s_j onto DoF j's ramp), plus the random bump of σ = kSpread that
  // the context does not explain.
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> goal(-0.3, 0.3);
  std::normal_distribution<double> amplitude(0.0, kSpread);
  std::vector<Eigen::MatrixXd> demos;
  std::vector<Eigen::VectorXd> contexts;
  std::vector<double> amplitudes;
  for (int d = 0; d < 30; ++d) {
    const Eigen::Vector2d s(goal(rng), goal(rng));
    const double a = amplitude(rng);
    Eigen::MatrixXd y(kSamples, 2);
    for (int r = 0; r < kSamples; ++r) {
      const double z = r / double(kSamples - 1);
      for (int j = 0; j < 2; ++j) y(r, j) = base(z, j) + s[j] * minimumJerk(z) + a * bump(z);
    }
    demos.push_back(y);
    contexts.emplace_back(s);
    amplitudes.push_back(a);
  }
  const bp::ContextualProMp contextual = bp::ContextualProMp::fit(bp::ProMpParameters(), demos, contexts, 2.0);
  EXPECT_EQ(contextual.contextSize(), 2);
  // In 30 samples the bump amplitudes correlate with the contexts by chance, and the least-squares fit attributes
  // that to K_ω. The reference is the same regression on the scalar amplitudes, a_k ≈ β_0 + β_sᵀ s_k (its residual
  // variance is what Σ_ω must hold).
  Eigen::MatrixXd X(30, 3);
  for (int d = 0; d < 30; ++d) X.row(d) << 1.0, contexts[d].transpose();
  const Eigen::VectorXd a = Eigen::Map<const Eigen::VectorXd>(amplitudes.data(), 30);
  const Eigen::Vector3d beta = (X.transpose() * X).ldlt().solve(X.transpose() * a);
  const double var_a = (a - X * beta).squaredNorm() / 30.0;
  const Eigen::Vector2d unseen(0.25, -0.35);  // the second entry outside the demonstrated range
  const double mean_a = beta[0] + beta.tail(2).dot(unseen);
  const bp::ProMp promp = contextual.forContext(unseen);
  bp::ProMpData data(promp);
  Eigen::VectorXd y(2), yd(2);
  Eigen::MatrixXd cov(2, 2);
  for (double z : {0.1, 0.3, 0.5, 0.7, 0.9, 1.0}) {
    ASSERT_EQ(promp.mean(data, z, y, yd), bp::ProMpStatus::Success);
    for (int j = 0; j < 2; ++j) {
      EXPECT_NEAR(y[j], base(z, j) + unseen[j] * minimumJerk(z) + mean_a * bump(z), 5e-3) << "z " << z;
    }
    // Σ_ω from the residuals holds only the unexplained bump (a plain ProMP would also hold the goals' spread).
    ASSERT_EQ(promp.covariance(data, z, cov), bp::ProMpStatus::Success);
    EXPECT_NEAR(std::sqrt(cov(0, 0)), std::sqrt(var_a) * bump(z), 0.1 * std::sqrt(var_a) + 2e-3) << "z " << z;
  }
  // Bad input.
  EXPECT_THROW(contextual.forContext(Eigen::VectorXd::Zero(3)), std::invalid_argument);
  EXPECT_THROW(contextual.forContext(Eigen::Vector2d(0.0, std::nan(""))), std::invalid_argument);
  std::vector<Eigen::VectorXd> short_contexts(contexts.begin(), contexts.end() - 1);
  EXPECT_THROW(bp::ContextualProMp::fit(bp::ProMpParameters(), demos, short_contexts, 2.0), std::invalid_argument);
  contexts[4] = Eigen::VectorXd::Zero(3);
  EXPECT_THROW(bp::ContextualProMp::fit(bp::ProMpParameters(), demos, contexts, 2.0), std::invalid_argument);
  contexts[4] = Eigen::Vector2d(std::nan(""), 0.0);
  EXPECT_THROW(bp::ContextualProMp::fit(bp::ProMpParameters(), demos, contexts, 2.0), std::invalid_argument);
  EXPECT_THROW(bp::ContextualProMp(bp::ProMpParameters(), 2, promp.weightMean(), Eigen::MatrixXd::Zero(39, 2),
                                   promp.weightCovariance(), promp.observationVariance(), 2.0),
               std::invalid_argument);
}

TEST(ProMp, BlockCovarianceEqualsTheDenseProduct) {
  // Independent reference: Ψ_zᵀ Σ_ω Ψ_z with the dense Ψ_z of blockBasis(), at 7 DoF × 20 kernels.
  std::mt19937 rng(8);
  std::normal_distribution<double> normal(0.0, 1.0);
  const int dofs = 7, kernels = 20, n = dofs * kernels;
  Eigen::MatrixXd A(n, n);
  for (Eigen::Index i = 0; i < A.size(); ++i) A.data()[i] = normal(rng);
  bp::ProMpParameters parameters;
  parameters.kernels = kernels;
  const bp::ProMp promp(parameters, dofs, Eigen::VectorXd::Zero(n), A * A.transpose() / n, Eigen::VectorXd::Ones(dofs),
                        2.0);
  bp::ProMpData data(promp);
  Eigen::MatrixXd state_covariance(2 * dofs, 2 * dofs), covariance(dofs, dofs);
  for (const double z : {0.0, 0.37, 0.8, 1.0}) {
    ASSERT_EQ(promp.stateCovariance(data, z, state_covariance), bp::ProMpStatus::Success);
    ASSERT_EQ(promp.covariance(data, z, covariance), bp::ProMpStatus::Success);
    ASSERT_EQ(promp.blockBasis(data, z), bp::ProMpStatus::Success);
    const Eigen::MatrixXd dense = data.psi.transpose() * promp.weightCovariance() * data.psi;
    EXPECT_LE((state_covariance - dense).cwiseAbs().maxCoeff(), 1e-12 * dense.cwiseAbs().maxCoeff()) << z;
    EXPECT_LE((covariance - dense.topLeftCorner(dofs, dofs)).cwiseAbs().maxCoeff(), 1e-12 * dense.cwiseAbs().maxCoeff())
        << z;
  }
}
