// sim_benchmark --experiment friction: thesis Table 4.1 and the friction-compensated tracking of Sec. 4.2, on the
// simulated plant (whose friction is deliberately not of the models' form: stick-slip, Stribeck decay, hysteresis,
// direction-dependent ripple and cable differentials, config/plant.yaml).
//
// 1. Excitation runs (per joint, per cable pair, all joints; sim_experiments.hpp) logged from the simulator: training
//    runs, then validation runs with fresh draws.
// 2. The initial (2.13), basic (2.14) and advanced (4.16) models fitted on the training runs with fit_friction's code.
// 3. Table 4.1 per joint: MAE, MSE and maximum error of each model on the validation runs that excite the joint,
//    averaged over those runs (as the thesis averages over its validation trajectories).
// 4. Tracking: the computed-torque controller at the same low gains on every validation run with no, basic and
//    advanced friction compensation; RMS joint error per joint.
#include "bimanual_skills/control/computed_torque_controller.hpp"
#include "bimanual_skills/dynamics/friction_yaml.hpp"
#include "sim_experiments.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <stdexcept>

namespace bimanual_skills::bench::sim_experiments {
namespace {

using dynamics::FrictionModelType;

constexpr FrictionModelType kModels[] = {FrictionModelType::Initial, FrictionModelType::Basic,
                                         FrictionModelType::Advanced};

/// Table 4.1's indicators of one model and joint, averaged over the validation runs that excite the joint.
struct TableEntry {
  double mae = 0.0, mse = 0.0, max_error = 0.0;
  int runs = 0;
};

/// Squared joint errors summed over a tracking run, and the samples.
struct Tracking {
  Eigen::VectorXd squared = Eigen::VectorXd::Zero(7);
  long samples = 0;
  Eigen::VectorXd rms() const { return (squared / static_cast<double>(std::max(1L, samples))).cwiseSqrt(); }
};

/// One validation run tracked at low gains; `friction` compensated unless `compensate` is false.
void track(const ExperimentOptions& options, const ExcitationTrajectory& e, const dynamics::FrictionModel& friction,
           bool compensate, Tracking& tracking) {
  sim::BimanualSimulation simulation(oneArmConfig(options));
  control::ComputedTorqueController controller(controllerModel(simulation), friction, lowGains(simulation.config()));
  controller.setFrictionCompensation(compensate);
  const int substeps = static_cast<int>(std::lround(kControlPeriod / simulation.stepSize()));
  sim::JointState state(7);
  Eigen::VectorXd q(7), qd(7), qdd(7), u(7);
  e.evaluate(0.0, q, qd, qdd);
  if (simulation.reset({{q, Eigen::VectorXd::Zero(7)}}) != sim::SimStatus::Ok) {
    throw std::runtime_error("tracking: start outside the limits");
  }
  const int steps = static_cast<int>(std::lround(e.length / kControlPeriod));
  for (int k = 0; k < steps; ++k) {
    e.evaluate(k * kControlPeriod, q, qd, qdd);
    if (simulation.readJointState(0, state) != sim::RobotStatus::Ok ||
        controller.update(state.position, state.velocity, q, qd, qdd, u) == control::ControlStatus::InvalidInput ||
        simulation.writeJointTorques(0, u) != sim::RobotStatus::Ok) {
      throw std::runtime_error("tracking: control failed");
    }
    // The true (noise-free) error: what the arm does, not what its encoders say.
    tracking.squared += (q - simulation.trueState(0).q).cwiseAbs2();
    ++tracking.samples;
    for (int s = 0; s < substeps; ++s) {
      if (simulation.step() != sim::SimStatus::Ok) throw std::runtime_error("tracking: simulation diverged");
    }
  }
}

}  // namespace

void friction(const ExperimentOptions& options, Rows& rows) {
  const std::vector<ExcitationTrajectory> training = trainingRuns(options);
  const std::vector<ExcitationTrajectory> validation = validationRuns(options);
  const IdentificationData data = logExcitation(options, training, validation);
  const int first_validation = static_cast<int>(training.size());

  std::ofstream errors_csv(options.out + "/friction_errors.csv");
  errors_csv << "model,joint,validation_runs,mae,mse,max_error,train_mae,train_mse\n";
  std::vector<dynamics::FrictionModel> fitted;
  for (const FrictionModelType type : kModels) {
    const dynamics::FrictionFit fit = identifyFriction(data, type, options.seed, options.quick);
    fitted.push_back(fit.model);
    if (type == FrictionModelType::Advanced) rememberAdvancedFriction(options, fit.model);
    const std::string name = dynamics::toString(type);
    const std::string origin =
        "Identified by sim_benchmark --experiment friction --seed " + std::to_string(options.seed) + " --arm " +
        armName() +
        (robotFile().empty() ? " on the simulated " + armName() + " WAM"
                             : " --robot " + robotFile() + " on its simulated " + armName() + " arm");
    dynamics::saveFrictionModel(fit.model, options.out + "/friction_" + name + ".yaml", origin);
    if (type == FrictionModelType::Advanced && !frictionOut().empty()) {
      dynamics::saveFrictionModel(fit.model, frictionOut(), origin);
      std::printf("sim_benchmark: friction: wrote the advanced model to %s\n", frictionOut().c_str());
    }
    std::vector<TableEntry> table(7);
    for (std::size_t v = 0; v < validation.size(); ++v) {
      const int run = first_validation + static_cast<int>(v);
      const auto per_joint = dynamics::evaluateFriction(fit.model, data.log, data.friction, data.signs,
                                                        data.first_sample[static_cast<std::size_t>(run)],
                                                        data.first_sample[static_cast<std::size_t>(run) + 1]);
      for (const int j : validation[v].excited) {
        TableEntry& entry = table[static_cast<std::size_t>(j)];
        const dynamics::FrictionErrors& err = per_joint[static_cast<std::size_t>(j)];
        entry.mae += err.mae;
        entry.mse += err.mse;
        entry.max_error += err.max_error;
        ++entry.runs;
      }
    }
    std::printf("sim_benchmark: friction: %-8s model on validation runs, per joint MAE [N m]:", name.c_str());
    for (int j = 0; j < 7; ++j) {
      TableEntry& entry = table[static_cast<std::size_t>(j)];
      entry.mae /= entry.runs;
      entry.mse /= entry.runs;
      entry.max_error /= entry.runs;
      const auto& train = fit.train[static_cast<std::size_t>(j)];
      errors_csv << name << ',' << j + 1 << ',' << entry.runs << ',' << entry.mae << ',' << entry.mse << ','
                 << entry.max_error << ',' << train.mae << ',' << train.mse << '\n';
      rows.push_back(JsonRow()
                         .add("experiment", "friction")
                         .add("table", "4.1")
                         .add("model", name)
                         .add("joint", j + 1)
                         .add("validation_runs", entry.runs)
                         .add("mae", entry.mae)
                         .add("mse", entry.mse)
                         .add("max_error", entry.max_error)
                         .add("train_mae", train.mae));
      std::printf(" %.4f", entry.mae);
    }
    std::printf("\n");
    std::fflush(stdout);
    errors_csv.flush();
  }

  // Fig. 4.6: the three models along the first validation run of joint 1.
  {
    std::ofstream example(options.out + "/friction_example.csv");
    example << "t,q1,qd1,observed";
    for (const FrictionModelType type : kModels) example << ',' << dynamics::toString(type);
    example << '\n';
    const int first = data.first_sample[static_cast<std::size_t>(first_validation)];
    const int last = data.first_sample[static_cast<std::size_t>(first_validation) + 1];
    std::vector<dynamics::FrictionState> states;
    for (const dynamics::FrictionModel& m : fitted) states.emplace_back(m);
    Eigen::VectorXd tau(7);
    for (int r = first; r < last; ++r) {
      example << data.log.t[r] - data.log.t[first] << ',' << data.log.q(r, 0) << ',' << data.log.qd(r, 0) << ','
              << data.friction(r, 0);
      for (std::size_t m = 0; m < fitted.size(); ++m) {
        if (dynamics::frictionTorques(fitted[m], states[m], data.log.q.row(r).transpose(),
                                      data.log.qd.row(r).transpose(), data.signs.row(r).transpose(),
                                      tau) != dynamics::DynamicsStatus::Success) {
          throw std::runtime_error("friction example: evaluation failed");
        }
        example << ',' << tau[0];
      }
      example << '\n';
    }
  }

  // Tracking at low gains: none, basic, advanced compensation on every validation run.
  std::ofstream tracking_csv(options.out + "/friction_tracking.csv");
  tracking_csv << "compensation,joint,rms_rad\n";
  const std::pair<std::string, int> compensations[] = {{"none", -1}, {"basic", 1}, {"advanced", 2}};
  for (const auto& [name, model] : compensations) {
    Tracking tracking;
    for (const ExcitationTrajectory& e : validation) {
      track(options, e, fitted[static_cast<std::size_t>(std::max(model, 0))], model >= 0, tracking);
    }
    const Eigen::VectorXd rms = tracking.rms();
    std::printf("sim_benchmark: friction: tracking with %-8s compensation, RMS error per joint [mrad]:", name.c_str());
    for (int j = 0; j < 7; ++j) {
      tracking_csv << name << ',' << j + 1 << ',' << rms[j] << '\n';
      std::printf(" %.2f", 1000.0 * rms[j]);
    }
    std::printf(" (mean %.2f)\n", 1000.0 * rms.mean());
    std::fflush(stdout);
    tracking_csv.flush();
    JsonRow row;
    row.add("experiment", "friction").add("table", "tracking").add("compensation", name);
    for (int j = 0; j < 7; ++j) row.add("rms_rad_joint" + std::to_string(j + 1), rms[j]);
    row.add("rms_rad_mean", rms.mean()).add("validation_runs", static_cast<int>(validation.size()));
    rows.push_back(row);
  }
}

}  // namespace bimanual_skills::bench::sim_experiments
