/// \file
/// A rectangular cloth patch (e.g. a polo shirt's fabric) on the table, simulated with Bullet's position-based
/// btSoftBody in its own soft-rigid world at its own time step, held by grippers that follow given poses.
/// Bullet types stay in the implementation: this header gives parameters, the mesh, grasp/release and the
/// cloth's pull on each gripper as plain Eigen values.
#pragma once

#include "bimanual_skills/sim/obstacle.hpp"

#include "bimanual_skills/sim/sim_status.hpp"
#include "bimanual_skills/sim/table.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <optional>

namespace bimanual_skills::sim {

using Vector6d = Eigen::Matrix<double, 6, 1>;

/// Cloth parameters. Stiffnesses and friction are Bullet's dimensionless position-solver coefficients (their effect
/// depends on the resolution, step and iterations: docs/ARCHITECTURE.md gives what the defaults measure).
struct ClothParameters {
  double length = 0.5;  ///< Extent along the patch's x axis [m].
  double width = 0.6;   ///< Extent along the patch's y axis [m].
  int nodes_x = 20;     ///< Nodes along x (≥ 2).
  int nodes_y = 24;     ///< Nodes along y (≥ 2).
  /// Pose of the patch's centre in the world; the patch lies in the pose's xy plane at rest.
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  double mass = 0.22;               ///< Total mass [kg] (a polo shirt weighs about 0.2–0.25 kg).
  double stretch_stiffness = 0.9;   ///< Bullet kLST of the structural and shear links, in (0, 1].
  double bending_stiffness = 0.05;  ///< Bullet kLST of the bending links (between nodes two links apart), [0, 1].
  double damping = 0.01;            ///< Bullet kDP: velocity damping per step, [0, 1).
  double friction = 0.5;        ///< Bullet kDF: friction with the table (times the table's) and with itself, [0, 1].
  double thickness = 0.004;     ///< Collision margin [m]: the cloth rests this far above the table, and two
                                ///< layers twice this far apart.
  int position_iterations = 4;  ///< Bullet piterations per step (≥ 1).
  bool self_collision = true;   ///< Node-versus-face contacts of the cloth with itself.
  /// Inextensibility: after each step, no free node is farther from its nearest held node (on the rest mesh) than
  /// (1 + strain_limit) times their rest distance (tethers), and structural edges longer than (1 + strain_limit)
  /// times their rest length are shortened (strain limiting, a few passes). Negative: off (Bullet's links alone
  /// stretch a lifted cloth by 15 % and more at few iterations); the grip stays rigid either way.
  double strain_limit = 0.05;
  double step = 0.004;           ///< Cloth time step [s].
  double max_node_speed = 20.0;  ///< Divergence bound on any node's speed [m/s].
  double max_stretch = 3.0;      ///< Divergence bound on any link's length over its rest length.

  /// Throws std::invalid_argument naming `where` and the parameter that is out of range.
  void validate(const char* where) const;
};

/// Why the cloth was declared diverged.
enum class ClothDivergence { None, NotFinite, NodeSpeed, Stretch };
const char* toString(ClothDivergence divergence) noexcept;

/// Wall-clock time spent in one Cloth (seconds, since construction or resetTimings()).
struct ClothTimings {
  double bullet = 0.0;  ///< Inside btSoftRigidDynamicsWorld::stepSimulation (self-collision detection excluded).
  double self_collision = 0.0;  ///< Self-collision detection (this module's, on Bullet's trees and solver).
  double bookkeeping = 0.0;     ///< Mesh copy, divergence check and gripper wrenches.
  long steps = 0;
  double wall() const noexcept { return bullet + self_collision + bookkeeping; }  ///< All of the cloth's steps.
};

/// The cloth and its grippers. Construction and reset() allocate and may throw; every other call is non-throwing
/// and reports problems as a SimStatus (Bullet itself may still allocate while new contacts appear).
class Cloth {
 public:
  /// A flat patch at parameters.pose, a static table box (none: a scene without a table) and `obstacles` (those that
  /// collide), `grippers` grippers (released), gravity in the world.
  /// \throws std::invalid_argument for invalid parameters.
  Cloth(const ClothParameters& parameters, const std::optional<Table>& table, int grippers,
        const Eigen::Vector3d& gravity = Eigen::Vector3d(0.0, 0.0, -9.81), const std::vector<Obstacle>& obstacles = {});
  ~Cloth();
  Cloth(Cloth&&) noexcept;
  Cloth& operator=(Cloth&&) noexcept;

  const ClothParameters& parameters() const noexcept;
  int nodeCount() const noexcept;
  int gripperCount() const noexcept;

  /// Moves gripper `gripper` to `pose` (world) with twist [v; ω] (world frame, v of the gripper origin) for the
  /// next step; grasped nodes follow it rigidly. InvalidArgument for non-finite values or an unknown gripper.
  SimStatus setGripperMotion(int gripper, const Eigen::Isometry3d& pose, const Vector6d& twist) noexcept;
  /// Pose of a gripper (as last set).
  Eigen::Isometry3d gripperPose(int gripper) const noexcept;

  /// Advances the cloth by parameters().step. Returns ClothDiverged (and freezes the cloth until reset()) when a
  /// node position or velocity is not finite, a node is faster than max_node_speed or a link is stretched beyond
  /// max_stretch times its rest length; the mesh then keeps the last valid state.
  SimStatus step() noexcept;
  SimStatus status() const noexcept;
  ClothDivergence divergence() const noexcept;

  /// Attaches every free node within `radius` [m] of the gripper's origin to the gripper (in its current pose);
  /// `attached`, if given, receives the number of nodes newly attached. InvalidArgument for a bad radius.
  SimStatus grasp(int gripper, double radius, int* attached = nullptr) noexcept;
  /// Detaches every node the gripper holds.
  SimStatus release(int gripper) noexcept;
  /// Nodes gripper `gripper` holds.
  int graspedNodeCount(int gripper) const noexcept;

  /// Wrench the cloth exerted on gripper `gripper` over the last step, [force; torque about the gripper origin],
  /// world frame [N, N m] (zero while it holds nothing or after a divergence). Measured as the momentum Bullet's
  /// anchor constraints transferred to the gripper body, plus the momentum the rigid grip, the tethers and the strain
  /// limiting gave the nodes from the gripper (reversed).
  const Vector6d& gripperWrench(int gripper) const noexcept;

  /// Node positions (3 × nodeCount, world frame), updated after every step. Node (i, j) is column j·nodes_x + i.
  const Eigen::Matrix3Xd& vertices() const noexcept;
  /// Node velocities (3 × nodeCount, world frame) [m/s].
  const Eigen::Matrix3Xd& velocities() const noexcept;
  /// Triangles as node indices (3 × triangle count), constant.
  const Eigen::Matrix3Xi& triangles() const noexcept;
  /// Node positions at rest (the flat patch), world frame.
  const Eigen::Matrix3Xd& restVertices() const noexcept;
  /// Largest link length over rest length after the last step, over every Bullet link: the structural edges
  /// between mesh neighbours, the diagonal shear links and the bending links (two nodes apart).
  double maxStretch() const noexcept;
  /// Largest length over rest length of a structural edge (a link between neighbours along x or y of the mesh grid)
  /// after the last step: how much the fabric itself stretches.
  double maxEdgeStretch() const noexcept;
  /// Self-contacts (node-face) found in the last step.
  int selfContactCount() const noexcept;

  /// Back to the flat patch at rest, all grippers released, status Ok. Allocates (rebuilds the Bullet world).
  void reset();

  const ClothTimings& timings() const noexcept;
  void resetTimings() noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bimanual_skills::sim
