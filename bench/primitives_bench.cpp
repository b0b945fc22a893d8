// Movement primitives per call: one DMP integration step of 7 DoF x 25 kernels, one Cartesian DMP step (position
// and orientation, 25 kernels) with either orientation encoding, and the state covariance of a 7-DoF ProMP with 20
// kernels per DoF, block by block (ours) against the dense product Ψᵀ Σ_ω Ψ (the naive form) in the same run.
//
//   primitives_bench [--benchmark_format=json] [--benchmark_repetitions=N] ...
#include "bench_timing.hpp"
#include "benchmark_main.hpp"
#include "bimanual_skills/primitives/cartesian_dmp.hpp"
#include "bimanual_skills/primitives/dmp.hpp"
#include "bimanual_skills/primitives/promp.hpp"

#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace bp = bimanual_skills::primitives;
using bimanual_skills::bench::timeBatches;

namespace {

constexpr int kSteps = 1000;

/// A 7-DoF DMP fitted to minimum-jerk motions (2 s at 500 Hz), stepped along its own rollout.
void BM_DmpStep(benchmark::State& state) {
  Eigen::MatrixXd demo(1001, 7);
  for (int r = 0; r < demo.rows(); ++r) {
    const double s = r / 1000.0;
    for (int j = 0; j < 7; ++j)
      demo(r, j) = (0.5 - 0.1 * j) * (10 * std::pow(s, 3) - 15 * std::pow(s, 4) + 6 * std::pow(s, 5));
  }
  const bp::Dmp dmp = bp::Dmp::fit(bp::DmpParameters(), demo, 0.002);
  bp::DmpState start = dmp.initialState();
  bp::DmpState running = start;
  timeBatches(state, kSteps, [&](int k) {
    if (k == 0) running = start;  // restart the rollout (a copy of equally sized vectors: no allocation)
    benchmark::DoNotOptimize(dmp.step(running, 0.002));
    benchmark::DoNotOptimize(running.y.data());
  });
}

/// A Cartesian DMP fitted to a minimum-jerk pose motion (0.3 m, 80° about a turning axis; 2 s at 500 Hz), stepped
/// along its own rollout; range(0) = 0: unit-quaternion DMP, 1: quaternion-vector encoding.
void BM_CartesianDmpStep(benchmark::State& state) {
  std::vector<bp::Pose> demo(1001);
  for (int r = 0; r < 1001; ++r) {
    const double s = r / 1000.0;
    const double m = 10 * std::pow(s, 3) - 15 * std::pow(s, 4) + 6 * std::pow(s, 5);
    demo[r].position = Eigen::Vector3d(0.5, 0.0, 0.3) + m * Eigen::Vector3d(0.1, 0.25, -0.15);
    const Eigen::Vector3d axis(std::cos(s), std::sin(s), 0.5);
    demo[r].orientation = Eigen::Quaterniond(Eigen::AngleAxisd(1.4 * m, axis.normalized()));
  }
  const auto encoding =
      state.range(0) == 0 ? bp::OrientationEncoding::UnitQuaternion : bp::OrientationEncoding::QuaternionVector;
  const bp::CartesianDmp dmp = bp::CartesianDmp::fit(bp::DmpParameters(), encoding, demo, 0.002);
  const bp::CartesianDmpState start = dmp.initialState();
  bp::CartesianDmpState running = start;
  timeBatches(state, kSteps, [&](int k) {
    if (k == 0) running = start;  // restart the rollout (equally sized vectors: no allocation)
    benchmark::DoNotOptimize(dmp.step(running, 0.002));
    benchmark::DoNotOptimize(running.orientation.coeffs().data());
  });
}

/// A 7-DoF ProMP with 20 kernels per DoF and a dense random Σ_ω (seed 11), evaluated at 200 phases.
bp::ProMp sevenDofProMp() {
  const int dofs = 7, kernels = 20, n = dofs * kernels;
  std::mt19937 rng(11);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::MatrixXd A(n, n);
  for (Eigen::Index i = 0; i < A.size(); ++i) A.data()[i] = normal(rng);
  bp::ProMpParameters parameters;
  parameters.kernels = kernels;
  return bp::ProMp(parameters, dofs, Eigen::VectorXd::Zero(n), A * A.transpose() / n, Eigen::VectorXd::Ones(dofs), 2.0);
}

/// ProMp::stateCovariance: 14 × 14 from Σ_ω's block columns (allocation-free).
void BM_ProMpStateCovariance(benchmark::State& state) {
  const bp::ProMp promp = sevenDofProMp();
  bp::ProMpData data(promp);
  Eigen::MatrixXd covariance(14, 14);
  timeBatches(state, 200, [&](int k) {
    benchmark::DoNotOptimize(promp.stateCovariance(data, k / 199.0, covariance));
    benchmark::DoNotOptimize(covariance.data());
  });
}

/// The naive form of the same: Ψ_z from blockBasis(), then the dense Ψ_zᵀ Σ_ω Ψ_z (Eigen's blocked product).
void BM_ProMpStateCovarianceDense(benchmark::State& state) {
  const bp::ProMp promp = sevenDofProMp();
  bp::ProMpData data(promp);
  Eigen::MatrixXd covariance(14, 14);
  timeBatches(state, 200, [&](int k) {
    benchmark::DoNotOptimize(promp.blockBasis(data, k / 199.0));
    data.sigma_psi.noalias() = promp.weightCovariance() * data.psi;
    covariance.noalias() = data.psi.transpose() * data.sigma_psi;
    benchmark::DoNotOptimize(covariance.data());
  });
}

}  // namespace

BENCHMARK(BM_ProMpStateCovariance);
BENCHMARK(BM_ProMpStateCovarianceDense);
BENCHMARK(BM_DmpStep);
BENCHMARK(BM_CartesianDmpStep)->Arg(0)->Arg(1)->ArgName("quaternion_vector");

int main(int argc, char** argv) {
  bimanual_skills::bench::initialiseBenchmarks(
      argc, argv, "primitives_bench",
      "DMP and Cartesian DMP steps, and a ProMP state covariance (ours and the dense product) per call.");
  benchmark::AddCustomContext("dmp", "7 DoF x 25 kernels, dt = 2 ms");
  benchmark::AddCustomContext("cartesian_dmp", "position + orientation, 25 kernels, dt = 2 ms");
  benchmark::AddCustomContext("promp", "7 DoF x 20 kernels, state covariance 14 x 14, dense random Sigma_w (seed 11)");
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
