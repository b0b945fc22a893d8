#include "bullet_arm.hpp"
#include "bimanual_skills/kinematics/urdf_pose.hpp"

#include "bullet_conversions.hpp"

#include <urdf_parser/urdf_parser.h>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <functional>
#include <stdexcept>

namespace bimanual_skills::sim {
namespace {

using kinematics::toIsometry;

/// Principal moments of inertia below this are raised to it [kg m²]: a link that is a point mass (zero moments)
/// would make Bullet's articulated inertias singular. 1e-10 kg m² is far below any real link's.
constexpr double kMinimumPrincipalMoment = 1e-10;

/// The primitive <collision> shapes of `link`, in the frame `in_frame` · link frame.
void appendShapes(const urdf::Link& link, const Eigen::Isometry3d& in_frame, std::vector<ShapeSpec>& out,
                  int& ignored_meshes) {
  std::vector<urdf::CollisionSharedPtr> collisions = link.collision_array;
  if (collisions.empty() && link.collision) collisions.push_back(link.collision);
  for (const urdf::CollisionSharedPtr& collision : collisions) {
    if (!collision || !collision->geometry) continue;
    ShapeSpec shape;
    shape.origin = in_frame * toIsometry(collision->origin);
    switch (collision->geometry->type) {
      case urdf::Geometry::BOX: {
        const auto& box = static_cast<const urdf::Box&>(*collision->geometry);
        shape.type = ShapeSpec::Type::Box;
        shape.dimensions << box.dim.x, box.dim.y, box.dim.z;
        break;
      }
      case urdf::Geometry::CYLINDER: {
        const auto& cylinder = static_cast<const urdf::Cylinder&>(*collision->geometry);
        shape.type = ShapeSpec::Type::Cylinder;
        shape.dimensions << cylinder.radius, cylinder.length, 0.0;
        break;
      }
      case urdf::Geometry::SPHERE: {
        const auto& sphere = static_cast<const urdf::Sphere&>(*collision->geometry);
        shape.type = ShapeSpec::Type::Sphere;
        shape.dimensions << sphere.radius, 0.0, 0.0;
        break;
      }
      default:
        ++ignored_meshes;
        continue;
    }
    out.push_back(shape);
  }
}

std::unique_ptr<btCollisionShape> makeShape(const ShapeSpec& shape) {
  switch (shape.type) {
    case ShapeSpec::Type::Box:
      return std::make_unique<btBoxShape>(toBullet(Eigen::Vector3d(0.5 * shape.dimensions)));
    case ShapeSpec::Type::Cylinder:
      return std::make_unique<btCylinderShapeZ>(
          btVector3(shape.dimensions[0], shape.dimensions[0], 0.5 * shape.dimensions[1]));
    case ShapeSpec::Type::Sphere:
      return std::make_unique<btSphereShape>(shape.dimensions[0]);
  }
  return nullptr;
}

}  // namespace

UrdfArm loadUrdfArm(const std::string& urdf_path, const ArmConfig& arm, const Eigen::Vector3d& world_gravity) {
  const std::string where = "arm '" + arm.name + "' of '" + urdf_path + "'";
  const urdf::ModelInterfaceSharedPtr urdf = urdf::parseURDFFile(urdf_path);
  if (!urdf) throw std::invalid_argument(where + ": cannot read or parse the URDF");
  for (const std::string& name : {arm.base_link, arm.tip_link}) {
    if (!urdf->getLink(name)) throw std::invalid_argument(where + ": unknown link '" + name + "'");
  }
  // The base must hang from the root through fixed joints only.
  Eigen::Isometry3d base_pose;
  try {
    base_pose = kinematics::poseInRoot(*urdf, arm.base_link, nullptr);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(where + ": base " + e.what());
  }

  kinematics::ChainModel chain = kinematics::ChainModel::fromUrdfFile(urdf_path, arm.base_link, arm.tip_link);
  UrdfArm out{chain.withGravity(base_pose.linear().transpose() * world_gravity), base_pose, {}, {}, {}, 0};
  const int n = out.model.nq();
  out.link_shapes.resize(static_cast<std::size_t>(n));

  // Link name -> frame index of the moving body it belongs to (children of movable joints; the tip is frame n).
  std::map<std::string, int> moving;
  for (int i = 0; i < n; ++i) moving[out.model.joints()[static_cast<std::size_t>(i)].child_link] = i;

  // Every link fixed to a moving link (or to the base), with its pose there; collision shapes collected per body.
  std::function<void(const urdf::Link&, int, const Eigen::Isometry3d&)> visit = [&](const urdf::Link& link, int body,
                                                                                    const Eigen::Isometry3d& pose) {
    if (body >= 0) {
      out.links[link.name] = {body, pose};
      appendShapes(link, pose, out.link_shapes[static_cast<std::size_t>(body)], out.ignored_meshes);
    } else {
      appendShapes(link, pose, out.base_shapes, out.ignored_meshes);
    }
    for (const urdf::JointSharedPtr& joint : link.child_joints) {
      const urdf::LinkConstSharedPtr child = urdf->getLink(joint->child_link_name);
      if (joint->type == urdf::Joint::FIXED) {
        visit(*child, body, pose * toIsometry(joint->parent_to_joint_origin_transform));
      } else if (const auto it = moving.find(child->name); it != moving.end()) {
        visit(*child, it->second, Eigen::Isometry3d::Identity());
      }
    }
  };
  visit(*urdf->getLink(arm.base_link), -1, Eigen::Isometry3d::Identity());
  // The tip is its own frame (index n) for Jacobians; links fixed to it keep the moving body's frame otherwise.
  if (const auto it = out.links.find(arm.tip_link); it != out.links.end())
    it->second = {n, Eigen::Isometry3d::Identity()};
  return out;
}

BulletArm::BulletArm(const UrdfArm& arm, int index, btMultiBodyDynamicsWorld& world) : world_(world) {
  if (index < 0 || index > 25) throw std::invalid_argument("bullet arm: at most 26 arms per world");
  const int own = 64 << index;  // above Bullet's predefined filter bits (1..32)
  const kinematics::ChainModel& model = arm.model;
  const int n = model.nq();
  body_ = std::make_unique<btMultiBody>(n, 1.0, btVector3(1.0, 1.0, 1.0), true, false);
  body_->setBaseWorldTransform(toBulletTransform(arm.base_pose));

  // Bullet's link frame C_i: origin at the centre of mass, axes along the principal axes of inertia (R_i, in the
  // URDF link frame L_i).
  std::vector<Eigen::Matrix3d> principal(static_cast<std::size_t>(n));
  std::vector<Eigen::Vector3d> com(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    const kinematics::ChainJoint& joint = model.joints()[k];
    const kinematics::BodyInertia& inertia = joint.body;
    if (!(inertia.mass > 0.0)) {
      throw std::invalid_argument("link '" + joint.child_link + "' has no mass: Bullet's btMultiBody needs one");
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(0.5 * (inertia.inertia + inertia.inertia.transpose()));
    Eigen::Matrix3d R = eigen.eigenvectors();
    if (R.determinant() < 0.0) R.col(2) *= -1.0;
    principal[k] = R;
    com[k] = inertia.com;
    const Eigen::Vector3d moments = eigen.eigenvalues().cwiseMax(kMinimumPrincipalMoment);

    const Eigen::Matrix3d R_parent = i == 0 ? Eigen::Matrix3d::Identity() : principal[k - 1];
    const Eigen::Vector3d c_parent = i == 0 ? Eigen::Vector3d::Zero() : com[k - 1];
    const Eigen::Matrix3d orientation = R_parent.transpose() * joint.origin.linear() * R;  // C_i in C_{i-1}
    const btQuaternion parent_to_this = toBulletQuaternion(orientation.transpose());
    const btVector3 parent_com_to_pivot = toBullet(R_parent.transpose() * (joint.origin.translation() - c_parent));
    const btVector3 pivot_to_com = toBullet(R.transpose() * inertia.com);
    const btVector3 axis = toBullet(R.transpose() * joint.axis.normalized());
    if (joint.type == kinematics::JointType::Revolute) {
      body_->setupRevolute(i, inertia.mass, toBullet(moments), i - 1, parent_to_this, axis, parent_com_to_pivot,
                           pivot_to_com, true);
    } else {
      body_->setupPrismatic(i, inertia.mass, toBullet(moments), i - 1, parent_to_this, axis, parent_com_to_pivot,
                            pivot_to_com, true);
    }
  }
  body_->finalizeMultiDof();
  body_->setLinearDamping(0.0);
  body_->setAngularDamping(0.0);
  body_->setUseGyroTerm(true);
  body_->setMaxCoordinateVelocity(1e3);
  body_->setHasSelfCollision(false);
  body_->setCanSleep(false);
  // No btMultiBodyJointLimitConstraint: the true plant stops the joints at their limits (ArmPlant), with the rotor
  // inertia Bullet does not know.
  world_.addMultiBody(body_.get());

  // Colliders: compound shapes in each body's Bullet frame.
  const auto makeCollider = [&](int link, const std::vector<ShapeSpec>& specs, const Eigen::Isometry3d& frame) {
    if (specs.empty()) return;
    auto compound = std::make_unique<btCompoundShape>();
    for (const ShapeSpec& spec : specs) {
      std::unique_ptr<btCollisionShape> shape = makeShape(spec);
      compound->addChildShape(toBulletTransform(frame.inverse() * spec.origin), shape.get());
      shapes_.push_back(std::move(shape));
    }
    auto collider = std::make_unique<btMultiBodyLinkCollider>(body_.get(), link);
    collider->setCollisionShape(compound.get());
    shapes_.push_back(std::move(compound));
    const bool base = link < 0;
    // Base: static, meets the other arms' links. Links: meet everything but their own arm.
    world_.addCollisionObject(collider.get(), own | (base ? btBroadphaseProxy::StaticFilter : 0),
                              base ? btBroadphaseProxy::AllFilter ^ btBroadphaseProxy::StaticFilter ^ own
                                   : btBroadphaseProxy::AllFilter ^ own);
    if (base) {
      body_->setBaseCollider(collider.get());
    } else {
      body_->getLink(link).m_collider = collider.get();
    }
    colliders_.push_back(std::move(collider));
  };
  makeCollider(-1, arm.base_shapes, Eigen::Isometry3d::Identity());
  for (int i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
    frame.linear() = principal[k];
    frame.translation() = com[k];
    makeCollider(i, arm.link_shapes[k], frame);
  }

  setState(Eigen::VectorXd::Zero(n), Eigen::VectorXd::Zero(n));
}

BulletArm::~BulletArm() {
  for (auto& collider : colliders_) world_.removeCollisionObject(collider.get());
  world_.removeMultiBody(body_.get());
}

void BulletArm::setState(const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
  for (int i = 0; i < body_->getNumLinks(); ++i) {
    body_->setJointPos(i, q[i]);
    body_->setJointVel(i, qd[i]);
  }
  body_->clearForcesAndTorques();
  body_->forwardKinematics(scratch_rotations_, scratch_vectors_);
  body_->updateCollisionObjectWorldTransforms(scratch_rotations_, scratch_vectors_);
}

}  // namespace bimanual_skills::sim
