// sim_benchmark --experiment payload: thesis Fig. 4.2 on the simulated plant. The left WAM carries 0, 0.5, 1, 1.5
// and 2 kg at its tool (a point mass at the tool origin, unknown to the controller and the observers) along a 10 s
// trajectory, then holds still for 2 s. The computed-torque controller (low gains, identified advanced friction)
// tracks; in the same run our disturbance observer (thesis 4.15) and KDL's ChainExternalWrenchEstimator (momentum
// observer) estimate the tool wrench. The vertical force is compared with the true weight:
//   steady-state error: mean estimate over the motion away from the start and the reversal, t ∈ [1, 4.5] ∪ [7, 9.5];
//   transient peaks: largest error around the reversal of joint 1 (t ∈ [4.5, 7]) and the stop (t ∈ [10, 11]);
//   at rest: mean estimate over t ∈ [11, 12], where the joints stick (static friction holds part of the load).
// Figs. 4.3 and 4.4: our observer's estimates against the simulation's truth, per joint for the 1 kg load
// (payload_joints.csv: τ_ext = −(RNEA with the load − RNEA without) at the true state and acceleration) and as the
// full wrench for 0.5 kg (payload_wrench.csv: the point mass's force m (g − a_tool) at the tool origin, a_tool by
// central differences of the true tool positions, and no moment).
// The observer on a learned dynamics model (thesis Sec. 2.3.1): locally weighted regression of n = u − M(q) q̈_d on
// [q; q̇], trained on two unloaded runs of the same trajectory (the arm's own logs), estimates the loads beside the
// rigid-body observer in the same runs ("ours_learned").
#include "bimanual_skills/control/disturbance_observer.hpp"
#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/learning/locally_weighted_regression.hpp"
#include "sim_experiments.hpp"

#include <kdl/chainexternalwrenchestimator.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <vector>

namespace bimanual_skills::bench::sim_experiments {
namespace {

constexpr double kGravity = 9.81;
constexpr double kMotionEnd = 10.0, kRunEnd = 12.0;

/// The trajectory of Fig. 4.2: joint 1 sweeps 1.2 rad out with a minimum-jerk profile in 5 s and comes back with a
/// half cosine in the next 5 s, so at t = 5 s it reverses with a step in the desired acceleration (and at 10 s it
/// stops with one); joints 2 and 4 rise and return by 0.15 rad over the 10 s; the others hold.
void payloadTrajectory(double t, Eigen::VectorXd& q, Eigen::VectorXd& qd, Eigen::VectorXd& qdd) {
  q << -0.6, 0.6, 0.0, 1.7, 0.0, 0.6, 0.0;
  qd.setZero();
  qdd.setZero();
  if (t <= 0.0 || t >= kMotionEnd) return;
  const double A = 1.2, half = 5.0;
  if (t < half) {
    const double s = t / half;
    q[0] += A * (10 * s * s * s - 15 * s * s * s * s + 6 * s * s * s * s * s);
    qd[0] = A / half * (30 * s * s - 60 * s * s * s + 30 * s * s * s * s);
    qdd[0] = A / (half * half) * (60 * s - 180 * s * s + 120 * s * s * s);
  } else {
    const double w = M_PI / half, x = w * (t - half);
    q[0] += 0.5 * A * (1.0 + std::cos(x));
    qd[0] = -0.5 * A * w * std::sin(x);
    qdd[0] = -0.5 * A * w * w * std::cos(x);
  }
  const double w = 2.0 * M_PI / kMotionEnd, x = w * t;
  for (const auto& [joint, amplitude] : {std::pair{1, 0.15}, std::pair{3, -0.15}}) {
    q[joint] += 0.5 * amplitude * (1.0 - std::cos(x));
    qd[joint] = 0.5 * amplitude * w * std::sin(x);
    qdd[joint] = 0.5 * amplitude * w * w * std::cos(x);
  }
}

/// Figures of one observer in one run.
struct Estimate {
  double steady_sum = 0.0, rest_sum = 0.0, reversal_peak = 0.0, stop_peak = 0.0;
  int steady_samples = 0, rest_samples = 0;

  void add(double t, double error) {
    if ((t >= 1.0 && t < 4.5) || (t >= 7.0 && t < 9.5)) {
      steady_sum += error;
      ++steady_samples;
    }
    if (t >= 11.0) {
      rest_sum += error;
      ++rest_samples;
    }
    if (t >= 4.5 && t < 7.0) reversal_peak = std::max(reversal_peak, std::abs(error));
    if (t >= kMotionEnd && t < 11.0) stop_peak = std::max(stop_peak, std::abs(error));
  }
};

/// Our observer's gains: those of test_control (K11 = 10, K12 = 0, K21 = 100, K22 = 0, Σ = 10, diagonal) with a
/// longer velocity FIR than its default: its noise, differentiated into ẋ̂2 (4.15), dominates the estimate otherwise.
control::ObserverGains observerGains() {
  control::ObserverGains gains = control::ObserverGains::diagonal(7, 10.0, 0.0, 100.0, 0.0, 10.0);
  gains.rate_hz = 1.0 / kControlPeriod;
  gains.fir_taps = 31;
  gains.fir_cutoff_hz = 15.0;
  return gains;
}

/// The learned n(q, q̇) = C q̇ + G + F_f: two unloaded runs of the payload trajectory tracked with the analytic
/// model, every control period's n = u − M(q) q̈_d at the measured state learned (thesis Sec. 2.3.1).
std::unique_ptr<learning::LocallyWeightedRegression> learnDynamics(const sim::SimConfig& config,
                                                                   const dynamics::FrictionModel& friction) {
  learning::LwrParameters parameters;
  parameters.width =
      (Eigen::VectorXd(14) << Eigen::VectorXd::Constant(7, 0.1), Eigen::VectorXd::Constant(7, 0.15)).finished();
  parameters.max_fields = 2000;
  auto lwr = std::make_unique<learning::LocallyWeightedRegression>(14, 7, parameters);
  for (int pass = 0; pass < 2; ++pass) {
    sim::SimConfig run = config;
    run.seed = config.seed + 100u + static_cast<std::uint32_t>(pass);  // other sensor noise than the test runs
    sim::BimanualSimulation simulation(run);
    const kinematics::ChainModel model = controllerModel(simulation);
    const kinematics::ChainModel inertial = model.withGravity(Eigen::Vector3d::Zero());
    dynamics::DynamicsData data(inertial);
    control::ComputedTorqueController controller(model, friction, lowGains(config));
    Eigen::VectorXd q(7), qd(7), qdd(7), u(7), inertia(7), x(14);
    sim::JointState state(7);
    payloadTrajectory(0.0, q, qd, qdd);
    if (simulation.reset({{q, Eigen::VectorXd::Zero(7)}}) != sim::SimStatus::Ok) {
      throw std::runtime_error("payload: start outside the limits");
    }
    const int substeps = static_cast<int>(std::lround(kControlPeriod / simulation.stepSize()));
    for (int k = 0; k < static_cast<int>(std::lround(kRunEnd / kControlPeriod)); ++k) {
      payloadTrajectory(k * kControlPeriod, q, qd, qdd);
      if (simulation.readJointState(0, state) != sim::RobotStatus::Ok ||
          controller.update(state.position, state.velocity, q, qd, qdd, u) == control::ControlStatus::InvalidInput ||
          simulation.writeJointTorques(0, u) != sim::RobotStatus::Ok ||
          dynamics::inverseDynamics(inertial, data, state.position, Eigen::VectorXd::Zero(7), qdd, inertia) !=
              dynamics::DynamicsStatus::Success) {
        throw std::runtime_error("payload: the learning run failed");
      }
      x << state.position, state.velocity;
      if (lwr->update(x, u - inertia) != learning::LwrStatus::Success) {
        throw std::runtime_error("payload: the learned model rejected a sample");
      }
      for (int s = 0; s < substeps; ++s) {
        if (simulation.step() != sim::SimStatus::Ok) throw std::runtime_error("payload: simulation diverged");
      }
    }
  }
  std::printf("sim_benchmark: payload: learned dynamics from 2 unloaded runs, %d receptive fields\n", lwr->fields());
  return lwr;
}

KDL::Chain kdlChain(const sim::SimConfig& config) {
  KDL::Tree tree;
  KDL::Chain chain;
  if (!kdl_parser::treeFromFile(config.urdf_path, tree) ||
      !tree.getChain(config.arms[0].base_link, config.arms[0].tip_link, chain)) {
    throw std::runtime_error("payload: KDL cannot load " + config.urdf_path);
  }
  return chain;
}

}  // namespace

void payload(const ExperimentOptions& options, Rows& rows) {
  if (!robotFile().empty()) {
    throw std::invalid_argument(
        "payload reproduces Fig. 4.2 on the WAM (its postures and load path): --robot is for "
        "the speed, fold_rollout and friction experiments");
  }
  const dynamics::FrictionModel friction = advancedFriction(options);
  const sim::SimConfig config = oneArmConfig(options);
  const KDL::Chain chain = kdlChain(config);  // must outlive the estimators: KDL's solvers keep a reference
  const std::unique_ptr<learning::LocallyWeightedRegression> learned = learnDynamics(config, friction);
  std::ofstream csv(options.out + "/payload.csv");
  csv << "load_kg,t,true_weight_n,ours_n,kdl_n,ours_learned_n\n";
  std::ofstream summary_csv(options.out + "/payload_summary.csv");
  summary_csv << "observer,load_kg,true_weight_n,steady_estimate_n,steady_error_n,steady_error_pct,reversal_peak_n,"
                 "stop_peak_n,transient_peak_n,rest_error_n,rest_error_pct\n";
  std::ofstream joints_csv(options.out + "/payload_joints.csv");
  joints_csv << "load_kg,t,joint,estimated_nm,true_nm\n";
  std::ofstream wrench_csv(options.out + "/payload_wrench.csv");
  wrench_csv << "load_kg,t,fx_est,fy_est,fz_est,mx_est,my_est,mz_est,fx_true,fy_true,fz_true,mx_true,my_true,"
                "mz_true\n";
  const double loads[] = {0.0, 0.5, 1.0, 1.5, 2.0};
  for (const double load : loads) {
    sim::BimanualSimulation simulation(config);
    if (simulation.setPayload(0, dynamics::Payload{load, Eigen::Vector3d::Zero()}) != sim::SimStatus::Ok) {
      throw std::runtime_error("payload: cannot set the load");
    }
    const kinematics::ChainModel model = controllerModel(simulation);
    control::ComputedTorqueController controller(model, friction, lowGains(config));
    control::DisturbanceObserver observer(model, friction, observerGains());
    control::DisturbanceObserver learned_observer(model, friction, observerGains());
    learned_observer.setLearnedModel(control::LearnedDynamics(*learned));
    const Eigen::Vector3d gravity = model.gravity();
    const Eigen::Vector3d up = -gravity.normalized();  // the base frame's vertical
    KDL::ChainExternalWrenchEstimator kdl(chain, KDL::Vector(gravity.x(), gravity.y(), gravity.z()),
                                          1.0 / kControlPeriod, 30.0, 0.5);
    dynamics::FrictionState kdl_friction_state(friction);
    kinematics::ChainData kinematics(model);
    KDL::JntArray kdl_q(7), kdl_qd(7), kdl_tau(7);
    KDL::Wrench kdl_wrench;
    sim::JointState state(7);
    Eigen::VectorXd q(7), qd(7), qdd(7), u(7), sign(7), model_friction(7);
    payloadTrajectory(0.0, q, qd, qdd);
    if (simulation.reset({{q, Eigen::VectorXd::Zero(7)}}) != sim::SimStatus::Ok) {
      throw std::runtime_error("payload: start outside the limits");
    }
    const int substeps = static_cast<int>(std::lround(kControlPeriod / simulation.stepSize()));
    const int steps = static_cast<int>(std::lround(kRunEnd / kControlPeriod));
    const double weight = load * kGravity;
    Estimate ours, theirs, ours_learned;
    // The truth of Figs. 4.3 (1 kg) and 4.4 (0.5 kg).
    const dynamics::Payload carried{load, Eigen::Vector3d::Zero()};
    const kinematics::ChainModel& plant = simulation.armModel(0);  // the simulation's own rigid bodies
    dynamics::DynamicsData dynamics_data(plant);
    kinematics::ChainData true_kinematics(plant);
    Eigen::VectorXd with_load(7), without_load(7);
    std::vector<Eigen::Vector3d> tool_positions;
    std::vector<Eigen::Matrix<double, 6, 1>> estimated_wrenches;
    double torque_squares[7] = {0, 0, 0, 0, 0, 0, 0};
    int torque_samples = 0;
    for (int k = 0; k < steps; ++k) {
      const double t = k * kControlPeriod;
      payloadTrajectory(t, q, qd, qdd);
      for (int j = 0; j < 7; ++j) sign[j] = (qdd[j] > 0.0) - (qdd[j] < 0.0);
      if (simulation.readJointState(0, state) != sim::RobotStatus::Ok ||
          controller.update(state.position, state.velocity, q, qd, qdd, u) == control::ControlStatus::InvalidInput ||
          simulation.writeJointTorques(0, u) != sim::RobotStatus::Ok) {
        throw std::runtime_error("payload: control failed");
      }
      if (k == 0) observer.reset(state.position, state.velocity);
      if (k == 0) learned_observer.reset(state.position, state.velocity);
      if (observer.update(state.position, state.velocity, u, sign) != control::ObserverStatus::Success ||
          learned_observer.update(state.position, state.velocity, u, sign) != control::ObserverStatus::Success) {
        throw std::runtime_error("payload: observer update failed");
      }
      // KDL's momentum observer models neither friction nor rotor inertia: it is given u − F̂_f − J_m q̈_d.
      if (dynamics::frictionTorques(friction, kdl_friction_state, state.position, qd, sign, model_friction) !=
              dynamics::DynamicsStatus::Success ||
          kinematics::forwardKinematics(model, kinematics, state.position) != kinematics::KinematicsStatus::Success) {
        throw std::runtime_error("payload: model evaluation failed");
      }
      kdl_q.data = state.position;
      kdl_qd.data = state.velocity;
      kdl_tau.data = u - model_friction - model.rotorInertia().cwiseProduct(qdd);
      if (k == 0 && kdl.setInitialMomentum(kdl_q, kdl_qd) < 0) throw std::runtime_error("payload: KDL start failed");
      if (kdl.JntToExtWrench(kdl_q, kdl_qd, kdl_tau, kdl_wrench) < 0) throw std::runtime_error("payload: KDL failed");
      // Both give the wrench the load exerts on the tool; KDL's in the tip frame. Weight = −vertical force.
      const Eigen::Vector3d kdl_force(kdl_wrench.force.x(), kdl_wrench.force.y(), kdl_wrench.force.z());
      const double ours_weight = -up.dot(observer.wrench().head<3>());
      const double kdl_weight = -up.dot(kinematics.tipPose().linear() * kdl_force);
      const double learned_weight = -up.dot(learned_observer.wrench().head<3>());
      ours.add(t, ours_weight - weight);
      theirs.add(t, kdl_weight - weight);
      ours_learned.add(t, learned_weight - weight);
      csv << load << ',' << t << ',' << weight << ',' << ours_weight << ',' << kdl_weight << ',' << learned_weight
          << '\n';
      const sim::ArmState& truth = simulation.trueState(0);
      if (load == 1.0 && k > 0) {
        // The load's torques at the true state and the acceleration of the last step.
        const Eigen::VectorXd& accel = simulation.lastAcceleration(0);
        if (dynamics::inverseDynamics(plant, dynamics_data, truth.q, truth.qd, accel, with_load, carried) !=
                dynamics::DynamicsStatus::Success ||
            dynamics::inverseDynamics(plant, dynamics_data, truth.q, truth.qd, accel, without_load) !=
                dynamics::DynamicsStatus::Success) {
          throw std::runtime_error("payload: the true load's torques failed");
        }
        for (int j = 0; j < 7; ++j) {
          const double true_torque = without_load[j] - with_load[j];
          joints_csv << load << ',' << t << ',' << j + 1 << ',' << observer.externalTorque()[j] << ',' << true_torque
                     << '\n';
          if (t >= 1.0 && t < kMotionEnd) {
            torque_squares[j] += std::pow(observer.externalTorque()[j] - true_torque, 2);
            if (j == 0) ++torque_samples;
          }
        }
      }
      if (load == 0.5) {
        if (kinematics::forwardKinematics(plant, true_kinematics, truth.q) != kinematics::KinematicsStatus::Success) {
          throw std::runtime_error("payload: the true tool pose failed");
        }
        tool_positions.push_back(true_kinematics.tipPose().translation());
        estimated_wrenches.push_back(observer.wrench());
      }
      for (int s = 0; s < substeps; ++s) {
        if (simulation.step() != sim::SimStatus::Ok) throw std::runtime_error("payload: simulation diverged");
      }
    }
    csv.flush();
    if (load == 1.0) {
      for (int j = 0; j < 7; ++j) {
        const double rms = std::sqrt(torque_squares[j] / std::max(1, torque_samples));
        rows.push_back(JsonRow()
                           .add("experiment", "payload_joints")
                           .add("load_kg", load)
                           .add("joint", j + 1)
                           .add("rms_error_nm", rms));
        std::printf("sim_benchmark: payload 1 kg, joint %d: external torque rms error %.3f N m over t in [1, 10) s\n",
                    j + 1, rms);
      }
      joints_csv.flush();
    }
    if (load == 0.5) {
      // The force of the point mass on the tool, m (g − a), a by central differences; no moment at its origin.
      double squares[6] = {0, 0, 0, 0, 0, 0};
      int samples = 0;
      for (std::size_t i = 1; i + 1 < tool_positions.size(); ++i) {
        const Eigen::Vector3d a = (tool_positions[i + 1] - 2.0 * tool_positions[i] + tool_positions[i - 1]) /
                                  (kControlPeriod * kControlPeriod);
        Eigen::Matrix<double, 6, 1> truth = Eigen::Matrix<double, 6, 1>::Zero();
        truth.head<3>() = load * (plant.gravity() - a);
        const Eigen::Matrix<double, 6, 1>& e = estimated_wrenches[i];
        const double t = static_cast<double>(i) * kControlPeriod;
        wrench_csv << load << ',' << t;
        for (int c = 0; c < 6; ++c) wrench_csv << ',' << e[c];
        for (int c = 0; c < 6; ++c) wrench_csv << ',' << truth[c];
        wrench_csv << '\n';
        if (t >= 1.0 && t < kMotionEnd) {
          for (int c = 0; c < 6; ++c) squares[c] += std::pow(e[c] - truth[c], 2);
          ++samples;
        }
      }
      const char* names[6] = {"fx", "fy", "fz", "mx", "my", "mz"};
      for (int c = 0; c < 6; ++c) {
        const double rms = std::sqrt(squares[c] / std::max(1, samples));
        rows.push_back(JsonRow()
                           .add("experiment", "payload_wrench")
                           .add("load_kg", load)
                           .add("component", names[c])
                           .add("rms_error", rms));
        std::printf("sim_benchmark: payload 0.5 kg, wrench %s: rms error %.3f %s over t in [1, 10) s\n", names[c], rms,
                    c < 3 ? "N" : "N m");
      }
      wrench_csv.flush();
    }
    // Percentages of the true weight; for the empty tool, of the smallest load's weight (0.5 kg).
    const double reference = load > 0.0 ? weight : loads[1] * kGravity;
    for (const auto& [name, e] :
         {std::pair<const char*, const Estimate&>{"ours", ours}, {"kdl", theirs}, {"ours_learned", ours_learned}}) {
      const double steady = e.steady_sum / e.steady_samples, rest = e.rest_sum / e.rest_samples;
      const double transient = std::max(e.reversal_peak, e.stop_peak);
      summary_csv << name << ',' << load << ',' << weight << ',' << weight + steady << ',' << steady << ','
                  << 100.0 * std::abs(steady) / reference << ',' << e.reversal_peak << ',' << e.stop_peak << ','
                  << transient << ',' << rest << ',' << 100.0 * std::abs(rest) / reference << '\n';
      rows.push_back(JsonRow()
                         .add("experiment", "payload")
                         .add("observer", name)
                         .add("load_kg", load)
                         .add("true_weight_n", weight)
                         .add("steady_estimate_n", weight + steady)
                         .add("steady_error_n", steady)
                         .add("steady_error_pct", 100.0 * std::abs(steady) / reference)
                         .add("transient_peak_n", transient)
                         .add("reversal_peak_n", e.reversal_peak)
                         .add("stop_peak_n", e.stop_peak)
                         .add("rest_error_n", rest)
                         .add("rest_error_pct", 100.0 * std::abs(rest) / reference));
      std::printf(
          "sim_benchmark: payload %.1f kg (%.2f N), %-4s: steady %.3f N (error %+.3f N, %.2f %%), transient peaks "
          "%.2f N at the reversal, %.2f N at the stop; at rest error %+.3f N (%.2f %%)\n",
          load, weight, name, weight + steady, steady, 100.0 * std::abs(steady) / reference, e.reversal_peak,
          e.stop_peak, rest, 100.0 * std::abs(rest) / reference);
    }
    std::fflush(stdout);
    summary_csv.flush();
  }
}

}  // namespace bimanual_skills::bench::sim_experiments
