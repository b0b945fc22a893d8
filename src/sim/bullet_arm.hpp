/// \file
/// Internal: one arm of a URDF as a Bullet btMultiBody (double precision), and the URDF facts the simulation needs
/// beyond the ChainModel (base pose in the world, collision shapes, links fixed to the moving ones).
#pragma once

#include "bimanual_skills/kinematics/chain_model.hpp"
#include "bimanual_skills/sim/sim_config.hpp"

#include <BulletDynamics/Featherstone/btMultiBody.h>
#include <BulletDynamics/Featherstone/btMultiBodyDynamicsWorld.h>
#include <BulletDynamics/Featherstone/btMultiBodyLinkCollider.h>
#include <btBulletCollisionCommon.h>

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace bimanual_skills::sim {

/// A primitive collision shape of a URDF <collision> element.
struct ShapeSpec {
  enum class Type { Box, Cylinder, Sphere };
  Type type = Type::Box;
  Eigen::Vector3d dimensions = Eigen::Vector3d::Zero();      ///< Box: full size; cylinder: (radius, length, 0);
                                                             ///< sphere: (radius, 0, 0).
  Eigen::Isometry3d origin = Eigen::Isometry3d::Identity();  ///< In the frame of the body that carries it.
};

/// What the simulation reads from the URDF for one arm.
struct UrdfArm {
  kinematics::ChainModel model;  ///< Base link to tip link, gravity in the base frame, no rotor inertia.
  Eigen::Isometry3d base_pose = Eigen::Isometry3d::Identity();  ///< Base link in the world (root) frame.
  std::vector<ShapeSpec> base_shapes;                           ///< In the base link frame.
  std::vector<std::vector<ShapeSpec>> link_shapes;              ///< Per moving link i, in its URDF frame.
  /// Every link that moves with the arm: name -> (frame index in model.frameNames(), pose in that frame).
  std::map<std::string, std::pair<int, Eigen::Isometry3d>> links;
  int ignored_meshes = 0;  ///< <collision> meshes, which the simulation does not collide.
};

/// Reads arm `arm` of the URDF file. \throws std::invalid_argument (unknown links, a base link that is not fixed to
/// the root, a chain the ChainModel rejects).
UrdfArm loadUrdfArm(const std::string& urdf_path, const ArmConfig& arm, const Eigen::Vector3d& world_gravity);

/// An arm in a btMultiBodyDynamicsWorld: the multibody (fixed base at the base pose; link frames at the centres of
/// mass along the principal axes of inertia; no damping; the joint limits are the plant's) and its colliders.
class BulletArm {
 public:
  /// `index` (0..25) gives the arm its own collision-filter bit, so that Bullet's broadphase never pairs the arm's
  /// colliders with each other (self-collision is off) and its base never with the static table.
  /// \throws std::invalid_argument for a moving link without mass or an index out of range.
  BulletArm(const UrdfArm& arm, int index, btMultiBodyDynamicsWorld& world);
  ~BulletArm();
  BulletArm(const BulletArm&) = delete;
  BulletArm& operator=(const BulletArm&) = delete;

  btMultiBody& body() noexcept { return *body_; }
  const btMultiBody& body() const noexcept { return *body_; }
  /// Sets the joint state and updates the link and collider transforms.
  void setState(const Eigen::VectorXd& q, const Eigen::VectorXd& qd);

 private:
  btMultiBodyDynamicsWorld& world_;
  std::unique_ptr<btMultiBody> body_;
  std::vector<std::unique_ptr<btCollisionShape>> shapes_;
  std::vector<std::unique_ptr<btMultiBodyLinkCollider>> colliders_;
  btAlignedObjectArray<btQuaternion> scratch_rotations_;
  btAlignedObjectArray<btVector3> scratch_vectors_;
};

}  // namespace bimanual_skills::sim
