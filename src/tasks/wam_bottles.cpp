#include "bimanual_skills/tasks/wam_bottles.hpp"

#include "bimanual_skills/control/arm_controller.hpp"
#include "bimanual_skills/dynamics/friction_yaml.hpp"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/kinematics/clik.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "bimanual_skills/tasks/in_process_control.hpp"
#include "bimanual_skills/tasks/policy_search_tasks.hpp"
#include "io/yaml_io.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace bimanual_skills::tasks {

namespace {

[[noreturn]] void fail(const std::string& what) {
  throw std::invalid_argument("WAM bottle task: " + what);
}

bool positiveFinite(double v) {
  return std::isfinite(v) && v > 0.0;
}

}  // namespace

void WamBottleConfig::validate() const {
  if (sim_config.empty()) fail("sim_config is empty");
  if (arm.empty()) fail("arm is empty");
  if (!start.allFinite() || !goal.allFinite()) fail("start and goal must be finite");
  if (std::abs(start.z() - goal.z()) > 1e-9) fail("start and goal must be at the same height (the tool keeps it)");
  if (!((goal - start).norm() >= 0.05 && (goal - start).norm() <= 3.0)) fail("the line must be 0.05 m to 3 m long");
  if (!(duration >= 0.1 && duration <= 60.0)) fail("duration must lie in [0.1, 60] s");
  if (!(hold_before >= 0.0 && hold_before <= 10.0) || !(settle >= 0.0 && settle <= 10.0)) {
    fail("hold_before and settle must lie in [0, 10] s");
  }
  if (!(tilt > 0.0 && tilt < 1.5707963267948966)) fail("tilt must lie in (0, 90) degrees");
  if (!positiveFinite(max_ik_error) || !positiveFinite(max_tracking_error)) {
    fail("max_ik_error and max_tracking_error must be > 0");
  }
  if (!std::isfinite(velocity_limit)) fail("velocity_limit must be finite");
  if (!std::isfinite(failure_reward)) fail("failure_reward must be finite");
  if (!(path_rate >= 1.0 && path_rate <= 1000.0)) fail("path_rate must lie in [1, 1000] per second");
}

WamBottleConfig WamBottleConfig::fromYamlFile(const std::string& path) {
  const std::string where = "WAM bottle task '" + path + "'";
  const YAML::Node root = io::loadYamlFile(path, where);
  io::checkKeys(root, where,
                {"sim_config", "arm", "start", "goal", "duration", "hold_before", "settle", "crossing_term", "tilt_deg",
                 "max_ik_error", "max_tracking_error", "velocity_limit", "failure_reward", "path_rate"});
  WamBottleConfig c;
  c.sim_config = io::resolvePath(path, io::readString(root, "sim_config", where));
  if (root["arm"]) c.arm = io::readString(root, "arm", where);
  if (root["start"]) c.start = io::readVector(root, "start", where, 3);
  if (root["goal"]) c.goal = io::readVector(root, "goal", where, 3);
  c.duration = io::readDouble(root, "duration", where, c.duration);
  c.hold_before = io::readDouble(root, "hold_before", where, c.hold_before);
  c.settle = io::readDouble(root, "settle", where, c.settle);
  if (root["crossing_term"]) c.crossing_term = io::readBool(root, "crossing_term", where);
  if (root["tilt_deg"]) c.tilt = io::readDouble(root, "tilt_deg", where) * M_PI / 180.0;
  c.max_ik_error = io::readDouble(root, "max_ik_error", where, c.max_ik_error);
  c.max_tracking_error = io::readDouble(root, "max_tracking_error", where, c.max_tracking_error);
  c.velocity_limit = io::readDouble(root, "velocity_limit", where, c.velocity_limit);
  c.failure_reward = io::readDouble(root, "failure_reward", where, c.failure_reward);
  c.path_rate = io::readDouble(root, "path_rate", where, c.path_rate);
  io::withContext(where, [&] { c.validate(); });
  return c;
}

std::string WamBottleConfig::toYaml() const {
  YAML::Emitter out;
  out << YAML::BeginMap << YAML::Key << "sim_config" << YAML::Value << sim_config << YAML::Key << "arm" << YAML::Value
      << arm;
  io::writeVector(out, "start", start);
  io::writeVector(out, "goal", goal);
  out << YAML::Key << "duration" << YAML::Value << duration << YAML::Key << "hold_before" << YAML::Value << hold_before
      << YAML::Key << "settle" << YAML::Value << settle << YAML::Key << "crossing_term" << YAML::Value << crossing_term
      << YAML::Key << "tilt_deg" << YAML::Value << tilt * 180.0 / M_PI << YAML::Key << "max_ik_error" << YAML::Value
      << max_ik_error << YAML::Key << "max_tracking_error" << YAML::Value << max_tracking_error << YAML::Key
      << "velocity_limit" << YAML::Value << velocity_limit << YAML::Key << "failure_reward" << YAML::Value
      << failure_reward << YAML::Key << "path_rate" << YAML::Value << path_rate << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

struct WamBottleTask::Impl {
  WamBottleConfig config;
  sim::SimConfig sim_config;
  int arm = 0, joints = 0;
  std::vector<int> bottles;     ///< Indices of the free obstacles in sim_config.obstacles.
  Eigen::Vector3d along, left;  ///< Unit vectors of the line (world).
  double length = 0.0;
  DmpRollout policy = BottleTask::initialPolicy();
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();
  Eigen::Matrix3d orientation;  ///< Of the tool in the world, kept along the line.
  std::unique_ptr<kinematics::ChainModel> model;
  std::vector<sim::ArmState> start;
  std::vector<std::vector<std::string>> joint_names;
  control::ComputedTorqueGains gains;
  std::vector<dynamics::FrictionModel> friction;
  std::vector<control::ArmControllerConfig> controller_configs;

  Eigen::Vector2d toLine(const Eigen::Vector3d& world) const {
    const Eigen::Vector3d d = world - config.start;
    return Eigen::Vector2d(d.dot(along), d.dot(left)) / length;
  }
  Eigen::Vector3d fromLine(const Eigen::Vector2d& p) const {
    return config.start + length * (p.x() * along + p.y() * left);
  }
};

WamBottleTask::WamBottleTask(const WamBottleConfig& config) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  config.validate();
  m.config = config;
  m.sim_config = sim::SimConfig::fromYamlFile(config.sim_config);
  if (m.sim_config.has_cloth) fail("'" + config.sim_config + "' has a cloth");
  for (std::size_t k = 0; k < m.sim_config.obstacles.size(); ++k) {
    if (m.sim_config.obstacles[k].mass > 0.0) m.bottles.push_back(static_cast<int>(k));
  }
  if (m.bottles.size() != 2) {
    fail("'" + config.sim_config + "' needs exactly two free obstacles (with a mass), the bottles; it has " +
         std::to_string(m.bottles.size()));
  }
  const sim::BimanualSimulation simulation(m.sim_config);
  m.arm = simulation.armIndex(config.arm);
  if (m.arm < 0) fail("no arm '" + config.arm + "' in '" + config.sim_config + "'");
  m.joints = simulation.jointCount(m.arm);
  m.length = (config.goal - config.start).norm();
  m.along = (config.goal - config.start) / m.length;
  m.left = Eigen::Vector3d::UnitZ().cross(m.along);
  for (const int b : m.bottles) {
    const Eigen::Vector2d on = m.toLine(m.sim_config.obstacles[static_cast<std::size_t>(b)].pose.translation());
    if (!(on.x() > 0.0 && on.x() < 1.0)) {
      fail("bottle '" + m.sim_config.obstacles[static_cast<std::size_t>(b)].name + "' is not between start and goal");
    }
  }
  // Bottles ordered along the line.
  if (m.toLine(m.sim_config.obstacles[static_cast<std::size_t>(m.bottles[0])].pose.translation()).x() >
      m.toLine(m.sim_config.obstacles[static_cast<std::size_t>(m.bottles[1])].pose.translation()).x()) {
    std::swap(m.bottles[0], m.bottles[1]);
  }
  m.base = simulation.basePose(m.arm);
  m.model = std::make_unique<kinematics::ChainModel>(simulation.armModel(m.arm));
  for (int a = 0; a < simulation.armCount(); ++a) {
    const sim::ArmConfig& arm = m.sim_config.arms[static_cast<std::size_t>(a)];
    if (arm.start.size() == 0) fail("arm '" + arm.name + "' has no start posture");
    m.start.push_back({arm.start, Eigen::VectorXd::Zero(arm.start.size())});
    m.joint_names.push_back(simulation.armModel(a).jointNames());
  }
  kinematics::ChainData fk(*m.model);
  Eigen::VectorXd& q = m.start[static_cast<std::size_t>(m.arm)].q;
  (void)kinematics::forwardKinematics(*m.model, fk, q);
  m.orientation = m.base.linear() * fk.tipPose().linear();
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
  tool.linear() = m.orientation;
  tool.translation() = config.start;
  const kinematics::ClikParameters clik;
  kinematics::ClikData clik_data(*m.model, clik);
  const kinematics::IkResult ik = kinematics::solve(*m.model, clik, clik_data, q, m.base.inverse() * tool);
  if (ik.status != kinematics::IkStatus::Converged || !m.model->withinLimits(q, 0.0)) {
    fail("arm '" + config.arm + "' cannot reach the line's start from its start posture (" +
         kinematics::toString(ik.status) + ", residual " + std::to_string(ik.residual) + ")");
  }

  m.gains.kp = m.sim_config.kp;
  m.gains.kv = m.sim_config.kv;
  if (m.gains.kp.size() == 0 || m.gains.kv.size() == 0) {
    fail("no controller gains in the robot file of '" + config.sim_config + "'");
  }
  const Eigen::VectorXd velocity_limit =
      config.velocity_limit > 0.0 ? Eigen::VectorXd::Constant(1, config.velocity_limit) : Eigen::VectorXd();
  for (int a = 0; a < simulation.armCount(); ++a) {
    const std::string& file = m.sim_config.arms[static_cast<std::size_t>(a)].friction_file;
    dynamics::FrictionModel model;
    if (file.empty()) {
      model.joints.assign(static_cast<std::size_t>(simulation.jointCount(a)), dynamics::JointFriction{});
    } else {
      model = dynamics::loadFrictionModel(file);
    }
    m.friction.push_back(model);
    m.controller_configs.push_back(inProcessControllerConfig(simulation.armModel(a), m.gains, !file.empty(),
                                                             simulation.stepSize(), velocity_limit, 2));
  }
}

WamBottleTask::~WamBottleTask() = default;

const WamBottleConfig& WamBottleTask::config() const noexcept {
  return impl_->config;
}

Eigen::VectorXd WamBottleTask::initialParameters() const {
  return impl_->policy.parameters();
}

int WamBottleTask::kernels() const noexcept {
  return impl_->policy.dmp.parameters().kernels;
}

int WamBottleTask::arm() const noexcept {
  return impl_->arm;
}

const std::vector<std::vector<std::string>>& WamBottleTask::jointNames() const noexcept {
  return impl_->joint_names;
}

std::vector<Eigen::VectorXd> WamBottleTask::starts() const {
  std::vector<Eigen::VectorXd> out;
  for (const sim::ArmState& s : impl_->start) out.push_back(s.q);
  return out;
}

const sim::SimConfig& WamBottleTask::simConfig() const noexcept {
  return impl_->sim_config;
}

Eigen::Vector2d WamBottleTask::bottleOnLine(int k) const {
  if (k < 0 || k > 1) throw std::out_of_range("WAM bottle task: bottle " + std::to_string(k) + " of 2");
  const Impl& m = *impl_;
  return m.toLine(
      m.sim_config.obstacles[static_cast<std::size_t>(m.bottles[static_cast<std::size_t>(k)])].pose.translation());
}

double WamBottleTask::lineLength() const noexcept {
  return impl_->length;
}

double WamBottleTask::bottleRadius() const noexcept {
  return impl_->sim_config.obstacles[static_cast<std::size_t>(impl_->bottles[0])].size.x();
}

Eigen::Vector2d WamBottleTask::toLine(const Eigen::Vector3d& world) const {
  return impl_->toLine(world);
}

Eigen::Vector3d WamBottleTask::fromLine(const Eigen::Vector2d& line) const {
  return impl_->fromLine(line);
}

namespace {

WamBottleRollout failedRollout(FoldOutcome outcome, const std::string& reason, double reward,
                               std::chrono::steady_clock::time_point wall_start) {
  WamBottleRollout out;
  out.outcome = outcome;
  out.reason = reason;
  out.reward = reward;
  out.wall_seconds = realtime::secondsSince(wall_start);
  return out;
}

}  // namespace

WamBottleRollout WamBottleTask::run(const Eigen::VectorXd& theta, std::uint32_t seed) {
  Impl& m = *impl_;
  const auto wall_start = std::chrono::steady_clock::now();
  const int kernels = m.policy.dmp.parameters().kernels;
  if (theta.size() != 2 * kernels || !theta.allFinite()) {
    return failedRollout(FoldOutcome::InvalidPolicy,
                         "the policy needs " + std::to_string(2 * kernels) + " finite weights, got " +
                             std::to_string(theta.size()) + (theta.allFinite() ? "" : " with NaN/Inf"),
                         m.config.failure_reward, wall_start);
  }
  // The DMP at the simulation's step over the motion and on while the arm settles (it converges to the goal).
  const double dt = m.sim_config.step;
  Eigen::MatrixXd w(2, kernels);
  for (int d = 0; d < 2; ++d) w.row(d) = theta.segment(d * kernels, kernels).transpose();
  const primitives::Dmp dmp = m.policy.dmp.withDuration(m.config.duration).withWeights(w);
  const int move = static_cast<int>(std::lround((m.config.duration + m.config.settle) / dt));
  Eigen::Matrix2Xd path(2, move + 1);
  primitives::DmpState state = dmp.initialState();
  path.col(0) = state.y;
  for (int k = 1; k <= move; ++k) {
    if (dmp.step(state, dt) != primitives::DmpStatus::Success) {
      return failedRollout(FoldOutcome::InvalidPolicy, "the DMP step failed at " + std::to_string(k * dt) + " s",
                           m.config.failure_reward, wall_start);
    }
    path.col(k) = state.y;
  }
  WamBottleRollout out = runPath(path, seed);
  out.wall_seconds = realtime::secondsSince(wall_start);
  return out;
}

void WamBottleTask::score(WamBottleRollout& out, int down) const {
  const Impl& m = *impl_;
  out.length = 0.0;
  out.max_height_error = 0.0;
  for (Eigen::Index i = 0; i < out.tool_path.cols(); ++i) {
    out.max_height_error = std::max(out.max_height_error, std::abs(out.tool_path(2, i) - m.config.start.z()));
    if (i > 0) out.length += (out.tool_path.col(i) - out.tool_path.col(i - 1)).norm();
  }
  for (int b = 0; b < 2; ++b) {
    const Eigen::Vector2d bottle = bottleOnLine(b);
    double side = 0.0;
    for (Eigen::Index i = 0; i < out.tool_path.cols(); ++i) {
      const Eigen::Vector2d p = m.toLine(out.tool_path.col(i));
      if (p.x() >= bottle.x()) {
        side = (p.y() - bottle.y()) * m.length;
        break;
      }
    }
    out.sides[static_cast<std::size_t>(b)] = side;
  }
  out.down = down;
  out.crossed = out.sides[0] * out.sides[1] < 0.0;
  out.satisfactory = out.crossed && out.down == 0;
  out.reward = -2.0 * out.down - 0.15 * out.length - (m.config.crossing_term && !out.crossed ? 4.0 : 0.0);
}

WamBottleRollout WamBottleTask::runPath(const Eigen::Matrix2Xd& path, std::uint32_t seed) {
  Impl& m = *impl_;
  WamBottleRollout out;
  const auto wall_start = std::chrono::steady_clock::now();
  const auto failed = [&](FoldOutcome outcome, const std::string& reason) {
    return failedRollout(outcome, reason, m.config.failure_reward, wall_start);
  };
  if (path.cols() < 2 || !path.allFinite()) {
    return failed(FoldOutcome::InvalidPolicy, "the path needs at least two finite points");
  }
  if ((path.col(0) - Eigen::Vector2d::Zero()).norm() > 1e-6) {
    return failed(FoldOutcome::InvalidPolicy, "the path must start at the line's start (0, 0)");
  }

  // The plan: each period's tool pose on the path solved by one CLIK step from the last; the references' velocities
  // and accelerations are the differences of the solutions.
  sim::SimConfig sim_config = m.sim_config;
  sim_config.seed = seed;
  sim::BimanualSimulation simulation(sim_config);
  const double dt = simulation.stepSize();
  const int hold = static_cast<int>(std::lround(m.config.hold_before / dt));
  const int move = static_cast<int>(path.cols()) - 1;
  const int periods = hold + move + 1;
  const int n = m.joints;
  Eigen::MatrixXd position(n, periods), velocity = Eigen::MatrixXd::Zero(n, periods),
                                        acceleration = Eigen::MatrixXd::Zero(n, periods);
  Eigen::Matrix3Xd planned(3, move + 1);
  const kinematics::ClikParameters clik;
  kinematics::ClikData clik_data(*m.model, clik);
  kinematics::ChainData fk(*m.model);
  Eigen::VectorXd q = m.start[static_cast<std::size_t>(m.arm)].q;
  position.leftCols(hold + 1).colwise() = q;
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  target.linear() = m.orientation;
  planned.col(0) = m.fromLine(path.col(0));
  for (int k = 1; k <= move; ++k) {
    planned.col(k) = m.fromLine(path.col(k));
    target.translation() = planned.col(k);
    const Eigen::Isometry3d in_base = m.base.inverse() * target;
    if (kinematics::step(*m.model, clik, clik_data, q, in_base) != kinematics::IkStatus::StepComputed) {
      return failed(FoldOutcome::IkFailed, "CLIK failed at " + std::to_string(k * dt) + " s");
    }
    q += clik_data.dq;
    (void)kinematics::forwardKinematics(*m.model, fk, q);
    out.max_ik_error = std::max(out.max_ik_error, (fk.tipPose().translation() - in_base.translation()).norm());
    if (!m.model->withinLimits(q, 0.0)) {
      return failed(FoldOutcome::OutOfLimits,
                    "the references leave the joint limits at " + std::to_string(k * dt) + " s");
    }
    position.col(hold + k) = q;
  }
  if (out.max_ik_error > m.config.max_ik_error) {
    return failed(FoldOutcome::IkFailed, "the planned tool is " + std::to_string(out.max_ik_error) +
                                             " m off the DMP's path (out of the arm's reach)");
  }
  for (int k = hold + 1; k < periods; ++k) {
    velocity.col(k) = (position.col(k) - position.col(k - 1)) / dt;
    acceleration.col(k) = (velocity.col(k) - velocity.col(k - 1)) / dt;
  }

  // The rollout: every arm's ArmController from its start; the moving arm's tracks the plan.
  if (simulation.reset(m.start) != sim::SimStatus::Ok) throw std::logic_error("WAM bottle task: reset rejected");
  std::vector<std::unique_ptr<control::ArmController>> controllers;
  for (int a = 0; a < simulation.armCount(); ++a) {
    control::ArmControllerConfig c = m.controller_configs[static_cast<std::size_t>(a)];
    c.trajectory_capacity = a == m.arm ? periods : 2;
    controllers.push_back(
        std::make_unique<control::ArmController>(simulation.armModel(a), m.friction[static_cast<std::size_t>(a)], c));
  }
  const control::Waypoints waypoints = plannedWaypoints(position, velocity, acceleration, 0, dt);
  const int path_every = std::max(1, static_cast<int>(std::lround(1.0 / (m.config.path_rate * dt))));
  std::vector<Eigen::Vector3d> tool;
  std::vector<Eigen::VectorXd> joints;
  std::vector<double> times;
  sim::JointState measured(n);
  Eigen::VectorXd torque(n);
  for (int k = 0; k < periods; ++k) {
    const double now = simulation.time();
    if (k >= hold && (k - hold) % path_every == 0) {
      tool.push_back(simulation.toolPose(m.arm).translation());
      simulation.readJointState(m.arm, measured);
      joints.push_back(measured.position);
      for (const int b : m.bottles) out.bottle_path.push_back(simulation.obstaclePose(b));
      times.push_back(now - hold * dt);
    }
    for (int a = 0; a < simulation.armCount(); ++a) {
      control::ArmController& controller = *controllers[static_cast<std::size_t>(a)];
      simulation.readJointState(a, measured);
      const control::ControllerStatus status =
          controller.update(now, now, measured.position, measured.velocity, torque);
      const std::string stop = controllerStopReason(status, a, measured.velocity,
                                                    m.controller_configs[static_cast<std::size_t>(a)].velocity_limit);
      if (!stop.empty()) return failed(FoldOutcome::ControllerFailed, stop + " at " + std::to_string(now) + " s");
      if (k == 0 && a == m.arm && controller.setTrajectory(waypoints) != control::TrajectoryStatus::Ok) {
        throw std::logic_error("WAM bottle task: the controller refused the planned references");
      }
      const double tracking = controller.trackingError().cwiseAbs().maxCoeff();
      if (a == m.arm) out.max_tracking_error = std::max(out.max_tracking_error, tracking);
      if (tracking > m.config.max_tracking_error) {
        return failed(FoldOutcome::ControllerFailed, "arm " + std::to_string(a) + " is " + std::to_string(tracking) +
                                                         " rad off its references at " + std::to_string(now) + " s");
      }
      simulation.writeJointTorques(a, torque);
    }
    if (simulation.step() == sim::SimStatus::ArmDiverged) {
      return failed(FoldOutcome::SimulationDiverged, "an arm diverged at " + std::to_string(now) + " s");
    }
  }

  out.tool_path.resize(3, static_cast<Eigen::Index>(tool.size()));
  out.path_times.resize(static_cast<Eigen::Index>(times.size()));
  out.joint_path.resize(n, static_cast<Eigen::Index>(joints.size()));
  for (std::size_t i = 0; i < tool.size(); ++i) {
    out.tool_path.col(static_cast<Eigen::Index>(i)) = tool[i];
    out.joint_path.col(static_cast<Eigen::Index>(i)) = joints[i];
    out.path_times[static_cast<Eigen::Index>(i)] = times[i];
  }
  out.planned_path = planned;
  for (int b = 0; b < 2; ++b) {
    out.bottles[static_cast<std::size_t>(b)] = simulation.obstaclePose(m.bottles[static_cast<std::size_t>(b)]);
  }
  score(out, simulation.knockedOver(m.config.tilt));
  out.simulated_seconds = simulation.time();
  out.wall_seconds = realtime::secondsSince(wall_start);
  return out;
}

}  // namespace bimanual_skills::tasks
