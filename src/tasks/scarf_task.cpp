#include "bimanual_skills/tasks/scarf_task.hpp"

#include "bimanual_skills/control/arm_controller.hpp"
#include "bimanual_skills/dynamics/friction_yaml.hpp"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "bimanual_skills/sim/robot_file.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "bimanual_skills/tasks/in_process_control.hpp"
#include "io/yaml_io.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace bimanual_skills::tasks {

namespace {

/// Samples per second of the scripted demonstration the DMP is fitted to.
constexpr double kDemonstrationRate = 100.0;
/// Damping of the observer's torques mapped to a force on the tool (ScarfRollout::mean_force_error).
constexpr double kForceDamping = 0.1;
/// How far the tool rises after it lets go before the arm goes to clear_posture [m], and the largest joint step that
/// lift may take [rad] (else the arm goes straight).
constexpr double kClearLift = 0.15, kMaxLiftStep = 1.0;

double minimumJerk(double s) {
  return s * s * s * (10.0 + s * (-15.0 + 6.0 * s));
}

}  // namespace

void ScarfTaskConfig::validate() const {
  if (kernels < 2 || !(duration > 0.0) || !(hold_before >= 0.0) || !(hold_after >= 0.0) || !(settle >= 0.0) ||
      !(max_tracking_error > 0.0) || !std::isfinite(velocity_limit) || !(path_rate > 0.0) || !(cloth_rate >= 0.0)) {
    throw std::invalid_argument(
        "scarf task: kernels >= 2, a positive duration, tracking limit and path rate, holds, settle and cloth rate >= "
        "0, a finite velocity limit");
  }
  if (!(acceleration_weight >= 0.0) || !(torque_weight >= 0.0) || !std::isfinite(acceleration_weight) ||
      !std::isfinite(torque_weight) || !(failure_cost > 0.0) || !std::isfinite(failure_cost)) {
    throw std::invalid_argument("scarf task: finite acceleration_weight, torque_weight >= 0 and failure_cost > 0");
  }
  // A move shorter than kMinClearTime would put the leave's first waypoint before the release (a period's rounding).
  const bool no_move = clear_posture.size() == 0 && clear_time == 0.0;
  const bool move = clear_posture.size() > 0 && clear_time >= kMinClearTime && clear_time <= settle;
  if (!clear_posture.allFinite() || !(no_move || move)) {
    throw std::invalid_argument(
        "scarf task: clear_posture (finite joints) and a clear_time in [0.1 s, settle] go together (neither: the arm "
        "stays where it lets go)");
  }
  for (const Eigen::Vector3d& w : demo_waypoints) {
    if (!w.allFinite()) throw std::invalid_argument("scarf task: a demonstration waypoint is not finite");
  }
  camera.validate("scarf task camera");
}

struct ScarfTask::Impl {
  ScarfTaskConfig config;
  sim::SimConfig sim_config;
  Mannequin mannequin;
  int arm = 0;
  std::vector<Eigen::VectorXd> start;  ///< Every arm's start.
  std::vector<std::vector<std::string>> joint_names;
  control::ComputedTorqueGains gains;
  std::vector<dynamics::FrictionModel> friction;
  std::vector<bool> with_friction;
  vision::PinholeCamera camera;
  std::unique_ptr<vision::PerspectiveRenderer> renderer;
  Eigen::Matrix3Xi triangles;     ///< The scarf's.
  Eigen::MatrixXd demonstration;  ///< samples × the arm's joints
  primitives::DrDmpParameters dmp;
  Eigen::VectorXd demonstration_weights;
  std::unique_ptr<kinematics::ChainModel> model;           ///< The holding arm's.
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();  ///< Its base frame in the world.

  /// The policy's DMP from the demonstration's start to its goal. \throws std::invalid_argument when it does not fit.
  std::unique_ptr<primitives::DrDmp> dmpOf(const std::vector<Eigen::MatrixXd>& coordination,
                                           const Eigen::VectorXd& latent_weights) const {
    if (!latent_weights.allFinite()) throw std::invalid_argument("non-finite weights");
    for (const Eigen::MatrixXd& omega : coordination) {
      if (!omega.allFinite()) throw std::invalid_argument("a non-finite coordination matrix");
    }
    primitives::DrDmpParameters parameters = dmp;
    parameters.matrices = static_cast<int>(coordination.size());
    const Eigen::VectorXd q0 = demonstration.row(0).transpose();
    const Eigen::VectorXd g = demonstration.bottomRows(1).transpose();
    return std::make_unique<primitives::DrDmp>(parameters, coordination, latent_weights, q0, g, config.duration);
  }

  /// The joint path through the waypoints: each a tool pose (the start's orientation) solved by global IK closest to
  /// the previous one, joined by minimum-jerk segments of equal time in joint space.
  void demonstrate(const sim::BimanualSimulation& simulation) {
    const kinematics::ChainModel& model = simulation.armModel(arm);
    const Eigen::Isometry3d base = simulation.basePose(arm);
    kinematics::ChainData fk(model);
    const Eigen::VectorXd& q0 = start[static_cast<std::size_t>(arm)];
    (void)kinematics::forwardKinematics(model, fk, q0);
    const Eigen::Isometry3d tool0 = fk.tipPose();
    kinematics::GlobalIkParameters parameters;
    parameters.mode = kinematics::SolutionMode::ClosestToSeed;
    parameters.timeout = 10.0;  // never binding: the attempt cap ends the search, the same on any machine
    parameters.max_attempts = 200;
    kinematics::GlobalIkSolver solver(model, parameters);
    std::vector<Eigen::VectorXd> keys{q0};
    for (std::size_t w = 0; w < config.demo_waypoints.size(); ++w) {
      Eigen::Isometry3d target = tool0;
      target.translation() = base.inverse() * config.demo_waypoints[w];
      Eigen::VectorXd q(model.nq());
      if (solver.solve(target, keys.back(), q).status != kinematics::IkStatus::Converged) {
        throw std::invalid_argument("scarf task: demonstration waypoint " + std::to_string(w + 1) +
                                    " is out of the arm's reach with the start's tool orientation");
      }
      keys.push_back(q);
    }
    const int samples = static_cast<int>(std::lround(config.duration * kDemonstrationRate)) + 1;
    const int segments = static_cast<int>(keys.size()) - 1;
    demonstration.resize(samples, model.nq());
    for (int k = 0; k < samples; ++k) {
      if (segments == 0) {
        demonstration.row(k) = keys.front().transpose();
        continue;
      }
      const double u = static_cast<double>(k) / (samples - 1) * segments;
      const auto s = static_cast<std::size_t>(std::min(static_cast<int>(u), segments - 1));
      const double a = minimumJerk(u - static_cast<double>(s));
      demonstration.row(k) = ((1.0 - a) * keys[s] + a * keys[s + 1]).transpose();
    }
    const primitives::DrDmpFit fit =
        primitives::DrDmp::fit(dmp, {demonstration}, 1.0 / kDemonstrationRate, model.nq(), 0.0);
    // The standard DMP's weights (Ω = I): the fit's latent weights mapped back through its coordination.
    const Eigen::MatrixXd& omega = fit.dmp.coordination().front();
    const Eigen::Map<const Eigen::MatrixXd> latent(fit.latent_weights.data(), dmp.basisSize(), model.nq());
    const Eigen::MatrixXd weights = omega * latent.transpose();  // dofs × kernels
    demonstration_weights =
        Eigen::Map<const Eigen::VectorXd>(Eigen::MatrixXd(weights.transpose()).data(), weights.size());
  }
};

ScarfTask::ScarfTask(const ScarfTaskConfig& config) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  config.validate();
  m.config = config;
  m.sim_config = sim::SimConfig::fromYamlFile(config.sim_config);
  if (!m.sim_config.has_cloth) throw std::invalid_argument("scarf task: '" + config.sim_config + "' has no scarf");
  m.mannequin = Mannequin::fromObstacles(m.sim_config.obstacles);
  const sim::BimanualSimulation simulation(m.sim_config);
  m.arm = simulation.armIndex(config.arm);
  if (m.arm < 0) throw std::invalid_argument("scarf task: no arm '" + config.arm + "' in '" + config.sim_config + "'");
  for (const sim::ArmConfig& a : m.sim_config.arms) {
    if (a.start.size() == 0) throw std::invalid_argument("scarf task: arm '" + a.name + "' has no start posture");
    m.start.push_back(a.start);
  }
  // The start file: the holding arm's posture and the camera, as bullet_sim reads them.
  const std::string where = "scarf start file '" + config.start + "'";
  const YAML::Node root = io::loadYamlFile(config.start, where);
  const int n = simulation.jointCount(m.arm);
  m.start[static_cast<std::size_t>(m.arm)] =
      io::readVector(io::required(root, "initial_positions", where), config.arm, where + " initial_positions", n);
  m.camera = vision::PinholeCamera::lookingAt(io::readVector(root, "rgbd_eye", where, 3),
                                              io::readVector(root, "rgbd_target", where, 3));
  m.renderer = std::make_unique<vision::PerspectiveRenderer>(rendererFor(m.sim_config), m.camera);
  if (config.from_camera) {
    m.config.camera.d_ref = referenceDistance(m.mannequin, m.camera);
    m.config.camera.hanging_level = hangingLevel(m.mannequin, m.camera);
  }

  m.gains.kp = m.sim_config.kp;
  m.gains.kv = m.sim_config.kv;
  if (m.gains.kp.size() == 0 || m.gains.kv.size() == 0) {
    throw std::invalid_argument("scarf task: no controller gains in the robot file of '" + config.sim_config + "'");
  }
  for (int a = 0; a < simulation.armCount(); ++a) {
    const std::string& file = m.sim_config.arms[static_cast<std::size_t>(a)].friction_file;
    m.with_friction.push_back(!file.empty());
    if (file.empty()) {
      dynamics::FrictionModel none;
      none.joints.assign(static_cast<std::size_t>(simulation.jointCount(a)), dynamics::JointFriction{});
      m.friction.push_back(none);
    } else {
      m.friction.push_back(dynamics::loadFrictionModel(file));
    }
  }
  m.triangles = simulation.cloth().triangles();
  m.model = std::make_unique<kinematics::ChainModel>(simulation.armModel(m.arm));
  if (config.clear_posture.size() > 0 &&
      (config.clear_posture.size() != n || !m.model->withinLimits(config.clear_posture, 0.0))) {
    throw std::invalid_argument("scarf task: clear_posture needs " + std::to_string(n) + " joints of arm '" +
                                config.arm + "' within its limits");
  }
  m.base = simulation.basePose(m.arm);
  for (int a = 0; a < simulation.armCount(); ++a) m.joint_names.push_back(simulation.armModel(a).jointNames());
  m.dmp.dmp.kernels = config.kernels;
  m.demonstrate(simulation);
}

ScarfTask::~ScarfTask() = default;

Eigen::Vector3d ScarfPlacement::apply(const Eigen::Vector3d& point) const {
  return Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * point + shift;
}

namespace {

/// The holding arm's base pose in the world with the simulation file on `robot` ("": its own).
Eigen::Isometry3d holdingBase(const ScarfTaskConfig& config, const std::string& robot) {
  const sim::BimanualSimulation simulation(sim::SimConfig::fromYamlFile(config.sim_config, robot));
  const int arm = simulation.armIndex(config.arm);
  if (arm < 0) {
    throw std::invalid_argument("scarf placement: the robot of '" + config.sim_config + "'" +
                                (robot.empty() ? "" : " on '" + robot + "'") + " has no arm '" + config.arm + "'");
  }
  return simulation.basePose(arm);
}

}  // namespace

ScarfPlacement scarfPlacementOn(const ScarfTaskConfig& config, const std::string& robot) {
  const Eigen::Isometry3d from = holdingBase(config, ""), to = holdingBase(config, robot);
  const Eigen::Isometry3d motion = to * from.inverse();
  if ((motion.linear().col(2) - Eigen::Vector3d::UnitZ()).norm() > 1e-6) {
    throw std::invalid_argument("scarf placement: arm '" + config.arm + "' of '" + robot +
                                "' stands tilted against the scene's robot's; place the scene by hand");
  }
  ScarfPlacement placement;
  placement.yaw = std::atan2(motion.linear()(1, 0), motion.linear()(0, 0));
  placement.shift = motion.translation();
  return placement;
}

Eigen::VectorXd scarfStartOn(const ScarfTaskConfig& config, const std::string& robot) {
  const ScarfTask task(config);
  kinematics::ChainData fk(task.armModel());
  (void)kinematics::forwardKinematics(task.armModel(), fk, task.startPosition());
  const Eigen::Vector3d grasp = scarfPlacementOn(config, robot).apply(task.basePose() * fk.tipPose().translation());

  const sim::BimanualSimulation simulation(sim::SimConfig::fromYamlFile(config.sim_config, robot));
  const int arm = simulation.armIndex(config.arm);
  const kinematics::ChainModel& model = simulation.armModel(arm);
  kinematics::ChainData data(model);
  (void)kinematics::forwardKinematics(model, data, simulation.config().arms[static_cast<std::size_t>(arm)].start);
  Eigen::Isometry3d tool = simulation.basePose(arm) * data.tipPose();
  tool.translation() = grasp;
  try {
    return sim::postureFromToolPose(model, simulation.basePose(arm).inverse() * tool);
  } catch (const std::exception& e) {
    throw std::invalid_argument("scarf start: arm '" + config.arm + "' of '" + robot +
                                "' cannot hold the scarf's end at (" + std::to_string(grasp.x()) + ", " +
                                std::to_string(grasp.y()) + ", " + std::to_string(grasp.z()) +
                                ") pointing as its start does: " + e.what());
  }
}

int ScarfTask::dofs() const noexcept {
  return static_cast<int>(impl_->demonstration.cols());
}

primitives::DrDmpParameters ScarfTask::forcingParameters(int matrices) const {
  primitives::DrDmpParameters p = impl_->dmp;
  p.matrices = matrices;
  return p;
}

const Eigen::MatrixXd& ScarfTask::demonstrationTrajectory() const noexcept {
  return impl_->demonstration;
}

double ScarfTask::demonstrationStep() const noexcept {
  return 1.0 / kDemonstrationRate;
}

Eigen::VectorXd ScarfTask::demonstrationWeights() const {
  return impl_->demonstration_weights;
}

const ScarfTaskConfig& ScarfTask::config() const noexcept {
  return impl_->config;
}

const sim::SimConfig& ScarfTask::simConfig() const noexcept {
  return impl_->sim_config;
}

const Mannequin& ScarfTask::mannequin() const noexcept {
  return impl_->mannequin;
}

const vision::PinholeCamera& ScarfTask::camera() const noexcept {
  return impl_->camera;
}

const kinematics::ChainModel& ScarfTask::armModel() const noexcept {
  return *impl_->model;
}

const Eigen::Isometry3d& ScarfTask::basePose() const noexcept {
  return impl_->base;
}

const Eigen::VectorXd& ScarfTask::startPosition() const noexcept {
  return impl_->start[static_cast<std::size_t>(impl_->arm)];
}

int ScarfTask::arm() const noexcept {
  return impl_->arm;
}

const std::vector<Eigen::VectorXd>& ScarfTask::starts() const noexcept {
  return impl_->start;
}

const std::vector<std::vector<std::string>>& ScarfTask::jointNames() const noexcept {
  return impl_->joint_names;
}

const Eigen::Matrix3Xi& ScarfTask::scarfTriangles() const noexcept {
  return impl_->triangles;
}

cv::Mat ScarfTask::cameraImage(const Eigen::Matrix3Xd& vertices) {
  if (vertices.cols() != impl_->triangles.maxCoeff() + 1) {
    throw std::invalid_argument("scarf task: a mesh of " + std::to_string(vertices.cols()) +
                                " nodes is not the scarf's");
  }
  (void)impl_->renderer->render(vertices, impl_->triangles);
  return impl_->renderer->bgr().clone();
}

void scoreScarfRollout(const ScarfTaskConfig& config, ScarfRollout& rollout) {
  rollout.c_acceleration = config.acceleration_weight * rollout.acceleration;
  rollout.c_torque = config.torque_weight * rollout.mean_abs_torque;
  rollout.c_cam = rollout.camera.c_cam;
  rollout.cost = rollout.outcome == FoldOutcome::Ok ? rollout.c_acceleration + rollout.c_cam + rollout.c_torque
                                                    : config.failure_cost;
}

ScarfPlan ScarfTask::plan(const std::vector<Eigen::MatrixXd>& coordination,
                          const Eigen::VectorXd& latent_weights) const {
  const Impl& m = *impl_;
  const ScarfTaskConfig& c = m.config;
  ScarfPlan out;
  out.dt = m.sim_config.step;
  out.move_start = static_cast<int>(std::lround(c.hold_before / out.dt));
  out.move_end = out.move_start + static_cast<int>(std::lround(c.duration / out.dt));
  out.release = out.move_end + static_cast<int>(std::lround(c.hold_after / out.dt));
  out.clear_end = out.release + static_cast<int>(std::lround(c.clear_time / out.dt));
  out.end = out.release + static_cast<int>(std::lround(c.settle / out.dt));
  std::unique_ptr<primitives::DrDmp> dmp;
  try {
    dmp = m.dmpOf(coordination, latent_weights);
  } catch (const std::invalid_argument& e) {
    out.outcome = FoldOutcome::InvalidPolicy;
    out.reason = std::string("the policy does not fit the task's DMP: ") + e.what();
    return out;
  }
  // As run() steps it: one DMP step per period of the motion, the reference of that period.
  const int steps = out.move_end - out.move_start, n = dofs();
  out.position.resize(n, steps);
  out.velocity.resize(n, steps);
  out.acceleration.resize(n, steps);
  primitives::DrDmpState state = dmp->initialState();
  for (int j = 0; j < steps; ++j) {
    const double t = (out.move_start + j) * out.dt;
    if (dmp->step(state, out.dt) == primitives::DmpStatus::InvalidInput || !state.dmp.y.allFinite()) {
      out.outcome = FoldOutcome::InvalidPolicy;
      out.reason = "the DMP's references are not finite at t = " + std::to_string(t) + " s";
      return out;
    }
    out.position.col(j) = state.dmp.y;
    out.velocity.col(j) = state.dmp.yd;
    out.acceleration.col(j) = state.dmp.ydd;
    out.acceleration_cost += state.dmp.ydd.squaredNorm() * out.dt;
    if (!m.model->withinLimits(state.dmp.y, 0.0)) {
      out.outcome = FoldOutcome::OutOfLimits;
      out.reason = "the DMP's references leave the joint limits at t = " + std::to_string(t) + " s";
      return out;
    }
  }
  if (out.clear_end > out.release) {
    // Out of the camera's view: straight up first (a tool just released beside the scarf must not sweep it off the
    // shoulders on its way out), then to clear_posture.
    out.lift_end = out.release + (out.clear_end - out.release) / 4;
    const Eigen::VectorXd last = out.position.col(steps - 1);
    out.lifted = last;
    kinematics::ChainData data(*m.model);
    (void)kinematics::forwardKinematics(*m.model, data, last);
    Eigen::Isometry3d up = data.tipPose();
    up.translation() += m.base.linear().transpose() * Eigen::Vector3d(0.0, 0.0, kClearLift);
    kinematics::GlobalIkParameters parameters;
    parameters.timeout = 1.0;  // never binding: the same posture under any load
    Eigen::VectorXd lifted = last;
    if (kinematics::GlobalIkSolver(*m.model, parameters).solve(up, last, lifted).status ==
            kinematics::IkStatus::Converged &&
        (lifted - last).cwiseAbs().maxCoeff() <= kMaxLiftStep) {
      out.lifted = lifted;  // else (an arm near its limits) it leaves without the lift
    }
  }
  return out;
}

ScarfTruth ScarfTask::truthOf(const Eigen::Matrix3Xd& vertices) const {
  const sim::ClothParameters& cloth = impl_->sim_config.cloth;
  if (vertices.cols() != static_cast<Eigen::Index>(cloth.nodes_x) * cloth.nodes_y) {
    throw std::invalid_argument("a scarf mesh of " + std::to_string(vertices.cols()) + " nodes, the task's has " +
                                std::to_string(cloth.nodes_x * cloth.nodes_y));
  }
  return scarfTruth(impl_->mannequin, vertices, cloth.nodes_x, cloth.nodes_y);
}

ScarfRollout ScarfTask::run(const std::vector<Eigen::MatrixXd>& coordination, const Eigen::VectorXd& latent_weights,
                            std::uint32_t seed, realtime::CycleProbe* probe) {
  Impl& m = *impl_;
  const ScarfTaskConfig& c = m.config;
  ScarfRollout out;
  const auto wall_start = std::chrono::steady_clock::now();
  const auto fail = [&](FoldOutcome outcome, const std::string& reason, double t) {
    out.outcome = outcome;
    out.reason = reason + (t >= 0.0 ? " at t = " + std::to_string(t) + " s" : std::string());
  };
  // The references first (open loop, as the robot path sends them), then the controllers track them.
  const ScarfPlan plan = this->plan(coordination, latent_weights);
  out.acceleration = plan.acceleration_cost;
  if (plan.outcome != FoldOutcome::Ok) {
    out.outcome = plan.outcome;
    out.reason = plan.reason;
    out.cost = c.failure_cost;
    return out;
  }

  sim::SimConfig sim_config = m.sim_config;
  sim_config.seed = seed;
  sim::BimanualSimulation simulation(sim_config);
  std::vector<sim::ArmState> start;
  for (const Eigen::VectorXd& q : m.start) start.push_back({q, Eigen::VectorXd::Zero(q.size())});
  if (simulation.reset(start) != sim::SimStatus::Ok) throw std::logic_error("scarf task: reset rejected");
  if (simulation.grasp(m.arm, &out.grasped_nodes) != sim::SimStatus::Ok || out.grasped_nodes == 0) {
    fail(FoldOutcome::GraspFailed, "the tool holds no scarf node at its start", -1.0);
    out.cost = c.failure_cost;
    return out;
  }
  const int arms = simulation.armCount();
  const double dt = simulation.stepSize();
  const int steps = plan.end;
  const Eigen::VectorXd velocity_limit =
      c.velocity_limit > 0.0 ? Eigen::VectorXd::Constant(1, c.velocity_limit) : Eigen::VectorXd();
  std::vector<control::ArmControllerConfig> configs;
  std::vector<std::unique_ptr<control::ArmController>> controllers;
  std::vector<sim::JointState> measured;
  for (int a = 0; a < arms; ++a) {
    const auto i = static_cast<std::size_t>(a);
    const kinematics::ChainModel& model = simulation.armModel(a);
    configs.push_back(inProcessControllerConfig(model, m.gains, m.with_friction[i], dt, velocity_limit,
                                                std::max(2, static_cast<int>(plan.position.cols()) + 1)));
    controllers.push_back(std::make_unique<control::ArmController>(model, m.friction[i], configs.back()));
    measured.emplace_back(model.nq());
  }
  // The holding arm's trajectory: at its start until the period before the motion, then the planned references;
  // at rest at their end after it. The other arms hold where they start.
  control::Waypoints waypoints;
  {
    const Eigen::Index columns = plan.position.cols() + (plan.move_start >= 1 ? 1 : 0);
    Eigen::MatrixXd position(plan.position.rows(), columns), velocity(position.rows(), columns),
        acceleration(position.rows(), columns);
    position.rightCols(plan.position.cols()) = plan.position;
    velocity.rightCols(plan.position.cols()) = plan.velocity;
    acceleration.rightCols(plan.position.cols()) = plan.acceleration;
    if (plan.move_start >= 1) {
      position.col(0) = m.start[static_cast<std::size_t>(m.arm)];
      velocity.col(0).setZero();
      acceleration.col(0).setZero();
    }
    waypoints =
        plannedWaypoints(position, velocity, acceleration, plan.move_start - (plan.move_start >= 1 ? 1 : 0), dt);
  }
  // From the release on (loaded after its update, from the rest the motion's references end in): up, then out of the
  // camera's view.
  control::Waypoints leave;
  if (plan.clear_end > plan.release) {
    leave.times = Eigen::Vector2d((plan.lift_end - plan.release - 1) * dt, (plan.clear_end - plan.release - 1) * dt);
    leave.positions.resize(plan.lifted.size(), 2);
    leave.positions << plan.lifted, c.clear_posture;
    leave.velocities = leave.accelerations = Eigen::MatrixXd::Zero(plan.lifted.size(), 2);
  }
  const int path_every = std::max(1, static_cast<int>(std::lround(1.0 / (c.path_rate * dt))));
  const int cloth_every =
      c.cloth_rate > 0.0 ? std::max(1, static_cast<int>(std::lround(1.0 / (c.cloth_rate * dt)))) : 0;
  const int n = dofs();
  const kinematics::ChainModel& model = simulation.armModel(m.arm);
  Eigen::VectorXd torque(n);
  std::vector<Eigen::VectorXd> joints;
  std::vector<Eigen::Vector3d> tools;
  std::vector<double> path_times, cloth_times;
  double torque_sum = 0.0, force_sum = 0.0, error_sum = 0.0;
  kinematics::ChainData jacobian(model);
  Eigen::Matrix<double, 6, 6> jjt;
  Eigen::Matrix<double, 6, 1> estimated;
  int torque_samples = 0;
  const control::ArmController& holder = *controllers[static_cast<std::size_t>(m.arm)];
  for (int k = 0; k < steps && out.outcome == FoldOutcome::Ok; ++k) {
    const double t = simulation.time();
    if (k == plan.release && c.release) (void)simulation.release(m.arm);
    control::ControllerStatus status = control::ControllerStatus::Ok;
    int stopped_arm = 0;
    double tracking = 0.0;
    // The control part of the period: every arm's state read, controller (with its observer) and torque.
    if (probe != nullptr) probe->begin();
    for (int a = 0; a < arms; ++a) {
      const auto i = static_cast<std::size_t>(a);
      sim::JointState& s = measured[i];
      simulation.readJointState(a, s);
      const bool holding = a == m.arm;
      status = controllers[i]->update(t, t, s.position, s.velocity, torque);
      stopped_arm = a;
      if (status != control::ControllerStatus::Ok && status != control::ControllerStatus::Saturated) break;
      tracking = controllers[i]->trackingError().cwiseAbs().maxCoeff();
      if (holding) out.max_tracking_error = std::max(out.max_tracking_error, tracking);
      if (tracking > c.max_tracking_error) break;
      simulation.writeJointTorques(a, torque);
      if (holding && k >= plan.move_start && k < plan.release) {
        const Eigen::VectorXd& tau = controllers[i]->estimatedExternalTorque();
        torque_sum += tau.cwiseAbs().mean();
        out.peak_abs_torque = std::max(out.peak_abs_torque, tau.cwiseAbs().maxCoeff());
        const double force = simulation.clothWrench(a).head<3>().norm();
        force_sum += force;
        out.peak_tool_force = std::max(out.peak_tool_force, force);
        ++torque_samples;
      }
    }
    if (probe != nullptr) out.control_allocations += probe->end();
    const auto i = static_cast<std::size_t>(stopped_arm);
    const std::string stop = controllerStopReason(status, stopped_arm, measured[i].velocity, configs[i].velocity_limit);
    if (!stop.empty()) {
      fail(FoldOutcome::ControllerFailed, stop, t);
    } else if (tracking > c.max_tracking_error) {
      fail(FoldOutcome::ControllerFailed,
           "arm " + std::to_string(stopped_arm) + " is " + std::to_string(tracking) + " rad off its references", t);
    }
    if (out.outcome != FoldOutcome::Ok) break;
    if ((k == 0 &&
         controllers[static_cast<std::size_t>(m.arm)]->setTrajectory(waypoints) != control::TrajectoryStatus::Ok) ||
        (k == plan.release && leave.times.size() > 0 &&
         controllers[static_cast<std::size_t>(m.arm)]->setTrajectory(leave) != control::TrajectoryStatus::Ok)) {
      throw std::logic_error("scarf task: the controller refused the planned references");
    }
    if (k >= plan.move_start && k < plan.release) {
      // The observer's estimate as a force on the tool, against the scarf's (both in the world frame).
      const sim::JointState& s = measured[static_cast<std::size_t>(m.arm)];
      (void)kinematics::computeJacobian(model, jacobian, s.position);
      jjt.noalias() = jacobian.jacobian * jacobian.jacobian.transpose();
      jjt.diagonal().array() += kForceDamping * kForceDamping;
      estimated.noalias() = jacobian.jacobian * holder.estimatedExternalTorque();
      estimated = jjt.ldlt().solve(estimated);
      const Eigen::Vector3d force = simulation.basePose(m.arm).linear() * estimated.head<3>();
      const double error = (force - simulation.clothWrench(m.arm).head<3>()).norm();
      error_sum += error;
      out.max_force_error = std::max(out.max_force_error, error);
    }
    if (k % path_every == 0) {
      path_times.push_back(t);
      joints.push_back(measured[static_cast<std::size_t>(m.arm)].position);
      tools.push_back(simulation.toolPose(m.arm).translation());
    }
    if (cloth_every > 0 && k % cloth_every == 0) {
      out.cloth_frames.push_back(simulation.cloth().vertices());
      cloth_times.push_back(t);
    }
    const sim::SimStatus status_after = simulation.step();
    if (status_after == sim::SimStatus::ArmDiverged) fail(FoldOutcome::SimulationDiverged, "an arm diverged", t);
    if (status_after == sim::SimStatus::ClothDiverged) fail(FoldOutcome::SimulationDiverged, "the scarf diverged", t);
  }
  out.mean_abs_torque = torque_samples > 0 ? torque_sum / torque_samples : 0.0;
  out.mean_tool_force = torque_samples > 0 ? force_sum / torque_samples : 0.0;
  out.mean_force_error = torque_samples > 0 ? error_sum / torque_samples : 0.0;
  const std::size_t samples = path_times.size();
  out.joint_path.resize(n, static_cast<Eigen::Index>(samples));
  out.tool_path.resize(3, static_cast<Eigen::Index>(samples));
  for (std::size_t i = 0; i < samples; ++i) {
    out.joint_path.col(static_cast<Eigen::Index>(i)) = joints[i];
    out.tool_path.col(static_cast<Eigen::Index>(i)) = tools[i];
  }
  path_times.resize(samples);
  out.path_times = Eigen::Map<const Eigen::VectorXd>(path_times.data(), static_cast<Eigen::Index>(samples));
  out.cloth_times =
      Eigen::Map<const Eigen::VectorXd>(cloth_times.data(), static_cast<Eigen::Index>(cloth_times.size()));
  out.cloth_vertices = simulation.cloth().vertices();
  const sim::ClothParameters& cloth = simulation.cloth().parameters();
  out.truth = scarfTruth(m.mannequin, out.cloth_vertices, cloth.nodes_x, cloth.nodes_y);
  std::mt19937 rng(seed);
  if (m.renderer->render(out.cloth_vertices, simulation.cloth().triangles(), rng) == vision::VisionStatus::Ok) {
    out.bgr = m.renderer->bgr().clone();
    out.camera = scarfCameraTerms(out.bgr, c.camera);
  } else {
    out.camera = scarfCameraTerms(cv::Mat(m.camera.height, m.camera.width, CV_8UC3, cv::Scalar(0, 0, 0)), c.camera);
  }
  scoreScarfRollout(c, out);
  out.simulated_seconds = simulation.time();
  out.wall_seconds = realtime::secondsSince(wall_start);
  out.cloth_wall_seconds = simulation.timings().cloth.wall();
  return out;
}

}  // namespace bimanual_skills::tasks
