#include "bimanual_skills/sim/bimanual_simulation.hpp"

#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bullet_arm.hpp"
#include "bullet_conversions.hpp"
#include "scene_bodies.hpp"

#include <BulletDynamics/Featherstone/btMultiBodyConstraintSolver.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

namespace bimanual_skills::sim {
namespace {

using realtime::Clock;
using realtime::seconds;

/// Joint speed beyond which an arm counts as diverged [rad/s or m/s] (the WAM's joints stay below 3 rad/s).
constexpr double kDivergedSpeed = 100.0;

/// A held external wrench on one moving frame of an arm.
struct HeldWrench {
  bool active = false;
  Eigen::Vector3d force = Eigen::Vector3d::Zero();   ///< World frame [N].
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();  ///< World frame [N m].
  Eigen::Vector3d point = Eigen::Vector3d::Zero();   ///< Application point in the frame [m].
};

/// Bullet's multibody world without the per-step prediction of the links' next poses (an extra forward-kinematics
/// pass per multibody that only continuous collision detection of rigid bodies and interpolated rendering read;
/// the arms' collisions are discrete). About 5 % of the two-arm step.
class ArmsDynamicsWorld : public btMultiBodyDynamicsWorld {
 public:
  using btMultiBodyDynamicsWorld::btMultiBodyDynamicsWorld;

 protected:
  void predictUnconstraintMotion(btScalar time_step) override {
    btDiscreteDynamicsWorld::predictUnconstraintMotion(time_step);
  }
};

/// The arms' Bullet world (rebuilt from scratch on reset, so a reset simulation has no warm-start caches).
struct ArmsWorld {
  ArmsWorld(const std::vector<UrdfArm>& arms, const SimConfig& config) {
    configuration = std::make_unique<btDefaultCollisionConfiguration>();
    dispatcher = std::make_unique<btCollisionDispatcher>(configuration.get());
    broadphase = std::make_unique<btDbvtBroadphase>();
    solver = std::make_unique<btMultiBodyConstraintSolver>();
    world = std::make_unique<ArmsDynamicsWorld>(dispatcher.get(), broadphase.get(), solver.get(), configuration.get());
    world->setGravity(toBullet(config.gravity));
    if (config.has_table) {
      table_shape = std::make_unique<btBoxShape>(toBullet(Eigen::Vector3d(0.5 * config.table.size)));
      btRigidBody::btRigidBodyConstructionInfo info(0.0, nullptr, table_shape.get());
      info.m_startWorldTransform = toBulletTransform(config.table.pose);
      info.m_friction = config.table.friction;
      table = std::make_unique<btRigidBody>(info);
      world->addRigidBody(table.get());
    }
    obstacles = std::make_unique<SceneBodies>(*world, config.obstacles);
    if (config.has_object && config.object.body.collides) {
      // Kinematic: the path (or the gripper) moves it, contacts do not; Bullet takes its velocity from the motion
      // state's change over a step.
      object_shape = obstacleShape(config.object.body);
      btRigidBody::btRigidBodyConstructionInfo info(0.0, &object_motion, object_shape.get());
      info.m_friction = config.object.body.friction;
      object = std::make_unique<btRigidBody>(info);
      object->setCollisionFlags(object->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
      object->setActivationState(DISABLE_DEACTIVATION);
      world->addRigidBody(object.get());
    }
    for (std::size_t a = 0; a < arms.size(); ++a) {
      bullet_arms.push_back(std::make_unique<BulletArm>(arms[a], static_cast<int>(a), *world));
    }
  }
  ~ArmsWorld() {
    bullet_arms.clear();
    obstacles.reset();
    if (object) world->removeRigidBody(object.get());
    if (table) world->removeRigidBody(table.get());
  }

  /// Moves the kinematic object (when the arms feel it) to `pose` over the next step.
  void moveObject(const Eigen::Isometry3d& pose) noexcept {
    if (!object) return;
    object_motion.setWorldTransform(toBulletTransform(pose));
  }
  /// A held object is part of the hand (its shape overlaps the hand's): no contact response with the arms from its
  /// grasp until the world is rebuilt (a reset), also once let go where it was (inside the open hand).
  void holdObject() noexcept {
    if (object) object->setCollisionFlags(object->getCollisionFlags() | btCollisionObject::CF_NO_CONTACT_RESPONSE);
  }
  ArmsWorld(const ArmsWorld&) = delete;
  ArmsWorld& operator=(const ArmsWorld&) = delete;

  std::unique_ptr<btDefaultCollisionConfiguration> configuration;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<btMultiBodyConstraintSolver> solver;
  std::unique_ptr<btMultiBodyDynamicsWorld> world;
  std::unique_ptr<btBoxShape> table_shape;
  std::unique_ptr<btRigidBody> table;
  std::unique_ptr<SceneBodies> obstacles;
  std::unique_ptr<btCollisionShape> object_shape;
  btDefaultMotionState object_motion;
  std::unique_ptr<btRigidBody> object;
  std::vector<std::unique_ptr<BulletArm>> bullet_arms;
};

}  // namespace

struct BimanualSimulation::Impl {
  /// Everything about one arm that is not Bullet's.
  struct Arm {
    Arm(const ArmConfig& c, UrdfArm u, const ArmPlantParameters& parameters)
        : config(c), urdf(std::move(u)), plant(urdf.model, parameters), kinematics(urdf.model) {
      const int n = urdf.model.nq();
      state.q = Eigen::VectorXd::Zero(n);
      state.qd = Eigen::VectorXd::Zero(n);
      for (Eigen::VectorXd* v :
           {&command, &applied, &tau_ext, &qdd, &rigid_body_torque, &q_measured, &qd_measured, &last_qdd, &qd_before}) {
        v->setZero(n);
      }
      jacobian.setZero(6, n);
      wrenches.resize(static_cast<std::size_t>(n + 1));
      cloth_wrench.setZero();
    }

    ArmConfig config;
    UrdfArm urdf;
    ArmPlant plant;
    kinematics::ChainData kinematics;
    ArmState state;
    Eigen::VectorXd command, applied, tau_ext, qdd, rigid_body_torque, q_measured, qd_measured, last_qdd, qd_before;
    kinematics::Matrix6Xd jacobian;
    dynamics::Payload payload;
    std::vector<HeldWrench> wrenches;  ///< One per frame of the model (moving links, then the tip).
    Vector6d cloth_wrench;
  };

  SimConfig config;
  std::mt19937 rng;
  std::vector<Arm> arms;
  std::unique_ptr<ArmsWorld> bullet;
  std::optional<Cloth> cloth;
  int cloth_period = 1;  ///< Arm steps per cloth step.
  std::optional<ObjectPath> object_path;
  int object_holder = -1;       ///< The arm holding the object, −1 for none.
  bool object_resting = false;  ///< Let go: it rests at object_pose until reset.
  bool object_carried = false;  ///< A person carries it toward object_target (carryObject) until reset.
  Eigen::Vector3d object_target = Eigen::Vector3d::Zero();
  double object_placed = 0.0;  ///< The time object_pose was placed for.
  Eigen::Isometry3d object_pose = Eigen::Isometry3d::Identity(), object_in_tool = Eigen::Isometry3d::Identity();
  Eigen::Vector3d object_velocity = Eigen::Vector3d::Zero();
  long step_index = 0;
  double time = 0.0;
  bool arms_diverged = false;
  SimTimings timings;

  void measure() noexcept {
    for (Arm& arm : arms) arm.plant.measure(arm.state.q, arm.state.qd, rng, arm.q_measured, arm.qd_measured);
  }

  /// Tool pose and twist (world frame) of an arm at its current state.
  void toolMotion(Arm& arm, const Eigen::Isometry3d& base, Eigen::Isometry3d& pose, Vector6d& twist) noexcept {
    (void)kinematics::computeJacobian(arm.urdf.model, arm.kinematics, arm.state.q);
    pose = base * arm.kinematics.tipPose();
    const Vector6d base_twist = arm.kinematics.jacobian * arm.state.qd;
    twist.head<3>() = base.linear() * base_twist.head<3>();
    twist.tail<3>() = base.linear() * base_twist.tail<3>();
  }

  /// τ_ext = Σ Jᵀ [F; M] of the held wrenches and the cloth's, at the current state (base-frame Jacobians).
  void externalTorques(Arm& arm) noexcept {
    arm.tau_ext.setZero();
    const bool cloth_pull = !arm.cloth_wrench.isZero(0.0);
    bool any = cloth_pull;
    for (const HeldWrench& w : arm.wrenches) any = any || w.active;
    if (!any) return;
    const kinematics::ChainModel& model = arm.urdf.model;
    if (kinematics::forwardKinematics(model, arm.kinematics, arm.state.q) != kinematics::KinematicsStatus::Success) {
      return;
    }
    const Eigen::Matrix3d world_to_base = arm.urdf.base_pose.linear().transpose();
    const auto add = [&](int frame, const Eigen::Vector3d& force, const Eigen::Vector3d& torque) {
      if (kinematics::frameJacobian(model, arm.kinematics, frame, kinematics::JacobianFrame::Base, arm.jacobian) !=
          kinematics::KinematicsStatus::Success) {
        return;
      }
      arm.tau_ext.noalias() += arm.jacobian.topRows<3>().transpose() * (world_to_base * force);
      arm.tau_ext.noalias() += arm.jacobian.bottomRows<3>().transpose() * (world_to_base * torque);
    };
    for (std::size_t f = 0; f < arm.wrenches.size(); ++f) {
      const HeldWrench& w = arm.wrenches[f];
      if (!w.active) continue;
      // Moment about the frame's origin of the force applied at `point`.
      const Eigen::Vector3d lever = arm.urdf.base_pose.linear() * (arm.kinematics.frame_poses[f].linear() * w.point);
      add(static_cast<int>(f), w.force, w.torque + lever.cross(w.force));
    }
    if (cloth_pull) add(model.nq(), arm.cloth_wrench.head<3>(), arm.cloth_wrench.tail<3>());
  }

  /// The object where it is at time `t` (on its path, resting, or in its holder's gripper at the current state).
  void placeObject(double t) noexcept {
    if (!object_path) return;
    if (object_holder >= 0) {
      Arm& arm = arms[static_cast<std::size_t>(object_holder)];
      Eigen::Isometry3d tool;
      Vector6d twist;
      toolMotion(arm, arm.urdf.base_pose, tool, twist);
      const Eigen::Isometry3d pose = tool * object_in_tool;
      object_velocity = twist.head<3>() + twist.tail<3>().cross(pose.translation() - tool.translation());
      object_pose = pose;
    } else if (object_resting) {
      object_velocity.setZero();
    } else if (object_carried) {
      // Critically damped toward the hand, within the path's speed and acceleration bounds.
      const double dt = t - object_placed;
      if (dt > 0.0) {
        const double omega = 1.0 / kCarryTimeConstant;
        const Eigen::Vector3d p = object_pose.translation();
        Eigen::Vector3d a = omega * omega * (object_target - p) - 2.0 * omega * object_velocity;
        const double max_a = config.object.path.max_acceleration, max_v = config.object.path.max_speed;
        if (a.norm() > max_a) a *= max_a / a.norm();
        object_velocity += a * dt;
        if (object_velocity.norm() > max_v) object_velocity *= max_v / object_velocity.norm();
        object_pose.setIdentity();
        object_pose.translation() = p + object_velocity * dt;
      }
    } else {
      const ObjectPathSample sample = object_path->at(t);
      object_pose.setIdentity();
      object_pose.translation() = sample.position;
      object_velocity = sample.velocity;
    }
    object_placed = t;
  }
  static constexpr double kCarryTimeConstant = 0.1;  ///< [s] of the carried object's follower.

  void rebuildBullet() {
    bullet.reset();
    std::vector<UrdfArm> urdf_arms;
    for (const Arm& arm : arms) urdf_arms.push_back(arm.urdf);
    bullet = std::make_unique<ArmsWorld>(urdf_arms, config);
    for (std::size_t a = 0; a < arms.size(); ++a) bullet->bullet_arms[a]->setState(arms[a].state.q, arms[a].state.qd);
    if (object_path) {
      placeObject(time);
      bullet->object_motion.setWorldTransform(toBulletTransform(object_pose));
      if (bullet->object) bullet->object->setWorldTransform(toBulletTransform(object_pose));
    }
  }
};

BimanualSimulation::BimanualSimulation(const SimConfig& config)
    : BimanualSimulation(config, std::mt19937(config.seed)) {}

BimanualSimulation::BimanualSimulation(const SimConfig& config, std::mt19937 rng) : impl_(std::make_unique<Impl>()) {
  config.validate();
  Impl& m = *impl_;
  m.config = config;
  m.rng = rng;
  m.arms.reserve(config.arms.size());
  for (const ArmConfig& arm : config.arms) {
    UrdfArm urdf = loadUrdfArm(config.urdf_path, arm, config.gravity);
    const ArmPlantParameters& parameters = config.plant.arm(arm.name);
    m.arms.emplace_back(arm, std::move(urdf), parameters);
  }
  if (config.has_cloth) {
    m.cloth.emplace(config.cloth, config.has_table ? std::optional<Table>(config.table) : std::nullopt,
                    static_cast<int>(m.arms.size()), config.gravity, config.obstacles);
    m.cloth_period = static_cast<int>(std::lround(config.cloth.step / config.step));
  }
  if (config.has_object) m.object_path.emplace(config.object.path);
  m.rebuildBullet();
  m.measure();
}

BimanualSimulation::~BimanualSimulation() = default;

int BimanualSimulation::armCount() const noexcept {
  return static_cast<int>(impl_->arms.size());
}

int BimanualSimulation::jointCount(int arm) const noexcept {
  if (arm < 0 || arm >= armCount()) return 0;
  return impl_->arms[static_cast<std::size_t>(arm)].urdf.model.nq();
}

RobotStatus BimanualSimulation::readJointState(int arm, JointState& state) noexcept {
  if (arm < 0 || arm >= armCount()) return RobotStatus::UnknownArm;
  const Impl::Arm& a = impl_->arms[static_cast<std::size_t>(arm)];
  const int n = a.urdf.model.nq();
  if (state.position.size() != n || state.velocity.size() != n || state.effort.size() != n) {
    return RobotStatus::WrongSize;
  }
  state.position = a.q_measured;
  state.velocity = a.qd_measured;
  state.effort = a.applied;
  state.time = impl_->time;
  return impl_->arms_diverged ? RobotStatus::Fault : RobotStatus::Ok;
}

RobotStatus BimanualSimulation::writeJointTorques(int arm, const Eigen::Ref<const Eigen::VectorXd>& torque) noexcept {
  if (arm < 0 || arm >= armCount()) return RobotStatus::UnknownArm;
  Impl::Arm& a = impl_->arms[static_cast<std::size_t>(arm)];
  if (torque.size() != a.urdf.model.nq() || !torque.allFinite()) return RobotStatus::InvalidCommand;
  a.command = torque;
  a.plant.applyTorqueLimits(a.command, a.applied);
  return impl_->arms_diverged ? RobotStatus::Fault : RobotStatus::Ok;
}

SimStatus BimanualSimulation::step() noexcept {
  Impl& m = *impl_;
  if (m.arms_diverged) return SimStatus::ArmDiverged;
  const auto start = Clock::now();
  SimStatus result = SimStatus::Ok;
  const double dt = m.config.step;

  // The cloth, every cloth period: grippers at the tools, one cloth step, its pull held on the tools.
  if (m.cloth && m.cloth->status() == SimStatus::Ok && m.step_index % m.cloth_period == 0) {
    for (std::size_t a = 0; a < m.arms.size(); ++a) {
      Eigen::Isometry3d pose;
      Vector6d twist;
      m.toolMotion(m.arms[a], m.arms[a].urdf.base_pose, pose, twist);
      (void)m.cloth->setGripperMotion(static_cast<int>(a), pose, twist);
    }
    (void)m.cloth->step();
    for (std::size_t a = 0; a < m.arms.size(); ++a) {
      m.arms[a].cloth_wrench = m.cloth->gripperWrench(static_cast<int>(a));
    }
    m.timings.cloth = m.cloth->timings();
  }
  if (m.cloth && m.cloth->status() != SimStatus::Ok) {
    result = m.cloth->status();
    for (Impl::Arm& arm : m.arms) arm.cloth_wrench.setZero();
  }
  const auto cloth_done = Clock::now();

  // The true plant of each arm gives q̈; Bullet gets the torque that reproduces it on its rigid bodies.
  for (std::size_t a = 0; a < m.arms.size(); ++a) {
    Impl::Arm& arm = m.arms[a];
    m.externalTorques(arm);
    if (arm.plant.step(arm.state.q, arm.state.qd, arm.applied, arm.tau_ext, arm.payload, dt, arm.qdd,
                       arm.rigid_body_torque) != SimStatus::Ok) {
      arm.rigid_body_torque.setZero();
    }
    btMultiBody& body = m.bullet->bullet_arms[a]->body();
    for (int j = 0; j < body.getNumLinks(); ++j) body.addJointTorque(j, arm.rigid_body_torque[j]);
    arm.qd_before = arm.state.qd;
  }
  if (m.object_path) {
    // Where the object will be at the step's end (in a gripper: where it is now, one step behind the tool).
    if (m.object_holder < 0) m.placeObject(m.time + dt);
    m.bullet->moveObject(m.object_pose);
  }
  const auto plant_done = Clock::now();
  m.bullet->world->stepSimulation(dt, 0, dt);
  const auto bullet_done = Clock::now();

  for (std::size_t a = 0; a < m.arms.size(); ++a) {
    Impl::Arm& arm = m.arms[a];
    const btMultiBody& body = m.bullet->bullet_arms[a]->body();
    bool finite = true;
    for (int j = 0; j < body.getNumLinks(); ++j) {
      const double q = body.getJointPos(j);
      const double qd = body.getJointVel(j);
      finite = finite && std::isfinite(q) && std::isfinite(qd) && std::abs(qd) < kDivergedSpeed;
    }
    if (!finite) {
      m.arms_diverged = true;
      continue;
    }
    for (int j = 0; j < body.getNumLinks(); ++j) {
      arm.state.q[j] = body.getJointPos(j);
      arm.state.qd[j] = body.getJointVel(j);
    }
    arm.last_qdd = (arm.state.qd - arm.qd_before) / dt;
  }
  m.measure();
  m.time = static_cast<double>(++m.step_index) * dt;
  if (m.object_holder >= 0 && !m.arms_diverged) m.placeObject(m.time);
  const auto done = Clock::now();
  m.timings.total += seconds(start, done);
  m.timings.bullet_arms += seconds(plant_done, bullet_done);
  m.timings.plant += seconds(cloth_done, plant_done) + seconds(bullet_done, done);
  ++m.timings.steps;
  return m.arms_diverged ? SimStatus::ArmDiverged : result;
}

double BimanualSimulation::time() const noexcept {
  return impl_->time;
}
double BimanualSimulation::stepSize() const noexcept {
  return impl_->config.step;
}
const SimConfig& BimanualSimulation::config() const noexcept {
  return impl_->config;
}

int BimanualSimulation::armIndex(const std::string& name) const noexcept {
  for (std::size_t a = 0; a < impl_->arms.size(); ++a) {
    if (impl_->arms[a].config.name == name) return static_cast<int>(a);
  }
  return -1;
}

namespace {
void requireArm(int arm, int count) {
  if (arm < 0 || arm >= count) {
    throw std::out_of_range("bimanual simulation: no arm " + std::to_string(arm) + " (it has " + std::to_string(count) +
                            ")");
  }
}
}  // namespace

const kinematics::ChainModel& BimanualSimulation::armModel(int arm) const {
  requireArm(arm, armCount());
  return impl_->arms[static_cast<std::size_t>(arm)].urdf.model;
}

const ArmPlant& BimanualSimulation::armPlant(int arm) const {
  requireArm(arm, armCount());
  return impl_->arms[static_cast<std::size_t>(arm)].plant;
}

const Eigen::Isometry3d& BimanualSimulation::basePose(int arm) const {
  requireArm(arm, armCount());
  return impl_->arms[static_cast<std::size_t>(arm)].urdf.base_pose;
}

const ArmState& BimanualSimulation::trueState(int arm) const {
  requireArm(arm, armCount());
  return impl_->arms[static_cast<std::size_t>(arm)].state;
}

const Eigen::VectorXd& BimanualSimulation::lastAcceleration(int arm) const {
  requireArm(arm, armCount());
  return impl_->arms[static_cast<std::size_t>(arm)].last_qdd;
}

Eigen::Isometry3d BimanualSimulation::toolPose(int arm) const {
  requireArm(arm, armCount());
  const Impl::Arm& a = impl_->arms[static_cast<std::size_t>(arm)];
  kinematics::ChainData data(a.urdf.model);
  (void)kinematics::forwardKinematics(a.urdf.model, data, a.state.q);
  return a.urdf.base_pose * data.tipPose();
}

SimStatus BimanualSimulation::setPayload(int arm, const dynamics::Payload& payload) noexcept {
  if (arm < 0 || arm >= armCount()) return SimStatus::UnknownArm;
  if (!std::isfinite(payload.mass) || payload.mass < 0.0 || !payload.com.allFinite()) {
    return SimStatus::InvalidArgument;
  }
  impl_->arms[static_cast<std::size_t>(arm)].payload = payload;
  return SimStatus::Ok;
}

LinkHandle BimanualSimulation::link(const std::string& name) const {
  for (std::size_t a = 0; a < impl_->arms.size(); ++a) {
    const auto& links = impl_->arms[a].urdf.links;
    if (const auto it = links.find(name); it != links.end()) {
      return LinkHandle{static_cast<int>(a), it->second.first, it->second.second};
    }
  }
  throw std::invalid_argument("bimanual simulation: unknown link '" + name +
                              "' (not a link that moves with a simulated arm)");
}

SimStatus BimanualSimulation::setExternalWrench(const LinkHandle& link, const Eigen::Vector3d& force,
                                                const Eigen::Vector3d& torque, const Eigen::Vector3d& point) noexcept {
  if (link.arm < 0 || link.arm >= armCount()) return SimStatus::UnknownLink;
  Impl::Arm& arm = impl_->arms[static_cast<std::size_t>(link.arm)];
  if (link.frame < 0 || link.frame > arm.urdf.model.nq()) return SimStatus::UnknownLink;
  if (!force.allFinite() || !torque.allFinite() || !point.allFinite() || !link.offset.matrix().allFinite()) {
    return SimStatus::InvalidArgument;
  }
  HeldWrench& w = arm.wrenches[static_cast<std::size_t>(link.frame)];
  w.active = true;
  w.force = force;
  w.torque = torque;
  w.point = link.offset * point;
  return SimStatus::Ok;
}

void BimanualSimulation::clearExternalWrenches() noexcept {
  for (Impl::Arm& arm : impl_->arms) {
    for (HeldWrench& w : arm.wrenches) w = HeldWrench();
  }
}

bool BimanualSimulation::hasCloth() const noexcept {
  return impl_->cloth.has_value();
}

const Cloth& BimanualSimulation::cloth() const {
  if (!impl_->cloth) throw std::logic_error("bimanual simulation: built without cloth");
  return *impl_->cloth;
}

SimStatus BimanualSimulation::grasp(int arm, int* attached, bool* object) noexcept {
  Impl& m = *impl_;
  if (attached != nullptr) *attached = 0;
  if (object != nullptr) *object = false;
  if (!m.cloth && !m.object_path) return SimStatus::NoCloth;
  if (arm < 0 || arm >= armCount()) return SimStatus::UnknownArm;
  Impl::Arm& a = m.arms[static_cast<std::size_t>(arm)];
  Eigen::Isometry3d pose;
  Vector6d twist;
  m.toolMotion(a, a.urdf.base_pose, pose, twist);
  if (m.object_path && m.object_holder < 0) {
    const Eigen::Vector3d grasp_point = m.object_pose.translation() + m.config.object.grasp_point;
    if ((pose.translation() - grasp_point).norm() <= m.config.object.grasp_radius) {
      m.object_holder = arm;
      m.object_resting = false;
      m.object_in_tool = pose.inverse(Eigen::Isometry) * m.object_pose;
      m.bullet->holdObject();
    }
  }
  if (object != nullptr) *object = m.object_holder == arm;
  if (!m.cloth) return SimStatus::Ok;
  if (const SimStatus s = m.cloth->setGripperMotion(arm, pose, twist); s != SimStatus::Ok) return s;
  return m.cloth->grasp(arm, m.config.grasp_radius, attached);
}

SimStatus BimanualSimulation::release(int arm) noexcept {
  Impl& m = *impl_;
  if (!m.cloth && !m.object_path) return SimStatus::NoCloth;
  if (arm < 0 || arm >= armCount()) return SimStatus::UnknownArm;
  if (m.object_holder == arm) {
    m.object_holder = -1;
    m.object_resting = true;
    m.object_velocity.setZero();
  }
  if (!m.cloth) return SimStatus::Ok;
  m.arms[static_cast<std::size_t>(arm)].cloth_wrench.setZero();
  return m.cloth->release(arm);
}

SimStatus BimanualSimulation::carryObject(const Eigen::Vector3d& target) noexcept {
  Impl& m = *impl_;
  if (!m.object_path) return SimStatus::NoCloth;
  if (!target.allFinite() || target.cwiseAbs().maxCoeff() > kMaxCarryDistance) return SimStatus::InvalidArgument;
  if (!m.object_carried) {
    m.object_carried = true;
    m.object_resting = false;
  }
  m.object_target = target;
  return SimStatus::Ok;
}

bool BimanualSimulation::hasObject() const noexcept {
  return impl_->object_path.has_value();
}

Eigen::Isometry3d BimanualSimulation::obstaclePose(int k) const {
  const std::vector<Obstacle>& obstacles = impl_->config.obstacles;
  if (k < 0 || k >= static_cast<int>(obstacles.size())) {
    throw std::out_of_range("simulation: no obstacle " + std::to_string(k) + " (the scene has " +
                            std::to_string(obstacles.size()) + ")");
  }
  return impl_->bullet->obstacles->pose(static_cast<std::size_t>(k));
}

int BimanualSimulation::knockedOver(double tilt) const noexcept {
  const std::vector<Obstacle>& obstacles = impl_->config.obstacles;
  int count = 0;
  for (std::size_t k = 0; k < obstacles.size(); ++k) {
    if (!(obstacles[k].mass > 0.0)) continue;
    const Eigen::Vector3d start = obstacles[k].pose.linear().col(2);
    const Eigen::Isometry3d now = impl_->bullet->obstacles->pose(k);
    const bool fell_off = now.translation().z() < obstacles[k].pose.translation().z() - kFallenDrop;
    count += fell_off || std::acos(std::clamp(start.dot(now.linear().col(2)), -1.0, 1.0)) > tilt ? 1 : 0;
  }
  return count;
}

const Eigen::Isometry3d& BimanualSimulation::objectPose() const noexcept {
  return impl_->object_pose;
}

const Eigen::Vector3d& BimanualSimulation::objectVelocity() const noexcept {
  return impl_->object_velocity;
}

int BimanualSimulation::objectHolder() const noexcept {
  return impl_->object_holder;
}

const ObjectPath& BimanualSimulation::objectPath() const {
  if (!impl_->object_path) throw std::logic_error("bimanual simulation: built without a moving object");
  return *impl_->object_path;
}

const Vector6d& BimanualSimulation::clothWrench(int arm) const noexcept {
  static const Vector6d kZero = Vector6d::Zero();
  if (arm < 0 || arm >= armCount()) return kZero;
  return impl_->arms[static_cast<std::size_t>(arm)].cloth_wrench;
}

SimStatus BimanualSimulation::reset(const std::vector<ArmState>& state) {
  Impl& m = *impl_;
  if (state.size() != m.arms.size()) return SimStatus::InvalidArgument;
  for (std::size_t a = 0; a < m.arms.size(); ++a) {
    const kinematics::ChainModel& model = m.arms[a].urdf.model;
    if (state[a].q.size() != model.nq() || state[a].qd.size() != model.nq() || !state[a].qd.allFinite() ||
        !model.withinLimits(state[a].q)) {
      return SimStatus::InvalidArgument;
    }
  }
  for (std::size_t a = 0; a < m.arms.size(); ++a) {
    Impl::Arm& arm = m.arms[a];
    arm.state = state[a];
    arm.command.setZero();
    arm.applied.setZero();
    arm.last_qdd.setZero();
    arm.cloth_wrench.setZero();
    for (HeldWrench& w : arm.wrenches) w = HeldWrench();
    arm.plant.resetFriction(arm.state.qd);
  }
  m.step_index = 0;
  m.time = 0.0;
  m.object_holder = -1;
  m.object_resting = false;
  m.object_carried = false;
  m.rebuildBullet();
  if (m.cloth) m.cloth->reset();
  m.arms_diverged = false;
  m.measure();
  return SimStatus::Ok;
}

SimStatus BimanualSimulation::resetToStart() {
  std::vector<ArmState> state;
  for (int a = 0; a < armCount(); ++a) {
    const Eigen::Index n = jointCount(a);
    const auto k = static_cast<std::size_t>(a);
    const bool given = k < config().arms.size() && config().arms[k].start.size() == n;
    state.push_back({given ? config().arms[k].start : Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n)});
  }
  return reset(state);
}

void BimanualSimulation::setRandomGenerator(const std::mt19937& rng) noexcept {
  impl_->rng = rng;
  for (Impl::Arm& arm : impl_->arms) arm.plant.resetNoise();
}

const SimTimings& BimanualSimulation::timings() const noexcept {
  return impl_->timings;
}

void BimanualSimulation::resetTimings() noexcept {
  impl_->timings = SimTimings();
  if (impl_->cloth) impl_->cloth->resetTimings();
}

}  // namespace bimanual_skills::sim
