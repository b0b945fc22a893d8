/// \file
/// The rigid bodies of a scene's obstacles in one Bullet world (the arms' or the cloth's): static ones, and in the
/// arms' world free ones (mass > 0) that contacts move; built together, removed together.
#pragma once

#include "bimanual_skills/sim/obstacle.hpp"

#include <BulletDynamics/Dynamics/btDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>

#include <Eigen/Geometry>

#include <memory>
#include <vector>

namespace bimanual_skills::sim {

/// The collision shape of an obstacle (or the moving object) in its own frame.
std::unique_ptr<btCollisionShape> obstacleShape(const Obstacle& obstacle);

class SceneBodies {
 public:
  /// Adds a body to `world` for every obstacle that collides (marks are not felt): static, or dynamic with its mass
  /// and the inertia of its shape, at its pose, when it is free.
  SceneBodies(btDynamicsWorld& world, const std::vector<Obstacle>& obstacles);
  ~SceneBodies();
  SceneBodies(const SceneBodies&) = delete;
  SceneBodies& operator=(const SceneBodies&) = delete;

  int count() const noexcept { return static_cast<int>(bodies_.size()); }
  /// Obstacle k's pose now (k in the order given): a free one's where the contacts moved it, the others' their own.
  Eigen::Isometry3d pose(std::size_t k) const noexcept;

 private:
  btDynamicsWorld& world_;
  std::vector<Eigen::Isometry3d> poses_;  ///< Per obstacle, its pose as given.
  std::vector<int> free_body_;            ///< Per obstacle, its index in bodies_ when free, else −1.
  std::vector<std::unique_ptr<btCollisionShape>> shapes_;
  std::vector<std::unique_ptr<btRigidBody>> bodies_;
};

}  // namespace bimanual_skills::sim
