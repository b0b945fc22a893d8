/// \file
/// The static rigid bodies of a scene's obstacles in one Bullet world (the arms' or the cloth's): built together,
/// removed together.
#pragma once

#include "bimanual_skills/sim/obstacle.hpp"

#include <BulletDynamics/Dynamics/btDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>

#include <memory>
#include <vector>

namespace bimanual_skills::sim {

/// The collision shape of an obstacle (or the moving object) in its own frame.
std::unique_ptr<btCollisionShape> obstacleShape(const Obstacle& obstacle);

class StaticBodies {
 public:
  /// Adds a static body to `world` for every obstacle that collides (marks are not felt).
  StaticBodies(btDynamicsWorld& world, const std::vector<Obstacle>& obstacles);
  ~StaticBodies();
  StaticBodies(const StaticBodies&) = delete;
  StaticBodies& operator=(const StaticBodies&) = delete;

  int count() const noexcept { return static_cast<int>(bodies_.size()); }

 private:
  btDynamicsWorld& world_;
  std::vector<std::unique_ptr<btCollisionShape>> shapes_;
  std::vector<std::unique_ptr<btRigidBody>> bodies_;
};

}  // namespace bimanual_skills::sim
