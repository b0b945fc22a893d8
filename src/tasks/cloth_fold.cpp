#include "bimanual_skills/tasks/cloth_fold.hpp"

#include "bimanual_skills/control/arm_controller.hpp"
#include "bimanual_skills/dynamics/friction_yaml.hpp"
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "bimanual_skills/primitives/dmp_yaml.hpp"
#include "bimanual_skills/primitives/dr_dmp.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "bimanual_skills/tasks/in_process_control.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <random>
#include <sstream>
#include <stdexcept>

namespace bimanual_skills::tasks {

namespace {

using primitives::CartesianDmp;
using primitives::CartesianDmpState;
using primitives::Pose;

/// Samples per second of the scripted demonstration the DMPs are fitted to.
constexpr double kDemonstrationRate = 100.0;

/// The coordinated forcing terms of both arms: a 12-DoF DR-DMP whose own transformation system is not used.
/// Null, with `reason`, when the policy does not fit.
std::unique_ptr<primitives::DrDmp> makeForcing(const ClothFoldTask& task,
                                               const std::vector<Eigen::MatrixXd>& coordination,
                                               const Eigen::VectorXd& latent_weights, std::string& reason) {
  bool finite = latent_weights.allFinite();
  for (const Eigen::MatrixXd& omega : coordination) finite = finite && omega.allFinite();
  try {
    if (!finite) throw std::invalid_argument("non-finite coordination or weights");
    if (coordination.empty()) throw std::invalid_argument("no coordination matrix");
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(ClothFoldTask::kDofs);
    return std::make_unique<primitives::DrDmp>(task.forcingParameters(static_cast<int>(coordination.size())),
                                               coordination, latent_weights, zero, zero, task.config().duration);
  } catch (const std::invalid_argument& e) {
    reason = std::string("the coordinated policy does not fit 12 DoF and ") + std::to_string(task.policyBasisSize()) +
             " weights per latent DoF: " + e.what();
    return nullptr;
  }
}

/// The joint references of a rollout, period by period: the two DMPs driven by the forcing terms while the
/// movement runs, followed by one CLIK step per period from the start configuration, and ∫ ‖q̈_ref‖² dt. Open loop
/// (nothing measured enters): a rollout's references are computed before it runs (ClothFoldTask::plan) and
/// tracked as one trajectory.
struct ReferenceGenerator {
  ReferenceGenerator(const std::vector<CartesianDmp>& dmps, std::unique_ptr<primitives::DrDmp> forcing,
                     const std::vector<Eigen::VectorXd>& start_q, double dt)
      : dmps(dmps),
        forcing(std::move(forcing)),
        forcing_state(this->forcing->initialState()),
        dmp_state{dmps[0].initialState(), dmps[1].initialState()},
        q_ref(start_q),
        qd_ref(2, Eigen::VectorXd::Zero(start_q.front().size())),
        qdd_ref(qd_ref),
        q_next(q_ref),
        qd_next(qd_ref),
        dt(dt) {}

  /// The forcing terms' period (only while the movement runs); false when they are not finite.
  bool stepForcing(bool moving) {
    return !moving || forcing->step(forcing_state, dt) == primitives::DmpStatus::Success;
  }

  /// Arm `arm`'s period: its DMP (while moving), then one CLIK step towards the DMP's pose in the arm's base frame
  /// `base`. Ok, or the outcome and `reason` of a failure.
  FoldOutcome stepArm(int arm, bool moving, const kinematics::ChainModel& model, const kinematics::ClikParameters& p,
                      const Eigen::Isometry3d& base, kinematics::ClikData& clik, double max_error,
                      std::string& reason) {
    const auto a = static_cast<std::size_t>(arm);
    if (moving && dmps[a].step(dmp_state[a], dt, forcing_state.forcing.segment<6>(6 * arm)) ==
                      primitives::DmpStatus::InvalidInput) {
      reason = "the DMP of arm " + std::to_string(arm) + " produced an invalid state";
      return FoldOutcome::IkFailed;
    }
    Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
    target.translation() = dmp_state[a].position.y;
    target.linear() = dmp_state[a].orientation.toRotationMatrix();
    target = base.inverse() * target;
    if (kinematics::step(model, p, clik, q_ref[a], target) != kinematics::IkStatus::StepComputed) {
      reason = "CLIK failed on arm " + std::to_string(arm);
      return FoldOutcome::IkFailed;
    }
    const double ik_error = clik.error.head<3>().norm();
    max_ik_error = std::max(max_ik_error, ik_error);
    if (ik_error > max_error) {
      reason =
          "arm " + std::to_string(arm) + "'s references are " + std::to_string(ik_error) + " m from the DMP's pose";
      return FoldOutcome::IkFailed;
    }
    q_next[a] = q_ref[a] + clik.dq;
    qd_next[a] = (q_next[a] - q_ref[a]) / dt;
    // The references a robot would be sent stay within the URDF's limits, in every backend alike.
    for (Eigen::Index j = 0; j < q_next[a].size(); ++j) {
      const double q = q_next[a][j], v = qd_next[a][j];
      if (q >= model.lowerLimits()[j] && q <= model.upperLimits()[j] && std::abs(v) <= model.velocityLimits()[j]) {
        continue;
      }
      std::ostringstream why;
      why << "arm " << arm << "'s reference for joint " << j + 1 << " leaves its limits: ";
      if (std::abs(v) > model.velocityLimits()[j]) {
        why << "velocity " << v << " rad/s, limit " << model.velocityLimits()[j];
      } else {
        why << "position " << q << " rad, limits [" << model.lowerLimits()[j] << ", " << model.upperLimits()[j] << "]";
      }
      reason = why.str();
      return FoldOutcome::OutOfLimits;
    }
    qdd_ref[a] = (qd_next[a] - qd_ref[a]) / dt;
    acceleration_cost += qdd_ref[a].squaredNorm() * dt;
    q_ref[a] = q_next[a];
    qd_ref[a] = qd_next[a];
    return FoldOutcome::Ok;
  }

  const std::vector<CartesianDmp>& dmps;
  std::unique_ptr<primitives::DrDmp> forcing;
  primitives::DrDmpState forcing_state;
  std::array<CartesianDmpState, 2> dmp_state;
  std::vector<Eigen::VectorXd> q_ref, qd_ref, qdd_ref, q_next, qd_next;
  double dt;
  double acceleration_cost = 0.0, max_ik_error = 0.0;
};

/// Where a rollout lays the cloth: the file's pose `pose` shifted by the noise draw and turned about the cloth's own
/// vertical.
Eigen::Isometry3d noisyClothPose(const Eigen::Isometry3d& pose, const FoldNoiseDraw& draw) {
  return Eigen::Translation3d(draw.cloth_x, draw.cloth_y, 0.0) * pose *
         Eigen::AngleAxisd(draw.cloth_yaw, Eigen::Vector3d::UnitZ());
}

}  // namespace

const char* toString(FoldOutcome outcome) noexcept {
  switch (outcome) {
    case FoldOutcome::Ok:
      return "Ok";
    case FoldOutcome::InvalidPolicy:
      return "InvalidPolicy";
    case FoldOutcome::GraspFailed:
      return "GraspFailed";
    case FoldOutcome::IkFailed:
      return "IkFailed";
    case FoldOutcome::ControllerFailed:
      return "ControllerFailed";
    case FoldOutcome::SimulationDiverged:
      return "SimulationDiverged";
    case FoldOutcome::RobotFailed:
      return "RobotFailed";
    case FoldOutcome::OutOfLimits:
      return "OutOfLimits";
  }
  return "Unknown";
}

const char* toString(FoldPolicy policy) noexcept {
  return policy == FoldPolicy::Weights ? "weights" : "goals";
}

FoldPolicy foldPolicyFromString(const std::string& text, const std::string& where) {
  for (const FoldPolicy policy : {FoldPolicy::Weights, FoldPolicy::WeightsAndGoals}) {
    if (text == toString(policy)) return policy;
  }
  throw std::invalid_argument(where + ": unknown policy '" + text + "' (weights, goals)");
}

void FoldNoise::validate(const std::string& where) const {
  const auto check = [&](double sigma, double most, const char* what) {
    if (!(sigma >= 0.0 && sigma <= most)) {
      throw std::invalid_argument(where + ": the " + what + " noise must be in [0, " + std::to_string(most) + "]");
    }
  };
  check(cloth_position, 0.05, "cloth position's [m]");
  check(cloth_yaw, 0.2, "cloth yaw's [rad]");
  check(release_time, 0.2, "release time's [s]");
}

FoldNoise foldNoiseSetting(const std::string& name, const std::string& where) {
  FoldNoise noise;
  noise.setting = name;
  if (name == "robot") {
    noise.cloth_position = 0.01;
    noise.cloth_yaw = 0.035;
    noise.release_time = 0.05;
  } else if (name != "none") {
    throw std::invalid_argument(where + ": unknown noise setting '" + name + "' (none, robot)");
  }
  return noise;
}

FoldNoiseDraw drawFoldNoise(const FoldNoise& noise, std::uint32_t seed) {
  FoldNoiseDraw draw;
  if (!noise.any()) return draw;
  std::seed_seq sequence{seed, 0x0b07u};
  std::mt19937 rng(sequence);
  std::normal_distribution<double> normal;
  const auto cut = [&](double sigma) { return sigma * std::clamp(normal(rng), -3.0, 3.0); };
  draw.cloth_x = cut(noise.cloth_position);
  draw.cloth_y = cut(noise.cloth_position);
  draw.cloth_yaw = cut(noise.cloth_yaw);
  draw.release[0] = cut(noise.release_time);
  draw.release[1] = cut(noise.release_time);
  return draw;
}

FoldOutcome foldOutcomeFromString(const std::string& text, const std::string& where) {
  for (const FoldOutcome outcome :
       {FoldOutcome::Ok, FoldOutcome::InvalidPolicy, FoldOutcome::GraspFailed, FoldOutcome::IkFailed,
        FoldOutcome::ControllerFailed, FoldOutcome::SimulationDiverged, FoldOutcome::RobotFailed,
        FoldOutcome::OutOfLimits}) {
    if (text == toString(outcome)) return outcome;
  }
  throw std::invalid_argument(where + ": unknown outcome '" + text + "'");
}

struct ClothFoldTask::Impl {
  ClothFoldConfig config;
  sim::SimConfig sim_config;
  std::unique_ptr<sim::BimanualSimulation> simulation;
  control::ComputedTorqueGains gains;
  std::vector<dynamics::FrictionModel> friction;
  std::vector<bool> with_friction;
  std::vector<control::ArmControllerConfig> controller_configs;
  std::vector<std::unique_ptr<control::ArmController>> controllers;
  kinematics::ClikParameters clik_parameters;
  std::vector<CartesianDmp> demonstration;
  std::vector<std::vector<Pose>> demonstration_paths;
  std::vector<Eigen::VectorXd> start_q;
  Eigen::Matrix3Xd file_rest;  ///< The flat cloth at rest as the simulation file places it (world frame).

  /// A rollout in progress (run()'s and a stepped one's): its result so far, buffers and recordings, period k next.
  struct Rollout {
    FoldRollout out;
    std::chrono::steady_clock::time_point wall_start;
    int k = 0, steps = 0;
    int release[2] = {0, 0};
    int path_every = 1, cloth_every = 0;
    std::vector<sim::JointState> measured;
    Eigen::VectorXd torque;
    std::vector<kinematics::ChainData> commanded_kinematics;
    std::vector<std::vector<Eigen::Vector3d>> commanded, actual;
    std::vector<std::vector<Eigen::VectorXd>> joints;
    std::vector<double> path_times, cloth_times;
  };

  /// The periods of a rollout at step dt: the grippers open at `release` (after the holds and the movement), it
  /// ends at `steps` (after the settling).
  void periods(double dt, int& move_start, int& move_end, int& release, int& steps) const {
    move_start = static_cast<int>(std::lround(config.hold_before / dt));
    move_end = move_start + static_cast<int>(std::lround(config.duration / dt));
    release = move_end + static_cast<int>(std::lround(config.hold_after / dt));
    steps = release + static_cast<int>(std::lround(config.settle / dt));
  }

  void fail(Rollout& r, FoldOutcome outcome, const std::string& reason) const {
    r.out.outcome = outcome;
    r.out.reason = reason + " at t = " + std::to_string(simulation->time()) + " s";
  }

  /// Rollout `seed`'s start: a new simulation with its noise, the arms at the start, the grasp, new controllers with
  /// room for `capacity` waypoints, the grippers' release periods about `release`. Not Ok (GraspFailed): it ends.
  /// A new simulation and new controllers for every rollout: after reset() a simulation whose cloth was grasped
  /// differs from a new one in the last bits, which the contacts amplify (0.6 mm on the cloth after a fold), and the
  /// controllers carry state from the last rollout; new ones make rollouts repeatable bit for bit whichever worker
  /// runs them and whatever it ran before.
  void begin(Rollout& r, std::uint32_t seed, int release, int steps, int capacity) {
    sim::SimConfig rollout_config = sim_config;
    rollout_config.seed = seed;
    // The robot's noise: the cloth laid down a little elsewhere, the grippers opening a little early or late.
    r.out.noise = drawFoldNoise(config.noise, seed);
    if (config.noise.any()) rollout_config.cloth.pose = noisyClothPose(rollout_config.cloth.pose, r.out.noise);
    simulation = std::make_unique<sim::BimanualSimulation>(rollout_config);
    std::vector<sim::ArmState> start;
    for (const Eigen::VectorXd& q : start_q) start.push_back({q, Eigen::VectorXd::Zero(q.size())});
    if (simulation->reset(start) != sim::SimStatus::Ok) throw std::logic_error("cloth fold: reset rejected");
    r.steps = steps;
    for (int arm = 0; arm < 2; ++arm) {
      if (simulation->grasp(arm, &r.out.grasped_nodes[arm]) != sim::SimStatus::Ok || r.out.grasped_nodes[arm] == 0) {
        r.out.outcome = FoldOutcome::GraspFailed;
        r.out.reason = "arm " + std::to_string(arm) + " grasped no cloth node";
        return;
      }
    }
    const double dt = simulation->stepSize();
    resetControl(capacity);
    r.measured.assign(2, sim::JointState(7));
    r.torque = Eigen::VectorXd::Zero(7);
    r.commanded_kinematics.clear();
    for (int arm = 0; arm < 2; ++arm) r.commanded_kinematics.emplace_back(simulation->armModel(arm));
    r.path_every = std::max(1, static_cast<int>(std::lround(1.0 / (config.path_rate * dt))));
    r.cloth_every =
        config.cloth_rate > 0.0 ? std::max(1, static_cast<int>(std::lround(1.0 / (config.cloth_rate * dt)))) : 0;
    r.commanded.assign(2, {});
    r.actual.assign(2, {});
    r.joints.assign(2, {});
    // Each gripper opens at the planned period, moved by its noise within the hold after the movement.
    const int hold_after = static_cast<int>(std::lround(config.hold_after / dt));
    for (int arm = 0; arm < 2; ++arm) {
      r.release[arm] = std::clamp(release + static_cast<int>(std::lround(r.out.noise.release[arm] / dt)),
                                  release - hold_after + 1, steps - 1);
    }
  }

  /// Period k = r.k: the releases due, the recordings, each arm's controller update (then `after_update(arm, k,
  /// controller)`), its stop rules and torque, the simulation's step; `commanded(arm, k)` is the arm's reference
  /// recorded in the commanded path. A failure ends the rollout (r.out.outcome).
  template <class AfterUpdate, class Commanded>
  void period(Rollout& r, AfterUpdate&& after_update, Commanded&& commanded) {
    const int k = r.k++;
    for (int arm = 0; arm < 2; ++arm) {
      if (k == r.release[arm]) (void)simulation->release(arm);
    }
    if (k % r.path_every == 0) r.path_times.push_back(simulation->time());
    if (r.cloth_every > 0 && k % r.cloth_every == 0) {
      r.out.cloth_frames.push_back(simulation->cloth().vertices());
      r.cloth_times.push_back(simulation->time());
    }
    const double now = simulation->time();
    for (int arm = 0; arm < 2; ++arm) {
      const auto a = static_cast<std::size_t>(arm);
      control::ArmController& controller = *controllers[a];
      sim::JointState& state = r.measured[a];
      simulation->readJointState(arm, state);
      const control::ControllerStatus status = controller.update(now, now, state.position, state.velocity, r.torque);
      const std::string stop = controllerStopReason(status, arm, state.velocity, controller_configs[a].velocity_limit);
      if (!stop.empty()) {
        fail(r, FoldOutcome::ControllerFailed, stop);
        return;
      }
      after_update(arm, k, controller);
      const double tracking = controller.trackingError().cwiseAbs().maxCoeff();
      r.out.max_tracking_error = std::max(r.out.max_tracking_error, tracking);
      if (tracking > config.max_tracking_error) {
        fail(r, FoldOutcome::ControllerFailed,
             "arm " + std::to_string(arm) + " is " + std::to_string(tracking) + " rad off its references");
        return;
      }
      simulation->writeJointTorques(arm, r.torque);
      if (k % r.path_every == 0) {
        (void)kinematics::forwardKinematics(simulation->armModel(arm), r.commanded_kinematics[a], commanded(arm, k));
        r.commanded[a].push_back(simulation->basePose(arm) *
                                 Eigen::Vector3d(r.commanded_kinematics[a].tipPose().translation()));
        r.actual[a].push_back(simulation->toolPose(arm).translation());
        r.joints[a].push_back(state.position);
      }
    }
    const sim::SimStatus status = simulation->step();
    if (status == sim::SimStatus::ArmDiverged) fail(r, FoldOutcome::SimulationDiverged, "an arm diverged");
    if (status == sim::SimStatus::ClothDiverged) fail(r, FoldOutcome::SimulationDiverged, "the cloth diverged");
    r.out.max_edge_stretch = std::max(r.out.max_edge_stretch, simulation->cloth().maxEdgeStretch());
  }

  /// The rollout's end after its last period: its paths, the images' moment, the fold's quality, its times.
  FoldRollout finish(Rollout& r) {
    FoldRollout& out = r.out;
    if (r.measured.empty()) return std::move(out);  // it ended before its first period (no grasp)
    sim::BimanualSimulation& sim = *simulation;
    const double dt = sim.stepSize();
    // A failure may stop a period between the arms: keep the samples both arms have.
    const std::size_t samples = std::min({r.path_times.size(), r.commanded[0].size(), r.commanded[1].size()});
    r.path_times.resize(samples);
    for (int arm = 0; arm < 2; ++arm) {
      const auto a = static_cast<std::size_t>(arm);
      Eigen::Matrix3Xd c(3, static_cast<Eigen::Index>(samples)), p(3, c.cols());
      for (Eigen::Index i = 0; i < c.cols(); ++i) {
        c.col(i) = r.commanded[a][static_cast<std::size_t>(i)];
        p.col(i) = r.actual[a][static_cast<std::size_t>(i)];
      }
      out.commanded_path.push_back(c);
      out.actual_path.push_back(p);
      Eigen::MatrixXd j(7, static_cast<Eigen::Index>(r.joints[a].size()));
      for (Eigen::Index i = 0; i < j.cols(); ++i) j.col(i) = r.joints[a][static_cast<std::size_t>(i)];
      out.joint_path.push_back(j);
    }
    out.path_times =
        Eigen::Map<const Eigen::VectorXd>(r.path_times.data(), static_cast<Eigen::Index>(r.path_times.size()));
    out.cloth_times =
        Eigen::Map<const Eigen::VectorXd>(r.cloth_times.data(), static_cast<Eigen::Index>(r.cloth_times.size()));
    out.cloth_vertices = sim.cloth().vertices();
    const int image_steps = static_cast<int>(std::lround(config.image_delay / dt));
    // The images' moment: the arms hold (this simulator's arms touch the cloth only through their grippers, released
    // by now, so where a robot's arms go meanwhile does not change the cloth) and the cloth slides on.
    for (int k = 0; k < image_steps && out.outcome == FoldOutcome::Ok; ++k) {
      const double now = sim.time();
      for (int arm = 0; arm < 2 && out.outcome == FoldOutcome::Ok; ++arm) {
        const auto a = static_cast<std::size_t>(arm);
        sim::JointState& state = r.measured[a];
        sim.readJointState(arm, state);
        const control::ControllerStatus status =
            controllers[a]->update(now, now, state.position, state.velocity, r.torque);
        const std::string stop =
            controllerStopReason(status, arm, state.velocity, controller_configs[a].velocity_limit);
        if (!stop.empty()) fail(r, FoldOutcome::ControllerFailed, stop);
        sim.writeJointTorques(arm, r.torque);
      }
      const sim::SimStatus status = sim.step();
      if (status == sim::SimStatus::ArmDiverged) fail(r, FoldOutcome::SimulationDiverged, "an arm diverged");
      if (status == sim::SimStatus::ClothDiverged) fail(r, FoldOutcome::SimulationDiverged, "the cloth diverged");
    }
    if (image_steps > 0) out.cloth_image_vertices = sim.cloth().vertices();
    out.cloth_triangles = sim.cloth().triangles();
    out.cloth_rest_vertices = sim.cloth().restVertices();
    const sim::ClothParameters& cloth = sim.cloth().parameters();
    out.fold = foldQuality(out.cloth_vertices, out.cloth_rest_vertices, cloth.nodes_x, cloth.nodes_y, cloth.thickness);
    out.simulated_seconds = sim.time();
    out.wall_seconds = realtime::secondsSince(r.wall_start);
    out.cloth_wall_seconds = sim.timings().cloth.wall();
    return std::move(out);
  }

  /// The stepped rollout in progress (beginSteps() to finishSteps()): its periods so far and the references.
  struct Stepped {
    bool running = false;
    std::uint32_t seed = 0;
    int driven = 0;  ///< Periods a policy drives (up to the planned release); the settling follows in finishSteps().
    Rollout rollout;
    std::vector<Eigen::VectorXd> q, qd, qdd, q_next, qd_next;  ///< Per arm: this period's reference, the next one's.
    control::Waypoints waypoint;                               ///< One waypoint, a period ahead.
  };
  Stepped stepped;

  /// A stepped period: the next period's reference from the commanded joint velocities `velocity` (both arms), loaded
  /// as one waypoint a period ahead from this period's reference (the controller started in hold at period 0, so from
  /// period 1 on), then the period.
  FoldOutcome steppedPeriod(const Eigen::Ref<const Eigen::VectorXd>& velocity) {
    Stepped& s = stepped;
    Rollout& r = s.rollout;
    const double dt = simulation->stepSize();
    for (int arm = 0; arm < 2; ++arm) {
      const auto a = static_cast<std::size_t>(arm);
      const kinematics::ChainModel& model = simulation->armModel(arm);
      // The commanded velocity, reached at most at the stepped acceleration and slowed so that the reference can
      // stop at a position limit; a reference that would pass one ends on it.
      const double most = config.step_acceleration * dt;
      for (int j = 0; j < 7; ++j) {
        const double q = s.q[a][j], lower = model.lowerLimits()[j], upper = model.upperLimits()[j];
        double v = std::clamp(velocity[7 * arm + j], s.qd[a][j] - most, s.qd[a][j] + most);
        v = std::min(v, std::sqrt(2.0 * config.step_acceleration * std::max(0.0, upper - q)));
        v = std::max(v, -std::sqrt(2.0 * config.step_acceleration * std::max(0.0, q - lower)));
        s.q_next[a][j] = std::clamp(q + v * dt, lower, upper);
      }
      s.qd_next[a] = (s.q_next[a] - s.q[a]) / dt;
      const Eigen::VectorXd qdd_next = (s.qd_next[a] - s.qd[a]) / dt;
      r.out.acceleration_cost += qdd_next.squaredNorm() * dt;
      if (r.k >= 1) {
        s.waypoint.positions.col(0) = s.q_next[a];
        s.waypoint.velocities.col(0) = s.qd_next[a];
        s.waypoint.accelerations.col(0) = qdd_next;
        if (controllers[a]->setTrajectoryFrom(s.waypoint, s.q[a], s.qd[a], s.qdd[a]) != control::TrajectoryStatus::Ok) {
          fail(r, FoldOutcome::ControllerFailed, "arm " + std::to_string(arm) + "'s controller refused its reference");
          return r.out.outcome;
        }
      }
      s.qdd[a] = qdd_next;
    }
    period(
        r, [](int, int, control::ArmController&) {},
        [&](int arm, int) -> const Eigen::VectorXd& { return s.q[static_cast<std::size_t>(arm)]; });
    s.q.swap(s.q_next);
    s.qd.swap(s.qd_next);
    return r.out.outcome;
  }

  /// New controllers for both arms (the robot path's ArmController) with room for a plan of `periods` periods: a
  /// rollout must not depend on which rollouts ran before it on this task (filters and trajectories carry state).
  void resetControl(int periods) {
    controllers.clear();
    for (int arm = 0; arm < 2; ++arm) {
      const auto a = static_cast<std::size_t>(arm);
      control::ArmControllerConfig c = controller_configs[a];
      c.trajectory_capacity = std::max(2, periods);
      controllers.push_back(std::make_unique<control::ArmController>(simulation->armModel(arm), friction[a], c));
    }
  }

  /// The poses of a DMP integrated from its start at the demonstration's rate (the path of a loaded demonstration).
  std::vector<Pose> integrate(const CartesianDmp& dmp) const {
    const double dt = 1.0 / kDemonstrationRate;
    const int samples = static_cast<int>(std::lround(dmp.duration() * kDemonstrationRate)) + 1;
    CartesianDmpState state = dmp.initialState();
    std::vector<Pose> path{state.pose()};
    for (int k = 1; k < samples; ++k) {
      if (dmp.step(state, dt) == primitives::DmpStatus::InvalidInput) {
        throw std::invalid_argument("cloth fold: the demonstration DMP cannot be integrated");
      }
      path.push_back(state.pose());
    }
    return path;
  }

  /// One fold arc per arm: from the far corner (x = centre + half length) over the cloth towards the near edge.
  std::vector<Pose> demonstrationPath(int arm) const {
    const double top = sim_config.table.topCentre().z();
    const Eigen::Vector3d centre = sim_config.cloth.pose.translation();
    const double half = 0.5 * sim_config.cloth.length, radius = config.demo_reach * half;
    const double side = simulation->basePose(arm).translation().y() > centre.y() ? 1.0 : -1.0;
    const double y = centre.y() + side * (0.5 * sim_config.cloth.width - 0.01);
    const double lift = 0.015;
    const int samples = static_cast<int>(std::lround(config.duration * kDemonstrationRate)) + 1;
    const double lag = arm == 1 ? config.demo_lag : 0.0;
    const double arc = arm == 1 ? config.demo_right_arc : 1.0;
    const double inward = side * config.demo_inward * 0.5 * sim_config.cloth.width;
    std::vector<Pose> path;
    for (int k = 0; k < samples; ++k) {
      double s = std::clamp((static_cast<double>(k) / (samples - 1) - lag) / (1.0 - lag), 0.0, 1.0);
      s = arc * s * s * s * (10.0 + s * (-15.0 + 6.0 * s));  // minimum jerk
      const double angle = M_PI * s;
      Pose pose;
      // The arc's radius shrinks from the corner's distance to the centre line to `radius`: it ends short of (or
      // beyond) the near edge, and `demo_drop` above the table.
      const double r = (half - 0.01) * (1.0 - s) + radius * s;
      pose.position = Eigen::Vector3d(centre.x() + r * std::cos(angle), y - inward * s,
                                      top + lift + config.demo_drop * s + config.demo_lift * r * std::sin(angle));
      pose.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI - 0.35 * std::sin(angle), Eigen::Vector3d::UnitY()));
      path.push_back(pose);
    }
    return path;
  }
};

ClothFoldTask::ClothFoldTask(const ClothFoldConfig& config) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.config = config;
  if (config.kernels < 2 || !(config.duration > 0.0) || config.hold_before < 0.0 || config.hold_after < 0.0 ||
      config.settle < 0.0 || !(config.max_ik_error > 0.0) || !(config.max_tracking_error > 0.0) ||
      !(config.path_rate > 0.0)) {
    throw std::invalid_argument("cloth fold: kernels >= 2, positive duration, limits and path rate, holds >= 0");
  }
  if (!(config.demo_lag >= 0.0 && config.demo_lag < 0.9))
    throw std::invalid_argument("cloth fold: demo_lag in [0, 0.9)");
  if (!(config.demo_right_arc >= 0.0 && config.demo_right_arc <= 1.0) ||
      !(config.demo_inward >= 0.0 && config.demo_inward <= 0.9)) {
    throw std::invalid_argument("cloth fold: demo_right_arc in [0, 1], demo_inward in [0, 0.9]");
  }
  if (!(config.step_acceleration > 0.0) || !std::isfinite(config.step_acceleration))
    throw std::invalid_argument("cloth fold: step_acceleration > 0 and finite");
  if (!(config.image_delay >= 0.0) || !std::isfinite(config.image_delay))
    throw std::invalid_argument("cloth fold: image_delay >= 0 and finite");
  config.noise.validate("cloth fold");
  m.sim_config = sim::SimConfig::fromYamlFile(config.sim_config, config.robot);
  if (!m.sim_config.has_cloth) throw std::invalid_argument("cloth fold: '" + config.sim_config + "' has no cloth");
  m.simulation = std::make_unique<sim::BimanualSimulation>(m.sim_config);
  m.file_rest = m.simulation->cloth().restVertices();
  if (m.simulation->armCount() != 2) throw std::invalid_argument("cloth fold: the simulation needs two arms");
  kinematics::InverseOperator op;
  kinematics::LimitScheme scheme;
  if (!kinematics::parseMethodName(config.ik_method, op, scheme)) {
    throw std::invalid_argument("cloth fold: unknown IK method '" + config.ik_method + "'");
  }
  m.clik_parameters.inverse = op;
  m.clik_parameters.limits = scheme;
  control::ComputedTorqueGains gains;
  gains.kp = config.kp.size() ? config.kp : m.sim_config.kp;
  gains.kv = config.kv.size() ? config.kv : m.sim_config.kv;
  if (gains.kp.size() == 0 || gains.kv.size() == 0) {
    throw std::invalid_argument(
        "cloth fold: no controller gains: give kp and kv, or a simulation file with a robot file");
  }
  m.gains = gains;
  for (int arm = 0; arm < 2; ++arm) {
    const kinematics::ChainModel& model = m.simulation->armModel(arm);
    dynamics::FrictionModel friction;
    const std::string file = config.friction_files.empty()
                                 ? m.sim_config.arms[static_cast<std::size_t>(arm)].friction_file
                                 : (arm < static_cast<int>(config.friction_files.size())
                                        ? config.friction_files[static_cast<std::size_t>(arm)]
                                        : std::string());
    const bool with_friction = !file.empty();
    if (with_friction) {
      friction = dynamics::loadFrictionModel(file);
    } else {
      friction.joints.assign(static_cast<std::size_t>(model.nq()), dynamics::JointFriction{});
    }
    m.friction.push_back(friction);
    m.with_friction.push_back(with_friction);
    // Checked here (a bad velocity limit is refused at once); the capacity is each rollout's plan's.
    m.controller_configs.push_back(
        inProcessControllerConfig(model, m.gains, with_friction, m.simulation->stepSize(), config.velocity_limit, 2));
  }

  // The demonstration: the scripted arcs fitted by two Cartesian DMPs; the start configurations by global IK.
  primitives::DmpParameters dmp;
  dmp.kernels = config.kernels;
  if (!config.demonstration_files.empty() && config.demonstration_files.size() != 2) {
    throw std::invalid_argument("cloth fold: demonstration_files needs one DMP file per arm (left, right)");
  }
  for (int arm = 0; arm < 2; ++arm) {
    if (config.demonstration_files.empty()) {
      const std::vector<Pose>& path = m.demonstration_paths.emplace_back(m.demonstrationPath(arm));
      m.demonstration.push_back(CartesianDmp::fit(dmp, primitives::OrientationEncoding::QuaternionVector, path,
                                                  1.0 / kDemonstrationRate, 0.0));
    } else {
      const std::string& file = config.demonstration_files[static_cast<std::size_t>(arm)];
      const CartesianDmp loaded = primitives::loadCartesianDmp(file);
      if (loaded.encoding() != primitives::OrientationEncoding::QuaternionVector ||
          loaded.parameters().kernels != config.kernels || loaded.parameters().goal_scaled_forcing) {
        throw std::invalid_argument("cloth fold: '" + file + "' must be a quaternion-vector Cartesian DMP of " +
                                    std::to_string(config.kernels) + " kernels without goal scaling");
      }
      m.demonstration.push_back(loaded.withDuration(config.duration));
      m.demonstration_paths.push_back(m.integrate(m.demonstration.back()));
    }
    const std::vector<Pose>& path = m.demonstration_paths.back();
    kinematics::GlobalIkParameters parameters;
    // Never binding: the same attempts, hence the same start, on any machine and under any load (the default 5 ms
    // ran out on a machine with both cores busy).
    parameters.timeout = 1.0;
    kinematics::GlobalIkSolver solver(m.simulation->armModel(arm), parameters);
    Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
    target.translation() = path.front().position;
    target.linear() = path.front().orientation.toRotationMatrix();
    // Seeded with the robot's IK seed (the middle of the joint ranges when the simulation file gives none): the fold
    // starts in the branch the arm works in.
    const kinematics::ChainModel& chain = m.simulation->armModel(arm);
    const Eigen::VectorXd& ik_seed = m.sim_config.arms[static_cast<std::size_t>(arm)].ik_seed;
    const Eigen::VectorXd seed = ik_seed.size() == chain.nq() ? ik_seed : kinematics::middleOfLimits(chain);
    Eigen::VectorXd q(chain.nq());
    const auto result = solver.solve(m.simulation->basePose(arm).inverse() * target, seed, q);
    if (result.status != kinematics::IkStatus::Converged) {
      throw std::invalid_argument("cloth fold: no IK solution for the start of arm " + std::to_string(arm));
    }
    m.start_q.push_back(q);
  }
}

ClothFoldTask::~ClothFoldTask() = default;

const ClothFoldConfig& ClothFoldTask::config() const noexcept {
  return impl_->config;
}

const sim::SimConfig& ClothFoldTask::simConfig() const noexcept {
  return impl_->sim_config;
}

int ClothFoldTask::parameterCount() const noexcept {
  return kDofs * policyBasisSize();
}

int ClothFoldTask::policyBasisSize() const noexcept {
  return impl_->config.kernels + (impl_->config.policy == FoldPolicy::WeightsAndGoals ? 1 : 0);
}

primitives::DrDmpParameters ClothFoldTask::forcingParameters(int matrices) const {
  primitives::DrDmpParameters parameters;
  parameters.dmp = dmpParameters();
  parameters.matrices = matrices;
  parameters.goal_offsets = impl_->config.policy == FoldPolicy::WeightsAndGoals;
  return parameters;
}

const std::vector<CartesianDmp>& ClothFoldTask::demonstration() const noexcept {
  return impl_->demonstration;
}

Eigen::VectorXd ClothFoldTask::demonstrationParameters() const {
  const int k = impl_->config.kernels, n = policyBasisSize();
  Eigen::VectorXd theta = Eigen::VectorXd::Zero(parameterCount());  // goal weights 0: the demonstration's goal
  for (int arm = 0; arm < 2; ++arm) {
    const CartesianDmp& d = impl_->demonstration[static_cast<std::size_t>(arm)];
    for (int row = 0; row < 3; ++row) {
      theta.segment((arm * 6 + row) * n, k) = d.positionWeights().row(row).transpose();
      theta.segment((arm * 6 + 3 + row) * n, k) = d.orientationWeights().row(row).transpose();
    }
  }
  return theta;
}

const primitives::DmpParameters& ClothFoldTask::dmpParameters() const noexcept {
  return impl_->demonstration.front().parameters();
}

Eigen::MatrixXd ClothFoldTask::demonstrationTrajectory() const {
  const auto samples = static_cast<Eigen::Index>(impl_->demonstration_paths.front().size());
  Eigen::MatrixXd out(samples, kDofs);
  for (int arm = 0; arm < 2; ++arm) {
    const std::vector<Pose>& path = impl_->demonstration_paths[static_cast<std::size_t>(arm)];
    for (Eigen::Index k = 0; k < samples; ++k) {
      const Pose& pose = path[static_cast<std::size_t>(k)];
      out.row(k).segment<3>(6 * arm) = pose.position.transpose();
      out.row(k).segment<3>(6 * arm + 3) =
          primitives::relativeQuaternionVector(path.front().orientation, pose.orientation).transpose();
    }
  }
  return out;
}

void ClothFoldTask::saveDemonstration(const std::string& prefix) const {
  const char* const names[2] = {"left", "right"};
  for (int arm = 0; arm < 2; ++arm) {
    primitives::saveCartesianDmp(impl_->demonstration[static_cast<std::size_t>(arm)], prefix + names[arm] + ".yaml",
                                 std::string("The cloth fold's demonstration, ") + names[arm] +
                                     " tool (world frame); tasks::ClothFoldConfig::demonstration_files reads it.");
  }
}

double ClothFoldTask::demonstrationStep() const noexcept {
  return 1.0 / kDemonstrationRate;
}

std::vector<CartesianDmp> ClothFoldTask::dmps(const Eigen::VectorXd& theta) const {
  if (theta.size() != parameterCount()) {
    throw std::invalid_argument("cloth fold: " + std::to_string(parameterCount()) + " parameters expected, got " +
                                std::to_string(theta.size()));
  }
  const int k = impl_->config.kernels, n = policyBasisSize();
  const bool goals = n > k;
  std::vector<CartesianDmp> out;
  for (int arm = 0; arm < 2; ++arm) {
    const CartesianDmp& d = impl_->demonstration[static_cast<std::size_t>(arm)];
    const primitives::DmpParameters& p = d.parameters();
    Eigen::MatrixXd position(3, k), orientation(3, k);
    Eigen::Vector3d position_offset = Eigen::Vector3d::Zero(), vector_offset = Eigen::Vector3d::Zero();
    for (int row = 0; row < 3; ++row) {
      position.row(row) = theta.segment((arm * 6 + row) * n, k).transpose();
      orientation.row(row) = theta.segment((arm * 6 + 3 + row) * n, k).transpose();
      if (goals) {
        position_offset[row] = theta[(arm * 6 + row) * n + k] / (p.alpha_z * p.beta_z);
        vector_offset[row] = theta[(arm * 6 + 3 + row) * n + k] / (p.alpha_z * p.beta_z);
      }
    }
    // The goal the constant forcing makes (DrDmpParameters::goal_offsets): the position moved, and the orientation
    // vector v = vec(q_s⁻¹ ∗ g) moved and rebuilt as q_s ∗ (√(1 − ‖v‖²), v).
    Pose goal = d.goal();
    goal.position += position_offset;
    Eigen::Vector3d v =
        primitives::relativeQuaternionVector(d.start().orientation, d.goal().orientation) + vector_offset;
    if (v.norm() > 1.0) v.normalize();
    goal.orientation = d.start().orientation *
                       Eigen::Quaterniond(std::sqrt(std::max(0.0, 1.0 - v.squaredNorm())), v.x(), v.y(), v.z());
    goal.orientation.normalize();
    out.emplace_back(p, d.encoding(), position, orientation, d.start(), goal, d.duration());
  }
  return out;
}

FoldRollout ClothFoldTask::run(const Eigen::VectorXd& theta) {
  if (theta.size() != parameterCount() || !theta.allFinite()) {
    FoldRollout out;
    out.outcome = FoldOutcome::InvalidPolicy;
    out.reason = "the policy needs " + std::to_string(parameterCount()) + " finite parameters";
    return out;
  }
  return run({Eigen::MatrixXd::Identity(kDofs, kDofs)}, theta);
}

FoldRollout ClothFoldTask::run(const std::vector<Eigen::MatrixXd>& coordination,
                               const Eigen::VectorXd& latent_weights) {
  return run(coordination, latent_weights, impl_->sim_config.seed);
}

FoldRollout ClothFoldTask::run(const std::vector<Eigen::MatrixXd>& coordination, const Eigen::VectorXd& latent_weights,
                               std::uint32_t seed) {
  Impl& m = *impl_;
  m.stepped.running = false;  // a stepped rollout in progress ends here
  Impl::Rollout r;
  r.wall_start = std::chrono::steady_clock::now();
  // The references first (open loop, as the robot path sends them), then the controllers track them.
  const FoldPlan plan = this->plan(coordination, latent_weights);
  r.out.acceleration_cost = plan.acceleration_cost;
  r.out.max_ik_error = plan.max_ik_error;
  if (plan.outcome != FoldOutcome::Ok) {
    r.out.outcome = plan.outcome;
    r.out.reason = plan.reason;
    return std::move(r.out);
  }
  const int steps = static_cast<int>(plan.position[0].cols());
  m.begin(r, seed, plan.release, steps, steps);
  if (r.out.outcome != FoldOutcome::Ok) return std::move(r.out);
  const double dt = m.simulation->stepSize();
  std::vector<control::Waypoints> waypoints;
  for (int arm = 0; arm < 2; ++arm) {
    const auto a = static_cast<std::size_t>(arm);
    waypoints.push_back(plannedWaypoints(plan.position[a], plan.velocity[a], plan.acceleration[a], 0, dt));
  }
  // The controller starts holding the arm where it stands (the plan's start), then tracks the plan from the next
  // period on.
  const auto load = [&](int arm, int k, control::ArmController& controller) {
    if (k == 0 && controller.setTrajectory(waypoints[static_cast<std::size_t>(arm)]) != control::TrajectoryStatus::Ok) {
      throw std::logic_error("cloth fold: the controller refused the planned references");
    }
  };
  const auto commanded = [&](int arm, int k) { return plan.position[static_cast<std::size_t>(arm)].col(k); };
  while (r.k < steps && r.out.outcome == FoldOutcome::Ok) m.period(r, load, commanded);
  return m.finish(r);
}

int ClothFoldTask::steppedPeriods() const {
  int move_start = 0, move_end = 0, release = 0, steps = 0;
  impl_->periods(impl_->simulation->stepSize(), move_start, move_end, release, steps);
  return release;
}

FoldOutcome ClothFoldTask::beginSteps(std::uint32_t seed) {
  Impl& m = *impl_;
  Impl::Stepped& s = m.stepped;
  int move_start = 0, move_end = 0, release = 0, steps = 0;
  m.periods(m.simulation->stepSize(), move_start, move_end, release, steps);
  s.rollout = Impl::Rollout{};
  s.rollout.wall_start = std::chrono::steady_clock::now();
  s.seed = seed;
  s.driven = release;
  s.q = m.start_q;
  s.qd.assign(2, Eigen::VectorXd::Zero(7));
  s.qdd = s.qd;
  s.q_next = s.q;
  s.qd_next = s.qd;
  s.waypoint.times = Eigen::VectorXd::Constant(1, m.simulation->stepSize());
  s.waypoint.positions.resize(7, 1);
  s.waypoint.velocities.resize(7, 1);
  s.waypoint.accelerations.resize(7, 1);
  m.begin(s.rollout, seed, release, steps, 2);
  s.running = true;
  return s.rollout.out.outcome;
}

bool ClothFoldTask::stepping() const noexcept {
  const Impl::Stepped& s = impl_->stepped;
  return s.running && s.rollout.out.outcome == FoldOutcome::Ok && s.rollout.k < s.driven;
}

int ClothFoldTask::steppedPeriod() const noexcept {
  return impl_->stepped.rollout.k;
}

FoldOutcome ClothFoldTask::step(const Eigen::Ref<const Eigen::VectorXd>& velocity) {
  Impl& m = *impl_;
  Impl::Stepped& s = m.stepped;
  if (!s.running) throw std::logic_error("cloth fold: step() without beginSteps()");
  Impl::Rollout& r = s.rollout;
  if (r.out.outcome != FoldOutcome::Ok) return r.out.outcome;
  if (r.k >= s.driven) {
    throw std::logic_error("cloth fold: the stepped rollout's " + std::to_string(s.driven) +
                           " driven periods are over: finishSteps()");
  }
  if (velocity.size() != 14 || !velocity.allFinite()) {
    r.out.outcome = FoldOutcome::InvalidPolicy;
    r.out.reason = "a step takes 14 finite joint velocities (left arm, then right), not " +
                   std::to_string(velocity.size()) + (velocity.allFinite() ? "" : " with NaN or Inf");
    return r.out.outcome;
  }
  for (int arm = 0; arm < 2; ++arm) {
    const Eigen::VectorXd& limit = m.simulation->armModel(arm).velocityLimits();
    for (int j = 0; j < 7; ++j) {
      const double v = velocity[7 * arm + j];
      if (std::abs(v) <= limit[j]) continue;
      std::ostringstream why;
      why << "arm " << arm << "'s reference for joint " << j + 1 << " leaves its limits: velocity " << v
          << " rad/s, limit " << limit[j];
      m.fail(r, FoldOutcome::OutOfLimits, why.str());
      return r.out.outcome;
    }
  }
  return m.steppedPeriod(velocity);
}

const Eigen::VectorXd& ClothFoldTask::steppedReference(int arm) const {
  return impl_->stepped.q.at(static_cast<std::size_t>(arm));
}

void ClothFoldTask::measuredState(int arm, Eigen::VectorXd& position, Eigen::VectorXd& velocity) const {
  if (arm < 0 || arm > 1) throw std::out_of_range("cloth fold: arm 0 or 1");
  const auto a = static_cast<std::size_t>(arm);
  const Impl::Rollout& r = impl_->stepped.rollout;
  // Not read again: the simulation's sensor noise draws from the rollout's stream.
  if (r.k == 0 || r.measured.empty()) {
    position = impl_->start_q[a];
    velocity = Eigen::VectorXd::Zero(position.size());
  } else {
    position = r.measured[a].position;
    velocity = r.measured[a].velocity;
  }
}

Eigen::Vector3d ClothFoldTask::toolPosition(int arm) const {
  if (arm < 0 || arm > 1) throw std::out_of_range("cloth fold: arm 0 or 1");
  return impl_->simulation->toolPose(arm).translation();
}

const Eigen::Matrix3Xd& ClothFoldTask::clothVertices() const {
  return impl_->simulation->cloth().vertices();
}

FoldRollout ClothFoldTask::finishSteps() {
  Impl& m = *impl_;
  Impl::Stepped& s = m.stepped;
  if (!s.running) throw std::logic_error("cloth fold: finishSteps() without beginSteps()");
  s.running = false;
  Impl::Rollout& r = s.rollout;
  // Through what is left of the rollout (the periods the policy did not drive, the settling) the references come to
  // rest at the stepped acceleration and hold there.
  const Eigen::VectorXd rest = Eigen::VectorXd::Zero(14);
  while (!r.measured.empty() && r.k < r.steps && r.out.outcome == FoldOutcome::Ok) (void)m.steppedPeriod(rest);
  return m.finish(r);
}

FoldPlan ClothFoldTask::plan(const std::vector<Eigen::MatrixXd>& coordination,
                             const Eigen::VectorXd& latent_weights) const {
  const Impl& m = *impl_;
  FoldPlan out;
  const sim::BimanualSimulation& simulation = *m.simulation;
  out.dt = simulation.stepSize();
  std::unique_ptr<primitives::DrDmp> forcing = makeForcing(*this, coordination, latent_weights, out.reason);
  if (!forcing) {
    out.outcome = FoldOutcome::InvalidPolicy;
    return out;
  }
  // The same periods as run(): hold, move, hold, then settle after the release.
  int move_end = 0, steps = 0;
  m.periods(out.dt, out.move_start, move_end, out.release, steps);
  ReferenceGenerator references(m.demonstration, std::move(forcing), m.start_q, out.dt);
  std::vector<kinematics::ClikData> clik;
  for (int arm = 0; arm < 2; ++arm) {
    clik.emplace_back(simulation.armModel(arm), m.clik_parameters);
    out.position.emplace_back(7, steps);
    out.velocity.emplace_back(7, steps);
    out.acceleration.emplace_back(7, steps);
  }
  for (int k = 0; k < steps; ++k) {
    const bool moving = k >= out.move_start && k < move_end;
    if (!references.stepForcing(moving)) {
      out.outcome = FoldOutcome::InvalidPolicy;
      out.reason = "the coordinated forcing terms are not finite";
      break;
    }
    for (int arm = 0; arm < 2 && out.outcome == FoldOutcome::Ok; ++arm) {
      const auto a = static_cast<std::size_t>(arm);
      out.outcome = references.stepArm(arm, moving, simulation.armModel(arm), m.clik_parameters,
                                       simulation.basePose(arm), clik[a], m.config.max_ik_error, out.reason);
      out.position[a].col(k) = references.q_ref[a];
      out.velocity[a].col(k) = references.qd_ref[a];
      out.acceleration[a].col(k) = references.qdd_ref[a];
    }
    if (out.outcome != FoldOutcome::Ok) {
      out.reason += " at t = " + std::to_string(k * out.dt) + " s";
      break;
    }
  }
  out.acceleration_cost = references.acceleration_cost;
  out.max_ik_error = references.max_ik_error;
  return out;
}

const std::vector<Eigen::VectorXd>& ClothFoldTask::startPositions() const noexcept {
  return impl_->start_q;
}

const kinematics::ChainModel& ClothFoldTask::armModel(int arm) const {
  return impl_->simulation->armModel(arm);
}

Eigen::Isometry3d ClothFoldTask::basePose(int arm) const {
  return impl_->simulation->basePose(arm);
}

FoldQuality ClothFoldTask::foldQualityOf(const Eigen::Matrix3Xd& vertices) const {
  const sim::Cloth& cloth = impl_->simulation->cloth();
  const sim::ClothParameters& p = cloth.parameters();
  return foldQuality(vertices, cloth.restVertices(), p.nodes_x, p.nodes_y, p.thickness);
}

Eigen::Matrix3Xd ClothFoldTask::idealFoldVertices() const {
  const sim::Cloth& cloth = impl_->simulation->cloth();
  const sim::ClothParameters& p = cloth.parameters();
  return idealFold(cloth.restVertices(), p.nodes_x, p.nodes_y, p.thickness);
}

const Eigen::Matrix3Xi& ClothFoldTask::clothTriangles() const {
  return impl_->simulation->cloth().triangles();
}

const Eigen::Matrix3Xd& ClothFoldTask::clothRestVertices() const {
  return impl_->simulation->cloth().restVertices();
}

Eigen::Matrix3Xd ClothFoldTask::clothStartVertices(std::uint32_t seed) const {
  const Impl& m = *impl_;
  if (!m.config.noise.any()) return m.file_rest;
  // run() lays the cloth at noisyClothPose() instead of the file's pose: the file's mesh moved by that times pose⁻¹.
  const Eigen::Isometry3d& pose = m.sim_config.cloth.pose;
  const Eigen::Isometry3d moved = noisyClothPose(pose, drawFoldNoise(m.config.noise, seed)) * pose.inverse();
  Eigen::Matrix3Xd out = moved.linear() * m.file_rest;
  out.colwise() += moved.translation();
  return out;
}

}  // namespace bimanual_skills::tasks
