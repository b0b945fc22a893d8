/// \file
/// The simulated bimanual robot: the arms of a URDF as Bullet btMultiBody's (double precision) driven by their true
/// plant (arm_plant.hpp), a table, payloads, external wrenches and an optional cloth at its own rate. It is one more
/// backend of RobotInterface. Bullet types stay in the implementation.
#pragma once

#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"
#include "bimanual_skills/sim/arm_plant.hpp"
#include "bimanual_skills/sim/cloth.hpp"
#include "bimanual_skills/sim/robot_interface.hpp"
#include "bimanual_skills/sim/sim_config.hpp"
#include "bimanual_skills/sim/sim_status.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <random>
#include <string>
#include <vector>

namespace bimanual_skills::sim {

/// Joint positions and velocities of one arm.
struct ArmState {
  Eigen::VectorXd q;   ///< [rad or m]
  Eigen::VectorXd qd;  ///< [rad/s or m/s]
};

/// A link of a simulated arm, resolved once by name (BimanualSimulation::link) for the real-time calls.
struct LinkHandle {
  int arm = -1;    ///< Arm index.
  int frame = -1;  ///< Index in the arm model's frameNames() of the moving link it is fixed to.
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();  ///< Its pose in that frame.
};

/// Wall-clock seconds spent in step() since construction or resetTimings().
struct SimTimings {
  double total = 0.0;        ///< All of step().
  double bullet_arms = 0.0;  ///< btMultiBodyDynamicsWorld::stepSimulation of the arms.
  double plant = 0.0;        ///< True plant: dynamics, rotor inertia, friction, sensors, external wrenches.
  ClothTimings cloth;        ///< The cloth's own split (Bullet, self-collision detection, bookkeeping).
  long steps = 0;
};

/// The simulation. Construction and reset() may allocate and throw std::invalid_argument; every other call is
/// noexcept and reports bad input as a status. step() does not allocate in the project's code; Bullet may allocate
/// while contacts appear (the simulation is a plant, not a real-time component).
///
/// One step of length Δt (SimConfig::step): every cloth period (a whole number of steps) the grippers take the
/// tools' poses and twists, the cloth advances one cloth step and its pull on each gripper becomes an external
/// wrench on that tool for the following steps; then each arm's true plant turns the applied torque, the external
/// wrenches (Jᵀ F) and its payload into q̈ (ArmPlant::step), Bullet's btMultiBody of the rigid-body model is given
/// the torque that reproduces this q̈, and Bullet integrates it (semi-implicit Euler) together with the joint limits
/// and the contacts of the arms with each other and the table.
class BimanualSimulation final : public RobotInterface {
 public:
  /// Builds the world of `config`; sensor noise is drawn from `rng`.
  /// \throws std::invalid_argument for an invalid configuration, a URDF that cannot be read, unknown links, base
  /// links not fixed to the world, links without mass, or a plant model without an entry for an arm.
  BimanualSimulation(const SimConfig& config, std::mt19937 rng);
  /// As above with std::mt19937(config.seed).
  explicit BimanualSimulation(const SimConfig& config);
  ~BimanualSimulation() override;
  BimanualSimulation(const BimanualSimulation&) = delete;
  BimanualSimulation& operator=(const BimanualSimulation&) = delete;

  // ---- RobotInterface ----
  int armCount() const noexcept override;
  int jointCount(int arm) const noexcept override;
  /// The measurement taken at the end of the last step (or at reset): encoder-quantised positions, noisy
  /// velocities, the applied torque.
  RobotStatus readJointState(int arm, JointState& state) noexcept override;
  /// Torque command [N m], held until the next write; saturated at the URDF effort limits when the plant says so.
  RobotStatus writeJointTorques(int arm, const Eigen::Ref<const Eigen::VectorXd>& torque) noexcept override;

  // ---- Stepping ----
  /// Advances the world by one step. Ok, ClothDiverged (the cloth is frozen and exerts no more force; the arms go
  /// on), or ArmDiverged (an arm's state became non-finite or faster than 100 rad/s: nothing moves until reset()).
  SimStatus step() noexcept;
  /// Simulated time since construction or reset [s].
  double time() const noexcept;
  double stepSize() const noexcept;
  const SimConfig& config() const noexcept;

  // ---- Arms ----
  /// Index of the arm called `name`, −1 if none.
  int armIndex(const std::string& name) const noexcept;
  /// The arm's rigid-body model (base frame = its base link; no rotor inertia, gravity in the base frame).
  const kinematics::ChainModel& armModel(int arm) const;
  /// The arm's true plant (its parameters and the friction it applied in the last step).
  const ArmPlant& armPlant(int arm) const;
  /// Pose of the arm's base link in the world.
  const Eigen::Isometry3d& basePose(int arm) const;
  /// The exact (noise-free) state.
  const ArmState& trueState(int arm) const;
  /// q̈ of the last step as Bullet integrated it ((q̇⁺ − q̇)/Δt).
  const Eigen::VectorXd& lastAcceleration(int arm) const;
  /// Pose of the arm's tool (tip link) in the world at the current state.
  Eigen::Isometry3d toolPose(int arm) const;

  // ---- Loads ----
  /// Point mass carried by the arm's tool (dynamics::Payload: mass, centre of mass in the tool frame).
  SimStatus setPayload(int arm, const dynamics::Payload& payload) noexcept;
  /// The link called `name` (any link of an arm's chain, or fixed to one).
  /// \throws std::invalid_argument for an unknown link or one that does not move with an arm.
  LinkHandle link(const std::string& name) const;
  /// Applies, until changed or cleared, the wrench [force; torque] (world frame, N and N m) at the origin of
  /// `link` (plus `point`, in the link's frame); replaces any wrench set before on the same moving link.
  SimStatus setExternalWrench(const LinkHandle& link, const Eigen::Vector3d& force, const Eigen::Vector3d& torque,
                              const Eigen::Vector3d& point = Eigen::Vector3d::Zero()) noexcept;
  void clearExternalWrenches() noexcept;

  // ---- Cloth ----
  bool hasCloth() const noexcept;
  /// The cloth (mesh, status); only when hasCloth().
  const Cloth& cloth() const;
  /// Closes arm `arm`'s gripper: it grasps the cloth nodes within the configured radius of its tool (`attached` gets
  /// how many) and the moving object when its grasp point lies within the object's grasp radius (`object` says
  /// whether it holds it). NoCloth when the scene has neither.
  SimStatus grasp(int arm, int* attached = nullptr, bool* object = nullptr) noexcept;
  /// Opens the gripper: the cloth nodes it held go, and the object it held rests where it is until reset().
  SimStatus release(int arm) noexcept;
  /// The cloth's wrench on the arm's tool currently applied [force; torque about the tool origin], world frame.
  const Vector6d& clothWrench(int arm) const noexcept;

  // ---- The scene's obstacles (SimConfig::obstacles) ----
  /// Obstacle k of the scene (SimConfig::obstacles' order) now: where contacts have moved a free one (mass > 0),
  /// where it stands for the others. \throws std::out_of_range for k outside the list.
  Eigen::Isometry3d obstaclePose(int k) const;
  /// How many free obstacles are knocked over: their z axis tilted more than `tilt` [rad] from where it pointed at
  /// the reset (a bottle of radius r and length h tips past atan(2r / h); 45° by default), or their centre more than
  /// kFallenDrop below where it was (pushed off the table, whichever way up it falls).
  int knockedOver(double tilt = 0.7853981633974483) const noexcept;
  static constexpr double kFallenDrop = 0.1;  ///< [m]

  // ---- The moving object (SimConfig::object) ----
  bool hasObject() const noexcept;
  /// Its pose in the world now: upright on its path, resting where it was let go, or in the gripper that holds it.
  const Eigen::Isometry3d& objectPose() const noexcept;
  /// Its velocity now [m/s].
  const Eigen::Vector3d& objectVelocity() const noexcept;
  /// The arm whose gripper holds it, −1 for none.
  int objectHolder() const noexcept;
  /// The path it follows while nobody holds it. \throws std::logic_error without an object.
  const ObjectPath& objectPath() const;
  /// A person carries it from now on (the hand of the thesis' human guidance, Sec. 6.2, that the camera sees): it
  /// moves toward `target` (world [m], the latest one given) critically damped with a 0.1 s time constant, within
  /// its path's max_speed and max_acceleration, instead of along its path, until reset(); a gripper that grasps it
  /// still takes it. Real-time safe. InvalidArgument for a non-finite target or one farther than kMaxCarryDistance
  /// from the world's origin on an axis, NoCloth without an object.
  SimStatus carryObject(const Eigen::Vector3d& target) noexcept;
  static constexpr double kMaxCarryDistance = 10.0;  ///< [m]

  // ---- Reset and determinism ----
  /// Sets every arm to the given state (within the joint limits), the cloth to its flat rest state, the object to
  /// its path's start (held by nobody), free obstacles to their poses, time to 0,
  /// clears torque commands and external wrenches (payloads stay), and rebuilds the Bullet worlds so the future is
  /// exactly that of a new simulation in this state. Allowed after a divergence.
  /// InvalidArgument (nothing changed) for wrong sizes, non-finite values or positions outside the limits.
  SimStatus reset(const std::vector<ArmState>& state);
  /// reset() to the arms' start postures (SimConfig::arms' start, the robot file's; zero for an arm without one),
  /// at rest: where bullet_sim starts them.
  SimStatus resetToStart();
  /// Replaces the sensor-noise generator.
  void setRandomGenerator(const std::mt19937& rng) noexcept;

  const SimTimings& timings() const noexcept;
  void resetTimings() noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bimanual_skills::sim
