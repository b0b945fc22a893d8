// Dynamics and the control cycle for one WAM per call: the core library's RNEA and mass matrix and KDL's in the same
// run, and a whole controller + observer cycle. When built with Pinocchio (BIMANUAL_SKILLS_WITH_PINOCCHIO: the
// headers that scripts/fetch_pinocchio.sh unpacks under build/peers/; Pinocchio is not a Debian package), also
// Pinocchio's CRBA, compiled from its headers with this project's flags on the same chain, after checking that both
// mass matrices agree to 1e-9 on every state.
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
#include "cli/package_share.hpp"

#include <benchmark/benchmark.h>
#include <kdl/chaindynparam.hpp>
#include <kdl/chainidsolver_recursive_newton_euler.hpp>
#include <kdl_parser/kdl_parser.hpp>
#ifdef BIMANUAL_SKILLS_WITH_PINOCCHIO
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/multibody.hpp>
#endif

#include <sched.h>
#include <sys/mman.h>

#include <cmath>
#include <cstdio>
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
/// The WAM of urdf/wam.urdf.
std::string wamUrdf() {
  return bimanual_skills::cli::packageFile("urdf/wam.urdf");
}

struct Fixture {
  bk::ChainModel model = bk::ChainModel::fromUrdfFile(wamUrdf(), "wam_base", "wam_tool");
  KDL::Chain chain;
  std::vector<Eigen::VectorXd> q, qd, qdd;
  std::vector<KDL::JntArray> q_kdl, qd_kdl, qdd_kdl;

  Fixture() {
    KDL::Tree tree;
    if (!kdl_parser::treeFromFile(wamUrdf(), tree) || !tree.getChain("wam_base", "wam_tool", chain)) {
      throw std::runtime_error("KDL cannot load " + wamUrdf());
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

#ifdef BIMANUAL_SKILLS_WITH_PINOCCHIO
/// The same chain as a Pinocchio model: each joint at its origin in the previous link, revolute about its axis,
/// carrying its link's inertia, with its rotor inertia as armature.
pinocchio::Model pinocchioModel(const bk::ChainModel& chain) {
  pinocchio::Model model;
  pinocchio::JointIndex parent = 0;
  for (const bk::ChainJoint& joint : chain.joints()) {
    if (joint.type != bk::JointType::Revolute) throw std::runtime_error("control_bench: revolute joints only");
    const pinocchio::SE3 placement(joint.origin.rotation(), joint.origin.translation());
    const Eigen::Vector3d axis = joint.axis.normalized();
    parent = axis.isApprox(Eigen::Vector3d::UnitZ())
                 ? model.addJoint(parent, pinocchio::JointModelRZ(), placement, joint.name)
                 : model.addJoint(parent, pinocchio::JointModelRevoluteUnaligned(axis), placement, joint.name);
    model.appendBodyToJoint(parent, pinocchio::Inertia(joint.body.mass, joint.body.com, joint.body.inertia),
                            pinocchio::SE3::Identity());
  }
  model.armature = chain.rotorInertia();
  return model;
}

const pinocchio::Model& pinocchioWam() {
  static const pinocchio::Model model = pinocchioModel(fixture().model);
  return model;
}

/// The largest difference between Pinocchio's mass matrix and ours over the fixture's states.
double pinocchioDifference() {
  const Fixture& f = fixture();
  bd::DynamicsData ours(f.model);
  pinocchio::Data theirs(pinocchioWam());
  double worst = 0.0;
  for (const Eigen::VectorXd& q : f.q) {
    if (bd::massMatrix(f.model, ours, q) != bd::DynamicsStatus::Success) return INFINITY;
    pinocchio::crba(pinocchioWam(), theirs, q);
    const Eigen::MatrixXd full = theirs.M.selfadjointView<Eigen::Upper>();
    worst = std::max(worst, (full - ours.mass_matrix).cwiseAbs().maxCoeff());
  }
  return worst;
}

/// Pinocchio's CRBA (its default, local convention) fills the upper triangle of M; ours fills all of it.
void BM_PinocchioCrba(benchmark::State& state) {
  const Fixture& f = fixture();
  pinocchio::Data data(pinocchioWam());
  timeBatches(state, kStates, [&](int k) {
    benchmark::DoNotOptimize(pinocchio::crba(pinocchioWam(), data, f.q[static_cast<std::size_t>(k)]).data());
  });
}
#endif

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
#ifdef BIMANUAL_SKILLS_WITH_PINOCCHIO
BENCHMARK(BM_PinocchioCrba);
#endif
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
  benchmark::AddCustomContext("model", wamUrdf() + " (wam_base -> wam_tool)");
  benchmark::AddCustomContext("scheduling", scheduling);
#ifdef BIMANUAL_SKILLS_WITH_PINOCCHIO
  const double difference = pinocchioDifference();
  std::fprintf(stderr, "control_bench: Pinocchio %s, max |M_ours - M_pinocchio| over %d states: %.3g\n",
               PINOCCHIO_VERSION, kStates, difference);
  if (!(difference <= 1e-9)) {
    std::fprintf(stderr, "control_bench: the mass matrices differ by more than 1e-9\n");
    return 1;
  }
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", difference);
  benchmark::AddCustomContext("pinocchio", PINOCCHIO_VERSION);
  benchmark::AddCustomContext("max_mass_matrix_difference_to_pinocchio", text);
#endif
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
