// Experiments on the physics simulator (issue 11), as one seeded program:
//
//   sim_benchmark --experiment speed|friction|payload|fold_rollout|scarf_rollout|all --seed S --out DIR [--quick]
//
// speed: wall-clock speed of the simulation on one core (the process is pinned to CPU 0), as simulated seconds per
// wall-clock second of BimanualSimulation::step() calls, with Bullet's share of that time:
//   two_arms                   both WAMs with their true plant at 1 kHz, tracking joint sinusoids (table on);
//   two_arms_cloth             the same with the 20 x 24 self-colliding cloth of config/sim.yaml, two corners grasped
//                              and folded over onto the cloth, released, settled (no divergence allowed);
//   two_arms_cloth_step_<N>ms  the same fold with the cloth at other steps (the rate comparison behind the choice);
//   two_arms_cloth_no_self     the same fold without self-collision (its cost and what it prevents).
// Writes DIR/speed.csv (one row per setting, appended as each ends). The controllers' own time is measured apart and
// not counted in realtime_factor.
// friction: thesis Table 4.1 and friction-compensated tracking (sim_friction_experiment.cpp).
// payload: thesis Fig. 4.2, payload estimation by our observer and KDL's (sim_payload_experiment.cpp).
// fold_rollout: the real-time factor of a whole 10 s cloth-folding rollout (tasks/cloth_fold) per CLIK method.
// all: every experiment in turn. Every experiment adds its rows to DIR/summary.json; friction and payload also
// write PNG plots and DIR/tables.md (scripts/plot_sim_benchmark.py).
#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/realtime/cycle_probe.hpp"
#include "bimanual_skills/rollout/fold_learning.hpp"
#include "bimanual_skills/rollout/scarf_learning.hpp"
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "bimanual_skills/tasks/cloth_fold.hpp"
#include "bimanual_skills/tasks/scarf_task.hpp"
#include "cli/package_share.hpp"
#include "cli/pinned_numerics.hpp"
#include "experiment_cli.hpp"
#include "sim_experiments.hpp"
#include "testing/allocation_counter.hpp"

#include <sched.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace bs = bimanual_skills;
namespace sim = bimanual_skills::sim;

namespace {

using Options = bs::bench::ExperimentOptions;
using bs::realtime::Clock;
using bs::realtime::seconds;

/// One row of summary.json and speed.csv: a simulation setting.
struct Row {
  std::string setting;
  double simulated = 0.0;        ///< [s]
  double wall = 0.0;             ///< [s] in step()
  double controller_wall = 0.0;  ///< [s] in the benchmark's controllers (not in realtime_factor)
  sim::SimTimings timings;
  double cloth_step = 0.0;  ///< [s], 0 without cloth
  bool diverged = false;
  double max_stretch = 0.0;
  double max_edge_stretch = 0.0;
  double fold_on_top = -1.0;  ///< Fraction of the folded half lying on the cloth after the fold (−1: no fold).

  double realtimeFactor() const { return simulated / wall; }
  double bulletShare() const { return (timings.bullet_arms + timings.cloth.bullet) / timings.total; }
};

/// Joint PD with inverse-dynamics feed-forward (the rigid-body model only: the true plant's friction and rotor
/// inertia are unknown to it), per arm.
class JointTracker {
 public:
  explicit JointTracker(const sim::BimanualSimulation& simulation) {
    for (int arm = 0; arm < simulation.armCount(); ++arm) {
      models_.push_back(simulation.armModel(arm));
      data_.emplace_back(models_.back());
    }
    kp_ = (Eigen::VectorXd(7) << 400, 400, 200, 150, 30, 30, 6).finished();
    kd_ = (Eigen::VectorXd(7) << 40, 40, 15, 10, 1.5, 1.5, 0.2).finished();
    tau_.setZero(7);
    state_ = sim::JointState(7);
  }

  void command(sim::BimanualSimulation& simulation, int arm, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
               const Eigen::VectorXd& qdd) {
    const auto a = static_cast<std::size_t>(arm);
    if (simulation.readJointState(arm, state_) != sim::RobotStatus::Ok) return;
    if (bs::dynamics::inverseDynamics(models_[a], data_[a], state_.position, state_.velocity, qdd, tau_) !=
        bs::dynamics::DynamicsStatus::Success) {
      return;
    }
    tau_ += kp_.cwiseProduct(q - state_.position) + kd_.cwiseProduct(qd - state_.velocity);
    (void)simulation.writeJointTorques(arm, tau_);
  }

 private:
  std::vector<bs::kinematics::ChainModel> models_;
  std::vector<bs::dynamics::DynamicsData> data_;
  Eigen::VectorXd kp_, kd_, tau_;
  sim::JointState state_;
};

/// A joint trajectory through waypoints at a fixed spacing: Catmull-Rom (C¹) in time.
class WaypointTrajectory {
 public:
  WaypointTrajectory(std::vector<Eigen::VectorXd> points, double spacing) : points_(std::move(points)), h_(spacing) {}

  double duration() const { return h_ * static_cast<double>(points_.size() - 1); }

  void evaluate(double t, Eigen::VectorXd& q, Eigen::VectorXd& qd, Eigen::VectorXd& qdd) const {
    const int last = static_cast<int>(points_.size()) - 1;
    const double x = std::clamp(t / h_, 0.0, static_cast<double>(last));
    const int i = std::min(static_cast<int>(x), last - 1);
    const double s = x - i;
    const auto at = [&](int k) { return points_[static_cast<std::size_t>(std::clamp(k, 0, last))]; };
    const Eigen::VectorXd m0 = (at(i + 1) - at(i - 1)) / (i == 0 ? 1.0 : 2.0);
    const Eigen::VectorXd m1 = (at(i + 2) - at(i)) / (i + 1 == last ? 1.0 : 2.0);
    const Eigen::VectorXd p0 = at(i), p1 = at(i + 1);
    const double s2 = s * s, s3 = s2 * s;
    q = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * m1;
    qd = ((6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * m1) / h_;
    qdd = ((12 * s - 6) * p0 + (6 * s - 4) * m0 + (-12 * s + 6) * p1 + (6 * s - 2) * m1) / (h_ * h_);
    if (t <= 0.0 || t >= duration()) {
      qd.setZero();
      qdd.setZero();
    }
  }

 private:
  std::vector<Eigen::VectorXd> points_;
  double h_;
};

/// Runs `steps` steps, calling `control(k)` before each; times step() and the controller apart.
void run(sim::BimanualSimulation& simulation, int steps, const std::function<void(int)>& control, Row& row) {
  simulation.resetTimings();
  for (int k = 0; k < steps; ++k) {
    const auto start = Clock::now();
    control(k);
    const auto controlled = Clock::now();
    const sim::SimStatus status = simulation.step();
    const auto stepped = Clock::now();
    row.controller_wall += seconds(start, controlled);
    row.wall += seconds(controlled, stepped);
    if (status == sim::SimStatus::ClothDiverged || status == sim::SimStatus::ArmDiverged) row.diverged = true;
    if (simulation.hasCloth()) {
      row.max_stretch = std::max(row.max_stretch, simulation.cloth().maxStretch());
      row.max_edge_stretch = std::max(row.max_edge_stretch, simulation.cloth().maxEdgeStretch());
    }
  }
  row.simulated += steps * simulation.stepSize();
  row.timings = simulation.timings();
}

/// The simulation the speed and fold_rollout experiments run (sim_benchmark --sim FILE); empty: config/sim.yaml.
std::string g_sim_file;
/// A robot file replacing the simulation file's (sim_benchmark --robot FILE); empty: the simulation file's.
std::string g_robot_file;

std::string simFile() {
  return g_sim_file.empty() ? bimanual_skills::cli::packageFile("config/sim.yaml") : g_sim_file;
}

sim::SimConfig baseConfig(const Options& options) {
  sim::SimConfig config = sim::SimConfig::fromYamlFile(simFile(), g_robot_file);
  config.seed = options.seed;
  return config;
}

Row twoArms(const Options& options) {
  sim::SimConfig config = baseConfig(options);
  config.has_cloth = false;
  sim::BimanualSimulation simulation(config);
  // Each arm swings every joint about its start posture (the middle of its joint ranges when the simulation file
  // gives none), within its limits.
  const Eigen::VectorXd amplitude = (Eigen::VectorXd(7) << 0.4, 0.3, 0.4, 0.3, 0.5, 0.4, 0.5).finished();
  const Eigen::VectorXd frequency = (Eigen::VectorXd(7) << 0.3, 0.25, 0.35, 0.4, 0.5, 0.45, 0.6).finished();
  std::vector<sim::ArmState> start;
  std::vector<Eigen::VectorXd> amplitudes;
  for (int arm = 0; arm < 2; ++arm) {
    const bs::kinematics::ChainModel& chain = simulation.armModel(arm);
    const Eigen::VectorXd& given = config.arms[static_cast<std::size_t>(arm)].start;
    const Eigen::VectorXd centre = given.size() == chain.nq() ? given : bs::kinematics::middleOfLimits(chain);
    const Eigen::VectorXd margin =
        (centre - chain.lowerLimits()).cwiseMin(chain.upperLimits() - centre).cwiseMax(0.0) * 0.9;
    start.push_back({centre, Eigen::VectorXd::Zero(chain.nq())});
    amplitudes.push_back(amplitude.cwiseMin(margin));
  }
  if (simulation.reset(start) != sim::SimStatus::Ok) throw std::runtime_error("two_arms: reset failed");
  JointTracker tracker(simulation);
  Eigen::VectorXd q(7), qd(7), qdd(7);
  const double dt = simulation.stepSize();
  Row row;
  row.setting = "two_arms";
  const int steps = static_cast<int>(std::lround((options.quick ? 0.5 : 20.0) / dt));
  run(
      simulation, steps,
      [&](int k) {
        const double t = k * dt;
        for (int arm = 0; arm < 2; ++arm) {
          for (int j = 0; j < 7; ++j) {
            const double w = 2.0 * M_PI * frequency[j];
            // Starts at rest: amplitude ramps in with (1 − cos) so the desired motion is smooth from t = 0.
            const double a = amplitudes[static_cast<std::size_t>(arm)][j] * std::min(1.0, t);
            q[j] = start[static_cast<std::size_t>(arm)].q[j] + a * std::sin(w * t);
            qd[j] = a * w * std::cos(w * t);
            qdd[j] = -a * w * w * std::sin(w * t);
          }
          tracker.command(simulation, arm, q, qd, qdd);
        }
      },
      row);
  return row;
}

/// The fold of config/sim.yaml's cloth: tools pointing down take the two corners of the far edge (x = 0.75) over to
/// the near edge (x = 0.25) on half circles, lay them on the cloth and let go.
struct FoldPlan {
  std::vector<WaypointTrajectory> arms;  ///< Joint trajectories of the fold, per arm.
  std::vector<Eigen::VectorXd> start;
};

FoldPlan planFold(const sim::BimanualSimulation& simulation, const sim::SimConfig& config, double duration) {
  const double top = config.table.topCentre().z();
  const Eigen::Vector3d centre = config.cloth.pose.translation();
  const double radius = 0.5 * config.cloth.length - 0.01, lift = 0.025;
  const int waypoints = 31;
  FoldPlan plan;
  for (int arm = 0; arm < simulation.armCount(); ++arm) {
    // From the robot's IK seed (the middle of the joint ranges when the simulation file gives none).
    const bs::kinematics::ChainModel& chain = simulation.armModel(arm);
    const Eigen::VectorXd& ik_seed = config.arms[static_cast<std::size_t>(arm)].ik_seed;
    const Eigen::VectorXd seed = ik_seed.size() == chain.nq() ? ik_seed : bs::kinematics::middleOfLimits(chain);
    const double y = centre.y() + (simulation.basePose(arm).translation().y() > 0 ? 0.5 : -0.5) * config.cloth.width;
    bs::kinematics::GlobalIkParameters parameters;
    parameters.timeout = 0.2;
    bs::kinematics::GlobalIkSolver solver(chain, parameters);
    std::vector<Eigen::VectorXd> points;
    Eigen::VectorXd previous = seed, q(chain.nq());
    for (int w = 0; w < waypoints; ++w) {
      double s = static_cast<double>(w) / (waypoints - 1);
      s = s * s * (3.0 - 2.0 * s);
      const double angle = M_PI * s;
      Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
      // Tool z down, turning with the fold about the y axis a little (the wrist follows the arc).
      target.linear() = Eigen::AngleAxisd(M_PI - 0.4 * std::sin(angle), Eigen::Vector3d::UnitY()).toRotationMatrix();
      target.translation() =
          Eigen::Vector3d(centre.x() + radius * std::cos(angle), y, top + lift + 0.8 * radius * std::sin(angle));
      const auto result = solver.solve(simulation.basePose(arm).inverse() * target, previous, q);
      if (result.status != bs::kinematics::IkStatus::Converged) {
        throw std::runtime_error("fold: no IK solution for waypoint " + std::to_string(w));
      }
      points.push_back(q);
      previous = q;
    }
    plan.start.push_back(points.front());
    plan.arms.emplace_back(points, duration / (waypoints - 1));
  }
  return plan;
}

Row twoArmsCloth(const Options& options, const std::string& setting, double cloth_step, bool self_collision) {
  sim::SimConfig config = baseConfig(options);
  if (cloth_step > 0.0) config.cloth.step = cloth_step;
  config.cloth.self_collision = self_collision;
  sim::BimanualSimulation simulation(config);
  const double fold = options.quick ? 1.2 : 3.0, hold = 0.3, settle = options.quick ? 0.2 : 0.7;
  const FoldPlan plan = planFold(simulation, config, fold);
  std::vector<sim::ArmState> start;
  for (const Eigen::VectorXd& q : plan.start) start.push_back({q, Eigen::VectorXd::Zero(7)});
  if (simulation.reset(start) != sim::SimStatus::Ok) throw std::runtime_error(setting + ": reset failed");
  for (int arm = 0; arm < 2; ++arm) {
    int attached = 0;
    if (simulation.grasp(arm, &attached) != sim::SimStatus::Ok || attached == 0) {
      throw std::runtime_error(setting + ": arm " + std::to_string(arm) + " grasped nothing");
    }
  }
  JointTracker tracker(simulation);
  Eigen::VectorXd q(7), qd(7), qdd(7);
  const double dt = simulation.stepSize();
  Row row;
  row.setting = setting;
  row.cloth_step = config.cloth.step;
  const int steps = static_cast<int>(std::lround((hold + fold + hold + settle) / dt));
  const int release_step = static_cast<int>(std::lround((hold + fold + hold) / dt));
  run(
      simulation, steps,
      [&](int k) {
        if (k == release_step) {
          for (int arm = 0; arm < 2; ++arm) (void)simulation.release(arm);
        }
        const double t = k * dt - hold;
        for (int arm = 0; arm < 2; ++arm) {
          plan.arms[static_cast<std::size_t>(arm)].evaluate(t, q, qd, qdd);
          if (k >= release_step) {  // after the release the tools rise 5 cm/s out of the cloth
            Eigen::VectorXd up = q;
            up[1] -= 0.1 * (k - release_step) * dt;
            q = up;
          }
          tracker.command(simulation, arm, q, qd, qdd);
        }
      },
      row);
  // Fold quality: nodes of the folded half lying over the bottom half (away from crease and near edge) that lie on
  // the cloth (above the bottom layer), not at table level.
  const sim::Cloth& cloth = simulation.cloth();
  const double top = config.table.topCentre().z();
  int on_top = 0, total = 0;
  for (int i = 0; i < cloth.nodeCount(); ++i) {
    const Eigen::Vector3d rest = cloth.restVertices().col(i) - config.cloth.pose.translation();
    const Eigen::Vector3d now = cloth.vertices().col(i) - config.cloth.pose.translation();
    const double quarter = 0.25 * config.cloth.length;
    if (rest.x() < 0.2 * quarter || std::abs(rest.y()) > 0.4 * config.cloth.width || now.x() > -0.3 * quarter ||
        now.x() < -1.7 * quarter) {
      continue;
    }
    ++total;
    on_top += cloth.vertices()(2, i) >= top + 1.5 * config.cloth.thickness;
  }
  row.fold_on_top = total > 0 ? static_cast<double>(on_top) / total : 0.0;
  return row;
}

class Writer {
 public:
  explicit Writer(const Options& options) : csv_(options.out + "/speed.csv") {
    csv_ << "setting,cloth_step_s,simulated_s,wall_s,realtime_factor,bullet_share,bullet_arms_s,bullet_cloth_s,"
            "self_collision_s,plant_s,cloth_bookkeeping_s,controller_s,steps,diverged,max_stretch,max_edge_stretch,"
            "fold_on_top\n";
  }
  void add(const Row& r) {
    csv_ << r.setting << ',' << r.cloth_step << ',' << r.simulated << ',' << r.wall << ',' << r.realtimeFactor() << ','
         << r.bulletShare() << ',' << r.timings.bullet_arms << ',' << r.timings.cloth.bullet << ','
         << r.timings.cloth.self_collision << ',' << r.timings.plant << ',' << r.timings.cloth.bookkeeping << ','
         << r.controller_wall << ',' << r.timings.steps << ',' << (r.diverged ? 1 : 0) << ',' << r.max_stretch << ','
         << r.max_edge_stretch << ',' << r.fold_on_top << '\n';
    csv_.flush();
  }

 private:
  std::ofstream csv_;
};

bs::bench::JsonRow summaryRow(const Row& r) {
  bs::bench::JsonRow row;
  row.add("experiment", "speed")
      .add("setting", r.setting)
      .add("realtime_factor", r.realtimeFactor())
      .add("bullet_share", r.bulletShare())
      .add("bullet_arms_share", r.timings.bullet_arms / r.timings.total)
      .add("bullet_cloth_share", r.timings.cloth.bullet / r.timings.total)
      .add("self_collision_share", r.timings.cloth.self_collision / r.timings.total)
      .add("plant_share", r.timings.plant / r.timings.total)
      .add("simulated_s", r.simulated)
      .add("wall_s", r.wall)
      .add("controller_s", r.controller_wall)
      .add("arm_step_s", r.simulated / static_cast<double>(std::max(1L, r.timings.steps)))
      .add("cloth_step_s", r.cloth_step)
      .add("diverged", r.diverged)
      .add("max_stretch", r.max_stretch)
      .add("max_edge_stretch", r.max_edge_stretch)
      .add("fold_on_top", r.fold_on_top)
      .add("cpu", 0);
  return row;
}

void speed(const Options& options, std::vector<bs::bench::JsonRow>& rows) {
  Writer writer(options);
  const auto report = [&](const Row& r) {
    std::printf(
        "sim_benchmark: %-28s %6.2f s simulated in %6.2f s: %6.2fx real time, Bullet %4.1f %% "
        "(arms %.1f %%, cloth %.1f %%), self-collision %.1f %%, plant %.1f %%%s\n",
        r.setting.c_str(), r.simulated, r.wall, r.realtimeFactor(), 100.0 * r.bulletShare(),
        100.0 * r.timings.bullet_arms / r.timings.total, 100.0 * r.timings.cloth.bullet / r.timings.total,
        100.0 * r.timings.cloth.self_collision / r.timings.total, 100.0 * r.timings.plant / r.timings.total,
        r.diverged ? ", DIVERGED" : "");
    std::fflush(stdout);
    writer.add(r);
    rows.push_back(summaryRow(r));
  };
  report(twoArms(options));
  report(twoArmsCloth(options, "two_arms_cloth", 0.0, true));
  if (options.quick) return;
  for (const double step : {0.001, 0.002, 0.005}) {
    report(twoArmsCloth(options, "two_arms_cloth_step_" + std::to_string(static_cast<int>(step * 1000)) + "ms", step,
                        true));
  }
  report(twoArmsCloth(options, "two_arms_cloth_no_self", 0.0, false));
}

/// fold_rollout: one rollout of the cloth-folding task's demonstration (tasks/cloth_fold), 10 s of simulated time
/// (0.2 s hold, 8.5 s movement, 0.3 s hold, 1 s settle) on one core, with each CLIK method the task may use:
/// the real-time factor of the whole rollout (simulation, CLIK, controllers) and how well the references follow the
/// DMP and the arms the references.
void foldRollout(const Options& options, std::vector<bs::bench::JsonRow>& rows) {
  std::ofstream csv(options.out + "/fold_rollout.csv");
  csv << "ik_method,outcome,simulated_s,wall_s,realtime_factor,max_ik_error_m,max_tracking_error_rad,"
         "acceleration_cost,max_edge_stretch,fold_quality\n";
  for (const char* method : {"ED", "CTP+SD+SVF"}) {
    bs::tasks::ClothFoldConfig config;
    config.sim_config = simFile();
    config.robot = g_robot_file;
    config.friction_files = {"", ""};  // the rigid-body model alone (the robot file's friction models otherwise)
    config.duration = options.quick ? 3.0 : 8.5;  // quicker folds ask the WAM for more than its joint speeds
    config.settle = options.quick ? 0.2 : 1.0;
    config.ik_method = method;
    bs::tasks::ClothFoldTask task(config);
    const bs::tasks::FoldRollout r = task.run(task.demonstrationParameters());
    const double factor = r.simulated_seconds / r.wall_seconds;
    std::printf(
        "sim_benchmark: fold_rollout %-11s %s, %5.2f s simulated in %5.2f s: %5.2fx real time, IK error "
        "%.5f m, tracking error %.4f rad, max edge stretch %.3f, fold quality %.3f\n",
        method, bs::tasks::toString(r.outcome), r.simulated_seconds, r.wall_seconds, factor, r.max_ik_error,
        r.max_tracking_error, r.max_edge_stretch, r.fold.q);
    std::fflush(stdout);
    csv << method << ',' << bs::tasks::toString(r.outcome) << ',' << r.simulated_seconds << ',' << r.wall_seconds << ','
        << factor << ',' << r.max_ik_error << ',' << r.max_tracking_error << ',' << r.acceleration_cost << ','
        << r.max_edge_stretch << ',' << r.fold.q << '\n';
    csv.flush();
    bs::bench::JsonRow row;
    row.add("experiment", "fold_rollout")
        .add("setting", std::string("fold_rollout_") + method)
        .add("ik_method", method)
        .add("outcome", bs::tasks::toString(r.outcome))
        .add("realtime_factor", factor)
        .add("simulated_s", r.simulated_seconds)
        .add("wall_s", r.wall_seconds)
        .add("max_ik_error_m", r.max_ik_error)
        .add("max_tracking_error_rad", r.max_tracking_error)
        .add("acceleration_cost", r.acceleration_cost)
        .add("max_edge_stretch", r.max_edge_stretch)
        .add("fold_quality", r.fold.q)
        .add("cpu", 0);
    rows.push_back(row);
  }
}

/// scarf_rollout: in one run, interleaved, the scarf task's demonstration (config/scarf_learning.yaml) and the fold's
/// (config/fold_demo.yaml, the robot file's friction models as its learning has them), each on one core: wall time
/// per simulated second and per cloth node, the median of the repetitions, and of it the time inside the cloth's own
/// steps (sim::ClothTimings); the rest (building the simulation, two arms with their controllers and observers, the
/// scoring) per simulated second; and what the scarf's control part allocated (tasks::ScarfTask::run's probe, counting
/// every allocation of the control part of every period).
void scarfRollout(const Options& options, std::vector<bs::bench::JsonRow>& rows) {
  const bs::rollout::ScarfLearningConfig scarf_config =
      bs::rollout::ScarfLearningConfig::fromYamlFile(bs::cli::packageFile("config/scarf_learning.yaml"));
  const bs::rollout::FoldLearningConfig fold_config =
      bs::rollout::FoldLearningConfig::fromYamlFile(bs::cli::packageFile("config/fold_demo.yaml"));
  bs::tasks::ScarfTask scarf(scarf_config.task);
  bs::tasks::ClothFoldTask fold(fold_config.task);
  const int scarf_nodes = static_cast<int>(scarf.scarfTriangles().maxCoeff()) + 1;
  const int fold_nodes = fold.simConfig().cloth.nodes_x * fold.simConfig().cloth.nodes_y;
  const int repetitions = options.quick ? 1 : 5;
  // Wall µs per simulated second and node: the whole rollout, and inside the cloth's steps; and the rest of each
  // rollout, µs per simulated second.
  std::vector<double> scarf_cost, fold_cost, scarf_cloth, fold_cloth, scarf_rest, fold_rest;
  std::size_t allocations = 0;
  double scarf_simulated = 0.0, fold_simulated = 0.0;
  bs::realtime::ScopedCounterProbe<bs::testing::AllocationCounter> probe;
  for (int k = 0; k < repetitions; ++k) {
    const bs::tasks::FoldRollout f = fold.run(fold.demonstrationParameters());
    fold_simulated = f.simulated_seconds;
    fold_cost.push_back(1e6 * f.wall_seconds / f.simulated_seconds / fold_nodes);
    fold_cloth.push_back(1e6 * f.cloth_wall_seconds / f.simulated_seconds / fold_nodes);
    fold_rest.push_back(1e6 * (f.wall_seconds - f.cloth_wall_seconds) / f.simulated_seconds);
    const int d = scarf.dofs();
    const bs::tasks::ScarfRollout r = scarf.run({Eigen::MatrixXd::Identity(d, d)}, scarf.demonstrationWeights(),
                                                static_cast<std::uint32_t>(options.seed + k), &probe);
    scarf_simulated = r.simulated_seconds;
    allocations += r.control_allocations;
    scarf_cost.push_back(1e6 * r.wall_seconds / r.simulated_seconds / scarf_nodes);
    scarf_cloth.push_back(1e6 * r.cloth_wall_seconds / r.simulated_seconds / scarf_nodes);
    scarf_rest.push_back(1e6 * (r.wall_seconds - r.cloth_wall_seconds) / r.simulated_seconds);
  }
  const auto median = [](std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::ofstream csv(options.out + "/scarf_rollout.csv");
  csv << "task,cloth_nodes,simulated_s,repetitions,us_per_simulated_s_per_node_median,"
         "cloth_us_per_simulated_s_per_node_median,rest_us_per_simulated_s,control_allocations\n";
  std::printf("sim_benchmark: scarf_rollout: median of %d, interleaved; wall time per simulated second and node\n",
              repetitions);
  for (const auto& [task, nodes, simulated, cost, cloth, rest] :
       {std::make_tuple("fold", fold_nodes, fold_simulated, median(fold_cost), median(fold_cloth), median(fold_rest)),
        std::make_tuple("scarf", scarf_nodes, scarf_simulated, median(scarf_cost), median(scarf_cloth),
                        median(scarf_rest))}) {
    const bool is_scarf = std::string(task) == "scarf";
    csv << task << ',' << nodes << ',' << simulated << ',' << repetitions << ',' << cost << ',' << cloth << ',' << rest
        << ',' << (is_scarf ? std::to_string(allocations) : std::string()) << '\n';
    std::printf(
        "  %-5s %3d nodes, %4.1f s simulated: %7.2f us, of which the cloth's steps %7.2f us; the rest %6.0f us "
        "per simulated s\n",
        task, nodes, simulated, cost, cloth, rest);
    bs::bench::JsonRow row;
    row.add("experiment", "scarf_rollout")
        .add("setting", std::string("rollout_") + task)
        .add("cloth_nodes", nodes)
        .add("us_per_simulated_s_per_node", cost)
        .add("cloth_us_per_simulated_s_per_node", cloth)
        .add("rest_us_per_simulated_s", rest)
        .add("repetitions", repetitions)
        .add("control_allocations", is_scarf ? static_cast<double>(allocations) : 0.0)
        .add("cpu", 0);
    rows.push_back(row);
  }
  std::printf("  the scarf's control part allocated %zu times\n", allocations);
  std::fflush(stdout);
}

/// The experiments of this program, in the order `all` runs them.
const std::vector<std::pair<std::string, std::function<void(const Options&, std::vector<bs::bench::JsonRow>&)>>>
    kExperiments = {
        {"speed", speed},
        {"friction", bs::bench::sim_experiments::friction},
        {"payload", bs::bench::sim_experiments::payload},
        {"fold_rollout", foldRollout},
        {"scarf_rollout", scarfRollout},
};

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bs::bench::ExperimentProgram program;
  program.name = "sim_benchmark";
  program.description =
      "Experiments on the physics simulator. speed: simulated seconds per wall-clock second on one core (CPU 0) and\n"
      "Bullet's share of the time, for the two arms alone and with the folding cloth (several cloth steps); writes\n"
      "DIR/speed.csv. friction: thesis Table 4.1 (initial, basic and advanced friction models identified from\n"
      "excitation runs, errors on validation runs) and tracking RMS with no, basic and advanced compensation;\n"
      "writes DIR/friction_*.csv and the fitted models as YAML. payload: thesis Fig. 4.2, the tool's vertical force\n"
      "estimated by our observer and KDL's for 0-2 kg; writes DIR/payload*.csv. fold_rollout: one 10 s rollout of\n"
      "the cloth-folding task's demonstration with the CLIK methods ED and CTP+SD+SVF (real-time factor, reference\n"
      "and tracking errors); writes DIR/fold_rollout.csv. scarf_rollout: the scarf task's demonstration against the\n"
      "fold's in one run, wall time per simulated second and cloth node (and of it the time inside the cloth's own\n"
      "steps), and the scarf's control allocations;\n"
      "writes DIR/scarf_rollout.csv. all: every experiment. Each writes\n"
      "DIR/summary.json; friction and payload also PNG plots and tables.md. --quick: short runs (a few seconds).";
  for (const auto& [name, function] : kExperiments) program.experiments.push_back(name);
  program.experiments.push_back("all");
  std::string plant_file, arm_name = "left";
  program.extra = [&](bs::cli::CommandLine& line) {
    line.option("--plant", "FILE",
                "true plant of the friction and payload experiments (default: config/plant.yaml; for diagnosis)",
                &plant_file);
    line.option("--sim", "FILE", "simulation of the speed and fold_rollout experiments (default: config/sim.yaml)",
                &g_sim_file);
    line.option("--robot", "FILE",
                "robot file instead of the simulation file's (e.g. config/robots/offset_wrist.yaml): the arms of\n"
                "the speed and fold_rollout experiments, the arm (--arm) the friction experiment identifies",
                &g_robot_file);
    line.option("--friction-out", "FILE",
                "friction: also write the advanced model here (the friction file the robot file's arm names)",
                &bs::bench::sim_experiments::frictionOut());
    line.option("--arm", "NAME", "arm of config/sim.yaml the friction and payload experiments use (default left)",
                &arm_name);
  };
  const Options options = bs::bench::parseExperimentOptions(argc, argv, program);
  bs::bench::sim_experiments::usePlantFile(plant_file);
  bs::bench::sim_experiments::useArm(arm_name);
  bs::bench::sim_experiments::useRobotFile(g_robot_file);
  try {
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(0, &one);
    if (sched_setaffinity(0, sizeof(one), &one) != 0) std::fprintf(stderr, "sim_benchmark: could not pin to CPU 0\n");
    std::filesystem::create_directories(options.out);
    std::printf("sim_benchmark: experiment %s, seed %u%s, output %s%s%s\n", options.experiment.c_str(), options.seed,
                options.quick ? " (quick)" : "", options.out.c_str(), plant_file.empty() ? "" : ", plant ",
                plant_file.c_str());
    std::vector<bs::bench::JsonRow> rows;
    for (const auto& [name, function] : kExperiments) {
      if (name == options.experiment || options.experiment == "all") {
        function(options, rows);
        bs::bench::writeSummaryJson(options, "sim_benchmark", rows);  // complete after each experiment
      }
    }
    std::printf("sim_benchmark: wrote %s/summary.json\n", options.out.c_str());
    if (options.experiment != "speed" &&
        !bs::bench::runPlotScript("sim_benchmark", "plot_sim_benchmark.py", options.out)) {
      return 1;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sim_benchmark: %s\n", e.what());
    return 1;
  }
  return 0;
}
