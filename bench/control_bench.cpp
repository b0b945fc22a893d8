// Dynamics for one WAM per call: the core library's RNEA and mass matrix and KDL's in the same run.
//
//   control_bench [--benchmark_format=json] [--benchmark_repetitions=N] ...
//
// Counters median_ns, p99_ns, p999_ns and max_ns are per call (batches of 8 timed with a steady clock); the
// configurations, velocities and accelerations are seeded random states within the joint limits.
#include "bench_timing.hpp"
#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"

#include <benchmark/benchmark.h>
#include <kdl/chaindynparam.hpp>
#include <kdl/chainidsolver_recursive_newton_euler.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include <random>
#include <string>
#include <vector>

namespace bd = bimanual_skills::dynamics;
namespace bk = bimanual_skills::kinematics;
using bimanual_skills::bench::timeBatches;

namespace {

constexpr unsigned kSeed = 42;
constexpr int kStates = 1024;
const std::string kWamUrdf = BIMANUAL_SKILLS_SOURCE_DIR "/urdf/wam.urdf";

struct Fixture {
  bk::ChainModel model = bk::ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  KDL::Chain chain;
  std::vector<Eigen::VectorXd> q, qd, qdd;
  std::vector<KDL::JntArray> q_kdl, qd_kdl, qdd_kdl;

  Fixture() {
    KDL::Tree tree;
    if (!kdl_parser::treeFromFile(kWamUrdf, tree) || !tree.getChain("wam_base", "wam_tool", chain)) {
      throw std::runtime_error("KDL cannot load " + kWamUrdf);
    }
    std::mt19937 rng(kSeed);
    std::uniform_real_distribution<double> rate(-2.0, 2.0);
    for (int k = 0; k < kStates; ++k) {
      Eigen::VectorXd a(7), b(7), c(7);
      for (int i = 0; i < 7; ++i) {
        a[i] = std::uniform_real_distribution<double>(model.lowerLimits()[i], model.upperLimits()[i])(rng);
        b[i] = rate(rng);
        c[i] = rate(rng);
      }
      q.push_back(a);
      qd.push_back(b);
      qdd.push_back(c);
      KDL::JntArray ka(7), kb(7), kc(7);
      ka.data = a;
      kb.data = b;
      kc.data = c;
      q_kdl.push_back(ka);
      qd_kdl.push_back(kb);
      qdd_kdl.push_back(kc);
    }
  }
};

const Fixture& fixture() {
  static const Fixture instance;
  return instance;
}

void BM_Rnea(benchmark::State& state) {
  const Fixture& f = fixture();
  bd::DynamicsData data(f.model);
  Eigen::VectorXd tau(7);
  timeBatches(state, kStates, [&](int k) {
    const auto i = static_cast<std::size_t>(k);
    benchmark::DoNotOptimize(bd::inverseDynamics(f.model, data, f.q[i], f.qd[i], f.qdd[i], tau));
    benchmark::DoNotOptimize(tau.data());
  });
}

void BM_KdlRnea(benchmark::State& state) {
  const Fixture& f = fixture();
  KDL::ChainIdSolver_RNE rne(f.chain, KDL::Vector(0, 0, -9.81));
  KDL::Wrenches none(f.chain.getNrOfSegments(), KDL::Wrench::Zero());
  KDL::JntArray tau(7);
  timeBatches(state, kStates, [&](int k) {
    const auto i = static_cast<std::size_t>(k);
    benchmark::DoNotOptimize(rne.CartToJnt(f.q_kdl[i], f.qd_kdl[i], f.qdd_kdl[i], none, tau));
    benchmark::DoNotOptimize(tau.data.data());
  });
}

void BM_MassMatrix(benchmark::State& state) {
  const Fixture& f = fixture();
  bd::DynamicsData data(f.model);
  timeBatches(state, kStates, [&](int k) {
    benchmark::DoNotOptimize(bd::massMatrix(f.model, data, f.q[static_cast<std::size_t>(k)]));
    benchmark::DoNotOptimize(data.mass_matrix.data());
  });
}

void BM_KdlMassMatrix(benchmark::State& state) {
  const Fixture& f = fixture();
  KDL::ChainDynParam dynparam(f.chain, KDL::Vector(0, 0, -9.81));
  KDL::JntSpaceInertiaMatrix M(7);
  timeBatches(state, kStates, [&](int k) {
    benchmark::DoNotOptimize(dynparam.JntToMass(f.q_kdl[static_cast<std::size_t>(k)], M));
    benchmark::DoNotOptimize(M.data.data());
  });
}

void BM_ForwardDynamics(benchmark::State& state) {
  const Fixture& f = fixture();
  bd::DynamicsData data(f.model);
  Eigen::VectorXd qdd(7);
  timeBatches(state, kStates, [&](int k) {
    const auto i = static_cast<std::size_t>(k);
    benchmark::DoNotOptimize(bd::forwardDynamics(f.model, data, f.q[i], f.qd[i], f.qdd[i], qdd));
    benchmark::DoNotOptimize(qdd.data());
  });
}

}  // namespace

BENCHMARK(BM_Rnea);
BENCHMARK(BM_KdlRnea);
BENCHMARK(BM_MassMatrix);
BENCHMARK(BM_KdlMassMatrix);
BENCHMARK(BM_ForwardDynamics);

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::AddCustomContext("seed", std::to_string(kSeed));
  benchmark::AddCustomContext("model", kWamUrdf + " (wam_base -> wam_tool)");
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
