#include "bimanual_skills/sim/obstacle.hpp"

#include "bullet_conversions.hpp"
#include "static_bodies.hpp"

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

StaticBodies::StaticBodies(btDynamicsWorld& world, const std::vector<Obstacle>& obstacles) : world_(world) {
  for (const Obstacle& obstacle : obstacles) {
    if (!obstacle.collides) continue;
    std::unique_ptr<btCollisionShape> shape = obstacleShape(obstacle);
    btRigidBody::btRigidBodyConstructionInfo info(0.0, nullptr, shape.get());
    info.m_startWorldTransform = toBulletTransform(obstacle.pose);
    info.m_friction = obstacle.friction;
    auto body = std::make_unique<btRigidBody>(info);
    world_.addRigidBody(body.get());
    shapes_.push_back(std::move(shape));
    bodies_.push_back(std::move(body));
  }
}

StaticBodies::~StaticBodies() {
  for (const auto& body : bodies_) world_.removeRigidBody(body.get());
}

}  // namespace bimanual_skills::sim
