#include "bimanual_skills/sim/obstacle.hpp"

#include "bullet_conversions.hpp"
#include "scene_bodies.hpp"

#include <cmath>
#include <stdexcept>

namespace bimanual_skills::sim {

const char* toString(Obstacle::Shape shape) noexcept {
  switch (shape) {
    case Obstacle::Shape::Box:
      return "box";
    case Obstacle::Shape::Sphere:
      return "sphere";
    case Obstacle::Shape::Cylinder:
      return "cylinder";
  }
  return "unknown";
}

int sizeValues(Obstacle::Shape shape) noexcept {
  return shape == Obstacle::Shape::Box ? 3 : shape == Obstacle::Shape::Cylinder ? 2 : 1;
}

void Obstacle::validate(const std::string& where) const {
  const std::string at = where + " obstacle '" + name + "'";
  if (name.empty()) throw std::invalid_argument(where + ": an obstacle needs a name");
  if (!pose.matrix().allFinite()) throw std::invalid_argument(at + ": its pose must be finite");
  const int dimensions = sizeValues(shape);
  for (int i = 0; i < 3; ++i) {
    const bool used = i < dimensions;
    if (!std::isfinite(size[i]) || (used && !(size[i] > 0.0 && size[i] <= 100.0))) {
      throw std::invalid_argument(at + ": 'size' of a " + toString(shape) + " needs " + std::to_string(dimensions) +
                                  " value(s) in (0, 100] m (box: extents; sphere: radius; cylinder: radius, length)");
    }
  }
  if (!colour.allFinite() || (colour.array() < 0.0).any() || (colour.array() > 1.0).any()) {
    throw std::invalid_argument(at + ": 'colour' must be RGB in [0, 1]");
  }
  if (!(friction >= 0.0 && friction <= 100.0)) throw std::invalid_argument(at + ": 'friction' must lie in [0, 100]");
  if (!(mass >= 0.0 && mass <= 1000.0)) throw std::invalid_argument(at + ": 'mass' must lie in [0, 1000] kg");
  if (mass > 0.0 && !collides) throw std::invalid_argument(at + ": a free obstacle (mass > 0) must collide");
}

std::unique_ptr<btCollisionShape> obstacleShape(const Obstacle& obstacle) {
  switch (obstacle.shape) {
    case Obstacle::Shape::Sphere:
      return std::make_unique<btSphereShape>(obstacle.size[0]);
    case Obstacle::Shape::Cylinder:
      return std::make_unique<btCylinderShapeZ>(btVector3(obstacle.size[0], obstacle.size[0], 0.5 * obstacle.size[1]));
    case Obstacle::Shape::Box:
      break;
  }
  return std::make_unique<btBoxShape>(toBullet(Eigen::Vector3d(0.5 * obstacle.size)));
}

SceneBodies::SceneBodies(btDynamicsWorld& world, const std::vector<Obstacle>& obstacles) : world_(world) {
  for (const Obstacle& obstacle : obstacles) {
    poses_.push_back(obstacle.pose);
    free_body_.push_back(-1);
    if (!obstacle.collides) continue;
    std::unique_ptr<btCollisionShape> shape = obstacleShape(obstacle);
    btVector3 inertia(0.0, 0.0, 0.0);
    if (obstacle.mass > 0.0) shape->calculateLocalInertia(obstacle.mass, inertia);
    btRigidBody::btRigidBodyConstructionInfo info(obstacle.mass, nullptr, shape.get(), inertia);
    info.m_startWorldTransform = toBulletTransform(obstacle.pose);
    info.m_friction = obstacle.friction;
    auto body = std::make_unique<btRigidBody>(info);
    world_.addRigidBody(body.get());
    if (obstacle.mass > 0.0) free_body_.back() = static_cast<int>(bodies_.size());
    shapes_.push_back(std::move(shape));
    bodies_.push_back(std::move(body));
  }
}

SceneBodies::~SceneBodies() {
  for (const auto& body : bodies_) world_.removeRigidBody(body.get());
}

Eigen::Isometry3d SceneBodies::pose(std::size_t k) const noexcept {
  const int body = free_body_[k];
  return body < 0 ? poses_[k] : toEigen(bodies_[static_cast<std::size_t>(body)]->getWorldTransform());
}

}  // namespace bimanual_skills::sim
