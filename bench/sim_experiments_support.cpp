// What the Chapter 4 experiments of sim_benchmark share: the one-arm simulation, the controller's model, the
// excitation trajectories, their logging and the friction identification (see sim_experiments.hpp).
#include "bimanual_skills/control/computed_torque_controller.hpp"
#include "bimanual_skills/signal/fir_filter.hpp"
#include "cli/package_share.hpp"
#include "sim_experiments.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <stdexcept>
#include <tuple>

namespace bimanual_skills::bench::sim_experiments {
namespace {

/// Ranges of the WAM's excitation (within the thesis' joint limits, away from self-collisions): centre interval and
/// largest amplitude per joint [rad].
const Eigen::VectorXd kCentreLow = (Eigen::VectorXd(7) << -1.0, -0.4, -0.8, 0.9, -1.0, -0.3, -0.5).finished();
const Eigen::VectorXd kCentreHigh = (Eigen::VectorXd(7) << 1.0, 0.4, 0.8, 1.7, -0.2, 0.3, 0.5).finished();
const Eigen::VectorXd kAmplitude = (Eigen::VectorXd(7) << 1.1, 0.9, 1.2, 0.9, 1.2, 1.0, 1.2).finished();

/// The arm's chain as the simulation file gives it.
kinematics::ChainModel armChain(const sim::SimConfig& config) {
  const sim::ArmConfig& arm = config.arms.front();
  return kinematics::ChainModel::fromUrdfFile(config.urdf_path, arm.base_link, arm.tip_link);
}

/// Offline processing of one run's samples (rows): zero-phase low-pass, q̈ by central differences of the filtered
/// q̇, ends trimmed; appended to the log.
void appendRun(const Eigen::MatrixXd& q, const Eigen::MatrixXd& qd, const Eigen::MatrixXd& tau, double t0,
               dynamics::FrictionLog& log) {
  constexpr double kCutoffHz = 8.0, kTrim = 0.25;
  const Eigen::MatrixXd qf = signal::zeroPhaseLowPass(q, kControlPeriod, kCutoffHz);
  const Eigen::MatrixXd qdf = signal::zeroPhaseLowPass(qd, kControlPeriod, kCutoffHz);
  const Eigen::MatrixXd tauf = signal::zeroPhaseLowPass(tau, kControlPeriod, kCutoffHz);
  const int trim = static_cast<int>(std::lround(kTrim / kControlPeriod));
  const int rows = static_cast<int>(q.rows()) - 2 * trim;
  if (rows < 10) throw std::invalid_argument("excitation run too short to log");
  const int n = static_cast<int>(q.cols()), old = log.samples();
  log.t.conservativeResize(old + rows);
  for (auto* m : {&log.q, &log.qd, &log.qdd, &log.tau}) m->conservativeResize(old + rows, n);
  for (int r = 0; r < rows; ++r) {
    const int k = r + trim;
    log.t[old + r] = t0 + k * kControlPeriod;
    log.q.row(old + r) = qf.row(k);
    log.qd.row(old + r) = qdf.row(k);
    log.qdd.row(old + r) = (qdf.row(k + 1) - qdf.row(k - 1)) / (2.0 * kControlPeriod);
    log.tau.row(old + r) = tauf.row(k);
  }
}

}  // namespace

std::string& plantFile() {
  static std::string path;
  return path;
}

void usePlantFile(const std::string& path) {
  plantFile() = path;
}

std::string& armName() {
  static std::string name = "left";
  return name;
}

void useArm(const std::string& name) {
  armName() = name;
}

std::string& robotFile() {
  static std::string path;
  return path;
}

void useRobotFile(const std::string& path) {
  robotFile() = path;
}

std::string& frictionOut() {
  static std::string path;
  return path;
}

sim::SimConfig oneArmConfig(const ExperimentOptions& options) {
  sim::SimConfig config =
      sim::SimConfig::fromYamlFile(bimanual_skills::cli::packageFile("config/sim.yaml"), robotFile());
  if (!plantFile().empty()) {
    config.plant = sim::PlantModel::fromYamlFile(plantFile());
    config.plant_path = plantFile();
  }
  config.seed = options.seed;
  const auto arm =
      std::find_if(config.arms.begin(), config.arms.end(), [](const sim::ArmConfig& a) { return a.name == armName(); });
  if (arm == config.arms.end()) {
    throw std::invalid_argument("no arm called '" + armName() + "' in " +
                                (robotFile().empty() ? std::string("config/sim.yaml") : robotFile()));
  }
  config.arms = {*arm};
  config.has_table = false;
  config.has_cloth = false;
  return config;
}

kinematics::ChainModel controllerModel(const sim::BimanualSimulation& simulation) {
  // The robot's own plant file stands for the data sheet, also when --plant gives the simulation another plant (a
  // diagnosis changes the arm, not what its controllers know of it).
  const sim::SimConfig robot =
      sim::SimConfig::fromYamlFile(bimanual_skills::cli::packageFile("config/sim.yaml"), robotFile());
  const Eigen::VectorXd& rotor = robot.plant.arm(simulation.config().arms.front().name).rotor_inertia;
  const int n = simulation.armModel(0).nq();
  return simulation.armModel(0).withRotorInertia(rotor.size() == n ? rotor : Eigen::VectorXd::Zero(n));
}

control::ComputedTorqueGains lowGains(const sim::SimConfig& config) {
  if (config.kp.size() == 0) throw std::invalid_argument("the simulation names no robot file: no controller gains");
  control::ComputedTorqueGains gains;
  gains.kp = config.kp;
  gains.kv = config.kv;
  return gains;
}

control::ComputedTorqueGains loggerGains(const sim::SimConfig& config) {
  control::ComputedTorqueGains gains;
  if (robotFile().empty()) {
    gains.kp = (Eigen::VectorXd(7) << 400, 400, 200, 150, 30, 30, 6).finished();
    gains.kv = (Eigen::VectorXd(7) << 40, 40, 15, 10, 1.5, 1.5, 0.2).finished();
  } else {
    gains = lowGains(config);
    gains.kp *= 3.0;
    gains.kv *= std::sqrt(3.0);
  }
  return gains;
}

ExcitationRanges excitationRanges(const sim::SimConfig& config) {
  ExcitationRanges ranges;
  for (const sim::Drive& drive : config.plant.arm(config.arms.front().name).drives) {
    if (drive.second >= 0) ranges.pairs.emplace_back(drive.first, drive.second);
  }
  if (robotFile().empty()) {
    ranges.centre_low = kCentreLow;
    ranges.centre_high = kCentreHigh;
    ranges.amplitude = kAmplitude;
    return ranges;
  }
  const kinematics::ChainModel chain = armChain(config);
  const int n = chain.nq();
  ranges.centre_low.resize(n);
  ranges.centre_high.resize(n);
  ranges.amplitude.resize(n);
  for (int i = 0; i < n; ++i) {
    const double lower = std::max(chain.lowerLimits()[i], -M_PI), upper = std::min(chain.upperLimits()[i], M_PI);
    const double range = upper - lower, amplitude = std::min(1.2, 0.2 * range);
    ranges.amplitude[i] = amplitude;
    ranges.centre_low[i] = lower + 0.15 * range + amplitude;
    ranges.centre_high[i] = upper - 0.15 * range - amplitude;
    if (ranges.centre_low[i] > ranges.centre_high[i])
      ranges.centre_low[i] = ranges.centre_high[i] = 0.5 * (lower + upper);
  }
  return ranges;
}

void ExcitationTrajectory::evaluate(double t, Eigen::VectorXd& q, Eigen::VectorXd& qd, Eigen::VectorXd& qdd) const {
  // ρ: (1 − cos)/2 over the first and last second, 1 between; ρ', ρ'' for the derivatives.
  const double ramp = 1.0;
  double rho = 1.0, drho = 0.0, ddrho = 0.0;
  const double tc = std::clamp(t, 0.0, length);
  const double edge = std::min(tc, length - tc);
  if (edge < ramp) {
    const double s = (length - tc < tc) ? -1.0 : 1.0;  // ρ falls at the end
    rho = 0.5 * (1.0 - std::cos(M_PI * edge / ramp));
    drho = s * 0.5 * M_PI / ramp * std::sin(M_PI * edge / ramp);
    ddrho = 0.5 * (M_PI / ramp) * (M_PI / ramp) * std::cos(M_PI * edge / ramp);
  }
  for (int i = 0; i < centre.size(); ++i) {
    const double w = 2.0 * M_PI * frequency[i], x = w * tc + phase[i];
    const double sn = std::sin(x), cs = std::cos(x), a = amplitude[i];
    q[i] = centre[i] + a * rho * sn;
    qd[i] = a * (drho * sn + rho * w * cs);
    qdd[i] = a * (ddrho * sn + 2.0 * drho * w * cs - rho * w * w * sn);
  }
  if (t <= 0.0 || t >= length) {
    qd.setZero();
    qdd.setZero();
  }
}

std::vector<ExcitationTrajectory> excitationSet(std::uint32_t seed, int repeats, double length,
                                                const ExcitationRanges& ranges) {
  const int n = static_cast<int>(ranges.amplitude.size());
  std::mt19937 rng(seed);
  const auto uniform = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  std::vector<ExcitationTrajectory> set;
  const auto draw = [&](const std::string& kind, const std::vector<int>& excited) {
    ExcitationTrajectory e;
    e.kind = kind;
    e.excited = excited;
    e.length = length;
    e.centre.resize(n);
    e.amplitude.resize(n);
    e.frequency.resize(n);
    e.phase.resize(n);
    for (int i = 0; i < n; ++i) {
      const bool main = std::find(excited.begin(), excited.end(), i) != excited.end();
      e.centre[i] = uniform(ranges.centre_low[i], ranges.centre_high[i]);
      // Main joints: 0.1–0.5 Hz, peak speed up to 0.25–1.5 rad/s, amplitude up to 40–100 % of the largest;
      // the others 15–35 % of it at 0.05–0.2 Hz: slower, but not creeping (a joint crawling at a few cm/s only
      // sticks and slips, data no model of the thesis' family fits, and it would dominate the fit).
      if (main) {
        e.frequency[i] = uniform(0.1, 0.5);
        const double peak_speed = uniform(0.25, 1.5);
        e.amplitude[i] = std::min(ranges.amplitude[i] * uniform(0.4, 1.0), peak_speed / (2.0 * M_PI * e.frequency[i]));
      } else {
        e.frequency[i] = uniform(0.05, 0.2);
        e.amplitude[i] = ranges.amplitude[i] * uniform(0.15, 0.35);
      }
      e.phase[i] = uniform(0.0, 2.0 * M_PI);
    }
    set.push_back(e);
  };
  for (int r = 0; r < repeats; ++r) {
    for (int j = 0; j < n; ++j) draw("joint " + std::to_string(j + 1), {j});
    for (const auto& [a, b] : ranges.pairs) {
      draw("coupled " + std::to_string(a + 1) + "-" + std::to_string(b + 1), {a, b});
    }
    std::vector<int> all(static_cast<std::size_t>(n));
    for (int j = 0; j < n; ++j) all[static_cast<std::size_t>(j)] = j;
    draw("all", all);
  }
  return set;
}

IdentificationData logExcitation(const ExperimentOptions& options, const std::vector<ExcitationTrajectory>& training,
                                 const std::vector<ExcitationTrajectory>& validation) {
  sim::BimanualSimulation simulation(oneArmConfig(options));
  const kinematics::ChainModel model = controllerModel(simulation);
  // The logger's controller: computed torque without friction compensation, stiff gains (the data only needs the
  // applied torque; the thesis logged its data under the WAM's stiff PID).
  const control::ComputedTorqueGains gains = loggerGains(simulation.config());
  dynamics::FrictionModel no_friction;
  no_friction.joints.assign(7, dynamics::JointFriction());
  control::ComputedTorqueController controller(model, no_friction, gains);
  const int substeps = static_cast<int>(std::lround(kControlPeriod / simulation.stepSize()));
  IdentificationData data;
  data.pairs = excitationRanges(simulation.config()).pairs;
  sim::JointState state(7);
  Eigen::VectorXd q(7), qd(7), qdd(7), u(7);
  double t0 = 0.0;
  int run = 0;
  const int runs = static_cast<int>(training.size() + validation.size());
  for (const auto* set : {&training, &validation}) {
    for (const ExcitationTrajectory& e : *set) {
      e.evaluate(0.0, q, qd, qdd);
      if (simulation.reset({{q, Eigen::VectorXd::Zero(7)}}) != sim::SimStatus::Ok) {
        throw std::runtime_error("excitation '" + e.kind + "': start outside the limits");
      }
      const int steps = static_cast<int>(std::lround(e.length / kControlPeriod));
      Eigen::MatrixXd log_q(steps, 7), log_qd(steps, 7), log_tau(steps, 7);
      double worst = 0.0;
      for (int k = 0; k < steps; ++k) {
        e.evaluate(k * kControlPeriod, q, qd, qdd);
        if (simulation.readJointState(0, state) != sim::RobotStatus::Ok ||
            controller.update(state.position, state.velocity, q, qd, qdd, u) == control::ControlStatus::InvalidInput ||
            simulation.writeJointTorques(0, u) != sim::RobotStatus::Ok) {
          throw std::runtime_error("excitation '" + e.kind + "': control failed");
        }
        log_q.row(k) = state.position.transpose();
        log_qd.row(k) = state.velocity.transpose();
        log_tau.row(k) = u.transpose();
        worst = std::max(worst, (q - state.position).cwiseAbs().maxCoeff());
        for (int s = 0; s < substeps; ++s) {
          if (simulation.step() != sim::SimStatus::Ok) throw std::runtime_error("excitation: simulation diverged");
        }
      }
      data.first_sample.push_back(data.log.samples());
      appendRun(log_q, log_qd, log_tau, t0, data.log);
      t0 += e.length;
      ++run;
      std::printf("sim_benchmark: friction: logged run %2d/%d (%s, %s), %.0f s, worst tracking error %.3f rad\n", run,
                  runs, set == &training ? "training" : "validation", e.kind.c_str(), e.length, worst);
      std::fflush(stdout);
    }
    if (set == &training) data.train_end = data.log.samples();
  }
  data.first_sample.push_back(data.log.samples());
  data.friction = dynamics::observedFriction(model, data.log);
  data.signs = dynamics::accelerationSigns(data.log, dynamics::SignSource::LoggedAcceleration);
  return data;
}

dynamics::FrictionFit identifyFriction(const IdentificationData& data, dynamics::FrictionModelType type,
                                       std::uint32_t seed, bool quick) {
  dynamics::FrictionFitOptions options;
  options.type = type;
  options.pairs = data.pairs;
  options.seed = seed;
  options.holdout = 1.0 - static_cast<double>(data.train_end) / data.log.samples();
  if (quick) {
    options.restarts = 3;
    options.max_search_samples = 2000;
  }
  return dynamics::fitFriction(data.log, data.friction, data.signs, options);
}

std::vector<ExcitationTrajectory> trainingRuns(const ExperimentOptions& options) {
  return excitationSet(options.seed, options.quick ? 1 : 3, options.quick ? 4.0 : 15.0,
                       excitationRanges(oneArmConfig(options)));
}

std::vector<ExcitationTrajectory> validationRuns(const ExperimentOptions& options) {
  return excitationSet(options.seed + 7919u, options.quick ? 1 : 2, options.quick ? 4.0 : 15.0,
                       excitationRanges(oneArmConfig(options)));
}

namespace {
std::map<std::tuple<std::uint32_t, bool>, dynamics::FrictionModel>& advancedCache() {
  static std::map<std::tuple<std::uint32_t, bool>, dynamics::FrictionModel> cache;
  return cache;
}
}  // namespace

void rememberAdvancedFriction(const ExperimentOptions& options, const dynamics::FrictionModel& model) {
  advancedCache()[{options.seed, options.quick}] = model;
}

dynamics::FrictionModel advancedFriction(const ExperimentOptions& options) {
  const auto found = advancedCache().find({options.seed, options.quick});
  if (found != advancedCache().end()) return found->second;
  const IdentificationData data = logExcitation(options, trainingRuns(options), {});
  dynamics::FrictionModel model =
      identifyFriction(data, dynamics::FrictionModelType::Advanced, options.seed, options.quick).model;
  rememberAdvancedFriction(options, model);
  return model;
}

}  // namespace bimanual_skills::bench::sim_experiments
