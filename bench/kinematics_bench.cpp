// Forward kinematics and Jacobian of the WAM per call, the core library and KDL in the same run, and single CLIK
// steps (JP, ED, CTP+SD+SVF).
//
//   kinematics_bench [--benchmark_format=json] [--benchmark_repetitions=N] ...
//
// Each benchmark cycles through the same seeded random configurations. Besides Google Benchmark's mean time per
// iteration, counters give the per-call median, p99 and worst case (ns), each from batches of kBatch calls timed with
// a steady clock (per-call = batch time / kBatch, so clock overhead is spread over the batch).
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/kinematics/chain_model.hpp"
#include "bimanual_skills/kinematics/clik.hpp"
#include "cli/package_share.hpp"

#include "bench_timing.hpp"
#include "benchmark_main.hpp"

#include <benchmark/benchmark.h>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainjnttojacsolver.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include <algorithm>
#include <chrono>
#include <random>
#include <string>
#include <vector>

namespace bk = bimanual_skills::kinematics;
using bimanual_skills::bench::kBatch;
using bimanual_skills::bench::timeBatches;

namespace {

constexpr unsigned kSeed = 42;
constexpr int kConfigurations = 1024;
/// The WAM of urdf/wam.urdf.
std::string wamUrdf() {
  return bimanual_skills::cli::packageFile("urdf/wam.urdf");
}

struct Fixture {
  bk::ChainModel model = bk::ChainModel::fromUrdfFile(wamUrdf(), "wam_base", "wam_tool");
  KDL::Chain chain;
  std::vector<Eigen::VectorXd> q;
  std::vector<KDL::JntArray> q_kdl;

  Fixture() {
    KDL::Tree tree;
    if (!kdl_parser::treeFromFile(wamUrdf(), tree) || !tree.getChain("wam_base", "wam_tool", chain)) {
      throw std::runtime_error("KDL cannot load " + wamUrdf());
    }
    std::mt19937 rng(kSeed);
    for (int k = 0; k < kConfigurations; ++k) {
      const Eigen::VectorXd sample = bk::randomWithinLimits(model, rng);
      q.push_back(sample);
      KDL::JntArray sample_kdl(chain.getNrOfJoints());
      sample_kdl.data = sample;
      q_kdl.push_back(sample_kdl);
    }
  }
};

const Fixture& fixture() {
  static const Fixture instance;
  return instance;
}

void BM_Fk(benchmark::State& state) {
  const Fixture& f = fixture();
  bk::ChainData data(f.model);
  timeBatches(state, kConfigurations, [&](int k) {
    benchmark::DoNotOptimize(bk::forwardKinematics(f.model, data, f.q[static_cast<std::size_t>(k)]));
    benchmark::DoNotOptimize(data.tipPose().data());
  });
}

void BM_FkJacobian(benchmark::State& state) {
  const Fixture& f = fixture();
  bk::ChainData data(f.model);
  timeBatches(state, kConfigurations, [&](int k) {
    benchmark::DoNotOptimize(bk::computeJacobian(f.model, data, f.q[static_cast<std::size_t>(k)]));
    benchmark::DoNotOptimize(data.jacobian.data());
  });
}

void BM_KdlFk(benchmark::State& state) {
  const Fixture& f = fixture();
  KDL::ChainFkSolverPos_recursive fk(f.chain);
  KDL::Frame tip;
  timeBatches(state, kConfigurations, [&](int k) {
    benchmark::DoNotOptimize(fk.JntToCart(f.q_kdl[static_cast<std::size_t>(k)], tip));
    benchmark::DoNotOptimize(&tip);
  });
}

void BM_KdlJacobian(benchmark::State& state) {
  const Fixture& f = fixture();
  KDL::ChainJntToJacSolver jac(f.chain);
  KDL::Jacobian J(f.chain.getNrOfJoints());
  timeBatches(state, kConfigurations, [&](int k) {
    benchmark::DoNotOptimize(jac.JntToJac(f.q_kdl[static_cast<std::size_t>(k)], J));
    benchmark::DoNotOptimize(J.data.data());
  });
}

/// What a CLIK step needs from KDL: the tip pose and the Jacobian (JntToJac recomputes the chain internally).
void BM_KdlFkJacobian(benchmark::State& state) {
  const Fixture& f = fixture();
  KDL::ChainFkSolverPos_recursive fk(f.chain);
  KDL::ChainJntToJacSolver jac(f.chain);
  KDL::Frame tip;
  KDL::Jacobian J(f.chain.getNrOfJoints());
  timeBatches(state, kConfigurations, [&](int k) {
    benchmark::DoNotOptimize(fk.JntToCart(f.q_kdl[static_cast<std::size_t>(k)], tip));
    benchmark::DoNotOptimize(jac.JntToJac(f.q_kdl[static_cast<std::size_t>(k)], J));
    benchmark::DoNotOptimize(J.data.data());
  });
}

/// One CLIK step (FK, Jacobian, pose error and the method's Δq) from configuration k towards the pose of k + 1.
void clikStep(benchmark::State& state, bk::InverseOperator op, bk::LimitScheme scheme) {
  const Fixture& f = fixture();
  bk::ClikParameters parameters;
  parameters.inverse = op;
  parameters.limits = scheme;
  bk::ClikData data(f.model, parameters);
  bk::ChainData kinematics(f.model);
  std::vector<Eigen::Isometry3d> targets;
  for (const auto& q : f.q) {
    if (bk::forwardKinematics(f.model, kinematics, q) != bk::KinematicsStatus::Success) state.SkipWithError("FK");
    targets.push_back(kinematics.tipPose());
  }
  timeBatches(state, kConfigurations, [&](int k) {
    const auto next = static_cast<std::size_t>((k + 1) % kConfigurations);
    benchmark::DoNotOptimize(bk::step(f.model, parameters, data, f.q[static_cast<std::size_t>(k)], targets[next]));
    benchmark::DoNotOptimize(data.dq.data());
  });
}

void BM_ClikStepJp(benchmark::State& state) {
  clikStep(state, bk::InverseOperator::Pseudoinverse, bk::LimitScheme::None);
}
void BM_ClikStepEd(benchmark::State& state) {
  clikStep(state, bk::InverseOperator::ErrorDamping, bk::LimitScheme::None);
}
void BM_ClikStepCtpSdSvf(benchmark::State& state) {
  clikStep(state, bk::InverseOperator::SvfSelectiveDamping, bk::LimitScheme::ContinuousTaskPriority);
}

}  // namespace

BENCHMARK(BM_Fk);
BENCHMARK(BM_KdlFk);
BENCHMARK(BM_FkJacobian);
BENCHMARK(BM_KdlJacobian);
BENCHMARK(BM_KdlFkJacobian);
BENCHMARK(BM_ClikStepJp);
BENCHMARK(BM_ClikStepEd);
BENCHMARK(BM_ClikStepCtpSdSvf);

int main(int argc, char** argv) {
  bimanual_skills::bench::initialiseBenchmarks(
      argc, argv, "kinematics_bench",
      "Forward kinematics, Jacobians and CLIK steps of the WAM per call, against KDL in the same run.");
  benchmark::AddCustomContext("seed", std::to_string(kSeed));
  benchmark::AddCustomContext("model", wamUrdf() + " (wam_base -> wam_tool)");
  benchmark::AddCustomContext("batch", std::to_string(kBatch));
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
