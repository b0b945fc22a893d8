// Policy-search updates (off the control loop): one REPS update and one Dual REPS update, clustering included, of
// 50 rollouts of dimension 20 — the thesis' bottle-task size, whose clustering alone took 0.52 s (Sec. 6.1.3) —
// and Alg. 6.1's clustering alone.
//
//   learning_bench [--benchmark_format=json] [--benchmark_repetitions=N] ...
#include "bimanual_skills/learning/dual_reps.hpp"

#include "benchmark_main.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <random>
#include <string>

namespace bl = bimanual_skills::learning;

namespace {

constexpr unsigned kSeed = 42;

/// 50 samples of N(0, I) in 20-D with a two-optimum reward, as one batch of a multimodal task.
struct Batch {
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(20);
  Eigen::MatrixXd covariance = Eigen::MatrixXd::Identity(20, 20);
  Eigen::MatrixXd samples = Eigen::MatrixXd(50, 20);
  Eigen::VectorXd rewards = Eigen::VectorXd(50);

  Batch() {
    std::mt19937 rng(kSeed);
    samples = bimanual_skills::learning::GaussianSampler().draw(mean, covariance, 50, rng);
    for (Eigen::Index k = 0; k < samples.rows(); ++k) {
      const Eigen::VectorXd theta = samples.row(k).transpose();
      rewards[k] = -std::min((theta.array() - 1.0).matrix().norm(), (theta.array() + 1.0).matrix().norm());
    }
  }
};

const Batch& batch() {
  static const Batch b;
  return b;
}

void BM_RepsUpdate(benchmark::State& state) {
  const Batch& b = batch();
  for (auto _ : state) {
    bl::Reps reps(bl::RepsParameters{});
    benchmark::DoNotOptimize(reps.update(b.samples, b.rewards).mean.data());
  }
}

void BM_DualRepsUpdate(benchmark::State& state) {
  const Batch& b = batch();
  for (auto _ : state) {
    bl::DualReps dreps(bl::DualRepsParameters{});
    benchmark::DoNotOptimize(dreps.update(b.mean, b.covariance, b.samples, b.rewards).policy.mean.data());
  }
}

void BM_DualRepsClustering(benchmark::State& state) {
  const Batch& b = batch();
  const bl::DualRepsParameters parameters;
  for (auto _ : state) {
    benchmark::DoNotOptimize(
        bl::dualRepsClusters(b.samples, bl::normalisedRewards(b.rewards), b.mean, b.covariance, parameters).data());
  }
}

}  // namespace

BENCHMARK(BM_RepsUpdate)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_DualRepsUpdate)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_DualRepsClustering)->Unit(benchmark::kMicrosecond);

int main(int argc, char** argv) {
  bimanual_skills::bench::initialiseBenchmarks(
      argc, argv, "learning_bench",
      "One REPS and one Dual REPS update (clustering included) of 50 rollouts of 20 parameters.");
  benchmark::AddCustomContext("seed", std::to_string(kSeed));
  benchmark::AddCustomContext("batch", "50 rollouts x 20 parameters, two-optimum reward");
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
