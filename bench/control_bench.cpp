// Dynamics and the control cycle for one WAM per call: the core library's RNEA and mass matrix and KDL's in the same
// run, and a whole controller + observer cycle.
//
//   control_bench [--benchmark_format=json] [--benchmark_repetitions=N] ...
//
// Counters median_ns, p99_ns, p999_ns and max_ns are per call (batches of 8 timed with a steady clock); the
// configurations, velocities and accelerations are seeded random states within the joint limits.
#include "bench_timing.hpp"
#include "benchmark_main.hpp"
#include "bimanual_skills/control/computed_torque_controller.hpp"
#include "bimanual_skills/control/disturbance_observer.hpp"
#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"
#include "bimanual_skills/signal/acceleration_sign.hpp"

#include <benchmark/benchmark.h>
#include <kdl/chaindynparam.hpp>
#include <kdl/chainidsolver_recursive_newton_euler.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include <sched.h>
#include <sys/mman.h>

#include <cstring>
#include <random>
#include <string>
#include <vector>

namespace bc = bimanual_skills::control;
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

/// One 500 Hz control cycle of one WAM: the acceleration-sign filter on the measured velocity, the computed-torque
/// controller (RNEA + advanced friction with coupled pairs + PD + saturation) and the disturbance observer (FIR,
/// RNEA, friction, Jacobian and wrench), as a controller node runs them.
void BM_Cycle(benchmark::State& state) {
  const Fixture& f = fixture();
  bd::FrictionModel friction;
  for (int j = 0; j < 7; ++j) {
    bd::JointFriction joint;
    joint.type = bd::FrictionModelType::Advanced;
    joint.b = Eigen::VectorXd::Constant(13, 0.1);
    joint.s = 20.0;
    joint.z = 0.5;
    friction.joints.push_back(joint);
  }
  for (auto [a, b] : {std::pair{1, 2}, std::pair{4, 5}}) {
    friction.pairs.push_back(bd::CoupledPair{a, b, friction.joints[1], friction.joints[2], 0.05});
  }
  bc::ComputedTorqueGains gains;
  gains.kp = (Eigen::VectorXd(7) << 150, 150, 60, 60, 10, 10, 2.5).finished();
  gains.kv = (Eigen::VectorXd(7) << 15, 15, 6, 6, 0.6, 0.6, 0.15).finished();
  bc::ComputedTorqueController controller(f.model, friction, gains);
  bc::DisturbanceObserver observer(f.model, friction, bc::ObserverGains::diagonal(7, 10.0, 0.0, 100.0, 0.0, 10.0));
  bimanual_skills::signal::AccelerationSign sign(7, 0.002);
  Eigen::VectorXd u(7);
  timeBatches(
      state, kStates,
      [&](int k) {
        const auto i = static_cast<std::size_t>(k);
        benchmark::DoNotOptimize(sign.update(f.qd[i]));
        benchmark::DoNotOptimize(controller.update(f.q[i], f.qd[i], f.q[i], f.qd[i], f.qdd[i], u));
        benchmark::DoNotOptimize(observer.update(f.q[i], f.qd[i], u, sign.sign()));
        benchmark::DoNotOptimize(observer.wrench().data());
      },
      1);
}

/// The machine's own jitter floor: a fixed arithmetic loop of about the cycle's duration, timed the same way. Tail
/// percentiles above this one's come from the code; up to it, from the machine (scheduling, hypervisor).
void BM_CycleJitterFloor(benchmark::State& state) {
  volatile double sink = 1.0;
  timeBatches(
      state, kStates,
      [&](int) {
        double x = sink;
        for (int i = 0; i < 1400; ++i) x = x * 0.999999 + 1e-9;
        sink = x;
      },
      1);
}

}  // namespace

BENCHMARK(BM_Rnea);
BENCHMARK(BM_KdlRnea);
BENCHMARK(BM_MassMatrix);
BENCHMARK(BM_KdlMassMatrix);
BENCHMARK(BM_ForwardDynamics);
BENCHMARK(BM_Cycle);
BENCHMARK(BM_CycleJitterFloor);

int main(int argc, char** argv) {
  const bool realtime = bimanual_skills::bench::initialiseBenchmarks(
      argc, argv, "control_bench",
      "Dynamics (RNEA, CRBA mass matrix, forward dynamics) against KDL, and the whole control cycle (controller,\n"
      "observer, acceleration sign) per call, with tail percentiles.",
      {{"--realtime",
        "run as a real-time controller would: SCHED_FIFO priority 80, memory locked (needs root or CAP_SYS_NICE)"}})[0];
  std::string scheduling = "SCHED_OTHER";
  if (realtime) {
    sched_param parameters{};
    parameters.sched_priority = 80;
    const bool fifo = sched_setscheduler(0, SCHED_FIFO, &parameters) == 0;
    const bool locked = mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
    scheduling = std::string(fifo ? "SCHED_FIFO 80" : "SCHED_FIFO refused") + (locked ? ", memory locked" : "");
  }
  benchmark::AddCustomContext("seed", std::to_string(kSeed));
  benchmark::AddCustomContext("model", kWamUrdf + " (wam_base -> wam_tool)");
  benchmark::AddCustomContext("scheduling", scheduling);
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
