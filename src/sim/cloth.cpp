#include "bimanual_skills/sim/cloth.hpp"

#include "bimanual_skills/realtime/clock.hpp"
#include "bullet_conversions.hpp"
#include "scene_bodies.hpp"

#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyInternals.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

namespace bimanual_skills::sim {
namespace {

using realtime::Clock;
using realtime::seconds;

/// Gripper bodies: heavy, unaffected by gravity and colliding with nothing, so the anchor impulses Bullet applies to
/// them barely move them and can be read back as the cloth's pull (momentum change over the step).
constexpr double kGripperMass = 100.0;    // [kg]
constexpr double kGripperInertia = 10.0;  // [kg m²], isotropic
/// Sparse signed-distance-field cell of the soft-rigid contacts [m]. Bullet's default (0.25 m) interpolates the
/// distance to a thin table top so coarsely that the cloth rests 2–3 cm inside it (measured); 0.05 m is exact for
/// the table's faces. Curved obstacles get a finer field (at 0.05 m the cloth sank 1.3–1.9 cm into a 0.1 m ball, at
/// 0.02 m 0.9–1.4 cm, measured); what remains is taken out by projecting the nodes out of the obstacles' exact shapes
/// (Impl::projectOutOfObstacles).
constexpr double kSdfVoxel = 0.05;
constexpr double kCurvedSdfVoxel = 0.02;
/// Gauss-Seidel passes of the strain limiting per step (fewer leave edges above the limit after a fold's put-down;
/// more cost time for little: docs/RESULTS.md "How much the fabric stretches").
constexpr int kStrainPasses = 4;

/// CreatePatch numbers node (ix, iy) as iy · nodes_x + ix; a structural edge joins grid neighbours.
bool isStructural(const btSoftBody::Link& link, const btSoftBody::Node* first, int nodes_x) {
  const int a = static_cast<int>(link.m_n[0] - first), b = static_cast<int>(link.m_n[1] - first);
  return std::abs(a % nodes_x - b % nodes_x) + std::abs(a / nodes_x - b / nodes_x) == 1;
}

/// Node-versus-face self-contacts of one cloth, fed to Bullet's soft-contact position solver (PSolve_SContacts).
/// Bullet's own VF_SS handler skips self-collision (and its node/face exclusion test is a no-op), so this does the
/// detection: a node collides with a face unless the face has a vertex within `skip` of the node on the rest mesh
/// (its own faces and the faces of its neighbours, which lie within the margin wherever the cloth bends).
struct SelfCollider : btDbvt::ICollide {
  void Process(const btDbvtNode* leaf_node, const btDbvtNode* leaf_face) override {
    btSoftBody::Node* node = static_cast<btSoftBody::Node*>(leaf_node->data);
    btSoftBody::Face* face = static_cast<btSoftBody::Face*>(leaf_face->data);
    const btSoftBody::Node* first = &body->m_nodes[0];
    const btVector3& rest_node = rest[node - first];
    for (int k = 0; k < 3; ++k) {
      if ((rest[face->m_n[k] - first] - rest_node).length2() < skip2) return;
    }
    const btVector3 o = node->m_x;
    btVector3 p(0, 0, 0);
    btScalar d2 = SIMD_INFINITY;
    ProjectOrigin(face->m_n[0]->m_x - o, face->m_n[1]->m_x - o, face->m_n[2]->m_x - o, p, d2);
    const btScalar m = margin + (o - node->m_q).length() * 2;
    if (!(d2 < m * m) || !(d2 > 0)) return;
    const btVector3 w = BaryCoord(face->m_n[0]->m_x, face->m_n[1]->m_x, face->m_n[2]->m_x, p + o);
    const btScalar ma = node->m_im;
    btScalar mb = BaryEval(face->m_n[0]->m_im, face->m_n[1]->m_im, face->m_n[2]->m_im, w);
    if (face->m_n[0]->m_im <= 0 || face->m_n[1]->m_im <= 0 || face->m_n[2]->m_im <= 0) mb = 0;
    const btScalar ms = ma + mb;
    if (ms <= 0) return;
    btSoftBody::SContact c;
    c.m_normal = p / -btSqrt(d2);
    c.m_margin = m;
    c.m_node = node;
    c.m_face = face;
    c.m_weights = w;
    c.m_friction = body->m_cfg.kDF;
    c.m_cfm[0] = ma / ms * body->m_cfg.kSHR;
    c.m_cfm[1] = mb / ms * body->m_cfg.kSHR;
    body->m_scontacts.push_back(c);
    ++count;
  }

  btSoftBody* body = nullptr;
  const btVector3* rest = nullptr;
  btScalar margin = 0;
  btScalar skip2 = 0;
  int count = 0;
};

/// The soft-rigid world with the self-contacts added after Bullet's collision detection (contacts are cleared in
/// predictMotion and solved after detection, so this is the only place they can go).
class ClothWorld : public btSoftRigidDynamicsWorld {
 public:
  using btSoftRigidDynamicsWorld::btSoftRigidDynamicsWorld;

  void performDiscreteCollisionDetection() override {
    btSoftRigidDynamicsWorld::performDiscreteCollisionDetection();
    if (collider.body == nullptr) return;
    const auto start = Clock::now();
    btSoftBody* body = collider.body;
    collider.count = 0;
    if (body->m_ndbvt.m_root != nullptr && body->m_fdbvt.m_root != nullptr) {
      body->m_ndbvt.collideTT(body->m_ndbvt.m_root, body->m_fdbvt.m_root, collider);
    }
    self_collision_seconds += seconds(start, Clock::now());
  }

  SelfCollider collider;
  double self_collision_seconds = 0.0;
};

}  // namespace

void ClothParameters::validate(const char* where) const {
  const std::string at = where;
  const auto positive = [&](double v, const char* name) {
    if (!(v > 0.0) || !std::isfinite(v)) throw std::invalid_argument(at + ": cloth '" + name + "' must be > 0");
  };
  const auto unit = [&](double v, const char* name, bool zero_ok, bool one_ok) {
    const bool ok = (zero_ok ? v >= 0.0 : v > 0.0) && (one_ok ? v <= 1.0 : v < 1.0);
    if (!ok) {
      throw std::invalid_argument(at + ": cloth '" + name + "' must be in " + (zero_ok ? "[0, " : "(0, ") +
                                  (one_ok ? "1]" : "1)"));
    }
  };
  positive(length, "length");
  positive(width, "width");
  positive(mass, "mass");
  positive(thickness, "thickness");
  positive(step, "step");
  positive(max_node_speed, "max_node_speed");
  if (!(max_stretch > 1.0) || !std::isfinite(max_stretch)) {
    throw std::invalid_argument(at + ": cloth 'max_stretch' must be > 1");
  }
  if (nodes_x < 2 || nodes_y < 2) throw std::invalid_argument(at + ": cloth 'nodes' must be at least 2 x 2");
  if (position_iterations < 1) throw std::invalid_argument(at + ": cloth 'position_iterations' must be >= 1");
  if (!std::isfinite(strain_limit)) throw std::invalid_argument(at + ": cloth 'strain_limit' must be finite");
  unit(stretch_stiffness, "stretch_stiffness", false, true);
  unit(bending_stiffness, "bending_stiffness", true, true);
  unit(damping, "damping", true, false);
  unit(friction, "friction", true, true);
  if (!pose.matrix().allFinite()) throw std::invalid_argument(at + ": cloth 'pose' must be finite");
}

const char* toString(ClothDivergence divergence) noexcept {
  switch (divergence) {
    case ClothDivergence::None:
      return "None";
    case ClothDivergence::NotFinite:
      return "NotFinite";
    case ClothDivergence::NodeSpeed:
      return "NodeSpeed";
    case ClothDivergence::Stretch:
      return "Stretch";
  }
  return "Unknown";
}

struct Cloth::Impl {
  ClothParameters parameters;
  std::optional<Table> table;
  std::vector<Obstacle> obstacles;
  /// Per obstacle: the world-to-obstacle transform, and the sphere about its centre and the world-axis-aligned box
  /// that contain it (a node farther from either than the margin cannot touch it: projectOutOfObstacles skips it;
  /// the box is what skips a floor's or a torso's far nodes, the sphere a ball's).
  std::vector<Eigen::Isometry3d> obstacle_inverse;
  std::vector<double> obstacle_radius;
  std::vector<Eigen::Vector3d> obstacle_half_extent;
  Eigen::Vector3d gravity;
  int gripper_count = 0;

  std::unique_ptr<btSoftBodyRigidBodyCollisionConfiguration> configuration;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btDbvtBroadphase> broadphase;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver;
  std::unique_ptr<ClothWorld> world;
  std::unique_ptr<btBoxShape> table_shape;
  std::unique_ptr<btRigidBody> table_body;
  std::unique_ptr<SceneBodies> obstacle_bodies;
  std::unique_ptr<btSphereShape> gripper_shape;
  std::vector<std::unique_ptr<btRigidBody>> grippers;
  std::unique_ptr<btSoftBody> soft;
  std::vector<btVector3> rest_bt;

  Eigen::Matrix3Xd vertices, velocities, rest;
  Eigen::Matrix3Xi triangles;
  std::vector<Vector6d> wrenches;
  /// Pull on each gripper of this step's pinning, tethers and strain limiting (their impulses on the nodes,
  /// reversed), [force; torque about the gripper's origin] [N, N m].
  std::vector<Vector6d> constraint_pull;
  std::vector<Vector6d> twists;
  std::vector<Eigen::Isometry3d> poses;
  std::vector<int> owner;  ///< Gripper holding each node, −1 if free.
  std::vector<int> grasped;
  /// Per node: the held node nearest to it on the rest mesh (−1 while no node is held) and their rest distance.
  std::vector<int> tether_node;
  std::vector<double> tether_rest;
  std::vector<btVector3> start_x;  ///< Node positions before limitStrain().
  std::vector<int> structural;     ///< Links between grid neighbours (structural edges).
  SimStatus status = SimStatus::Ok;
  ClothDivergence divergence = ClothDivergence::None;
  double max_stretch = 1.0;
  double max_edge_stretch = 1.0;
  ClothTimings timings;

  void build();
  void destroy() noexcept;
  void copyMesh() noexcept;
  ClothDivergence check() noexcept;
  void updateTethers() noexcept;
  void limitStrain(double dt) noexcept;
  void pinHeldNodes(double dt) noexcept;
  void projectOutOfObstacles() noexcept;
  /// Adds to constraint_pull[gripper] the pull of moving `node` by `correction` this step (nothing for −1).
  void pull(int gripper, const btSoftBody::Node& node, const btVector3& correction) noexcept;
};

// Bullet's anchors are soft (an impulse per iteration towards the anchor point), so a lifted cloth drags its held
// nodes out of the gripper's grip and stretches the edges between them. After the solve, each held node takes its
// anchor point and the gripper's velocity there: the grip is rigid. The momentum that gives the node is added to the
// gripper's pull (its torque about the node's position before the pin, millimetres away).
void Cloth::Impl::pinHeldNodes(double dt) noexcept {
  const btSoftBody::Node* first = &soft->m_nodes[0];
  for (int a = 0; a < soft->m_anchors.size(); ++a) {
    btSoftBody::Anchor& anchor = soft->m_anchors[a];
    btSoftBody::Node& node = *anchor.m_node;
    const btVector3 offset = anchor.m_body->getWorldTransform().getBasis() * anchor.m_local;
    const btVector3 velocity = anchor.m_body->getLinearVelocity() + anchor.m_body->getAngularVelocity().cross(offset);
    pull(owner[static_cast<std::size_t>(&node - first)], node, (velocity - node.m_v) * dt);
    node.m_x = anchor.m_body->getWorldTransform().getOrigin() + offset;
    node.m_v = velocity;
  }
}

void Cloth::Impl::pull(int gripper, const btSoftBody::Node& node, const btVector3& correction) noexcept {
  if (gripper < 0 || !(node.m_im > 0.0)) return;
  const double dt = parameters.step;
  // The node's momentum change over the step, m Δx / dt, came from the gripper: the cloth pulls the other way.
  const Eigen::Vector3d force = -toEigen(correction) / (node.m_im * dt * dt);
  const btRigidBody& body = *grippers[static_cast<std::size_t>(gripper)];
  Vector6d& w = constraint_pull[static_cast<std::size_t>(gripper)];
  w.head<3>() += force;
  w.tail<3>() += toEigen(node.m_x - body.getWorldTransform().getOrigin()).cross(force);
}

void Cloth::Impl::updateTethers() noexcept {
  const int n = soft->m_nodes.size();
  std::fill(tether_node.begin(), tether_node.end(), -1);
  if (parameters.strain_limit < 0.0) return;
  for (int a = 0; a < n; ++a) {
    if (owner[static_cast<std::size_t>(a)] < 0) continue;
    for (int i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(i);
      const double d = (rest_bt[k] - rest_bt[static_cast<std::size_t>(a)]).length();
      if (tether_node[k] < 0 || d < tether_rest[k]) {
        tether_node[k] = a;
        tether_rest[k] = d;
      }
    }
  }
}

// Inextensibility after Bullet's solve, in position-based dynamics' way (positions move, velocities take the
// position change over the step); held nodes do not move. First the long-range attachments (tethers; Kim,
// Chentanez and Müller-Fischer, "Long range attachments", SCA 2012): a free node farther than (1 + limit) times
// its rest distance from its nearest held node (of any gripper) moves back onto that sphere. Then strain limiting
// (Provot, "Deformation constraints in a mass-spring model to describe rigid cloth behavior", 1995): each
// structural edge longer than (1 + limit) times its rest length is shortened to that length, its free ends moving
// equally, for a few Gauss-Seidel passes.
void Cloth::Impl::limitStrain(double dt) noexcept {
  const double limit = 1.0 + parameters.strain_limit;
  const int n = soft->m_nodes.size();
  for (int i = 0; i < n; ++i) start_x[static_cast<std::size_t>(i)] = soft->m_nodes[i].m_x;
  for (int i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (tether_node[k] < 0 || owner[k] >= 0) continue;
    btSoftBody::Node& node = soft->m_nodes[i];
    const btVector3 d = node.m_x - soft->m_nodes[tether_node[k]].m_x;
    const double length = d.length(), most = limit * tether_rest[k];
    if (!(length > most)) continue;
    const btVector3 correction = d * (most / length - 1.0);
    node.m_x += correction;
    pull(owner[static_cast<std::size_t>(tether_node[k])], node, correction);
  }
  const btSoftBody::Node* first = &soft->m_nodes[0];
  for (int pass = 0; pass < kStrainPasses; ++pass) {
    bool moved = false;
    for (const int l : structural) {
      btSoftBody::Link& link = soft->m_links[l];
      btSoftBody::Node& a = *link.m_n[0];
      btSoftBody::Node& b = *link.m_n[1];
      const btVector3 d = b.m_x - a.m_x;
      const double length = d.length(), most = limit * link.m_rl;
      if (!(length > most)) continue;
      const int owner_a = owner[static_cast<std::size_t>(&a - first)];
      const int owner_b = owner[static_cast<std::size_t>(&b - first)];
      if (owner_a >= 0 && owner_b >= 0) continue;
      const btVector3 correction = d * ((length - most) / length / (owner_a < 0 && owner_b < 0 ? 2.0 : 1.0));
      if (owner_a < 0) a.m_x += correction;
      if (owner_b < 0) b.m_x -= correction;
      // Between two free nodes the impulses cancel; a free node pulled towards a held one pulls its gripper.
      if (owner_b >= 0) pull(owner_b, a, correction);
      if (owner_a >= 0) pull(owner_a, b, -correction);
      moved = true;
    }
    if (!moved) break;
  }
  for (int i = 0; i < n; ++i) {
    soft->m_nodes[i].m_v += (soft->m_nodes[i].m_x - start_x[static_cast<std::size_t>(i)]) / dt;
  }
}

namespace {

/// Half the extent of the world-axis-aligned box about `o`'s centre that contains it [m].
Eigen::Vector3d boundingHalfExtent(const Obstacle& o) noexcept {
  Eigen::Vector3d local = Eigen::Vector3d::Constant(o.size.x());  // sphere
  if (o.shape == Obstacle::Shape::Cylinder) local = Eigen::Vector3d(o.size.x(), o.size.x(), 0.5 * o.size.y());
  if (o.shape == Obstacle::Shape::Box) local = 0.5 * o.size;
  return o.pose.linear().cwiseAbs() * local;
}

/// The radius of the smallest sphere about `o`'s centre that contains it [m].
double boundingRadius(const Obstacle& o) noexcept {
  switch (o.shape) {
    case Obstacle::Shape::Sphere:
      return o.size.x();
    case Obstacle::Shape::Cylinder:
      return std::hypot(o.size.x(), 0.5 * o.size.y());
    case Obstacle::Shape::Box:
      break;
  }
  return 0.5 * o.size.norm();
}

/// Signed distance from `p` to the surface of `o` (negative inside) and the outward normal there, both in the world;
/// `inverse` is o.pose.inverse().
double signedDistance(const Obstacle& o, const Eigen::Isometry3d& inverse, const Eigen::Vector3d& p,
                      Eigen::Vector3d& normal) noexcept {
  const Eigen::Vector3d x = inverse * p;  // in the obstacle's frame
  Eigen::Vector3d n_local = Eigen::Vector3d::UnitZ();
  double d = 0.0;
  switch (o.shape) {
    case Obstacle::Shape::Sphere: {
      const double r = x.norm();
      if (r > 1e-12) n_local = x / r;
      d = r - o.size.x();
      break;
    }
    case Obstacle::Shape::Cylinder: {
      const double rho = x.head<2>().norm(), radius = o.size.x(), half = 0.5 * o.size.y();
      const Eigen::Vector3d radial =
          rho > 1e-12 ? Eigen::Vector3d(x.x() / rho, x.y() / rho, 0.0) : Eigen::Vector3d::UnitX();
      const double side = rho - radius, cap = std::abs(x.z()) - half;
      const Eigen::Vector3d axial(0.0, 0.0, x.z() >= 0.0 ? 1.0 : -1.0);
      if (side > 0.0 && cap > 0.0) {  // beyond the rim
        const Eigen::Vector3d e = side * radial + cap * axial;
        d = e.norm();
        n_local = e / d;
      } else if (side > cap) {
        d = side;
        n_local = radial;
      } else {
        d = cap;
        n_local = axial;
      }
      break;
    }
    case Obstacle::Shape::Box: {
      const Eigen::Vector3d q = x.cwiseAbs() - 0.5 * o.size;
      if ((q.array() > 0.0).any()) {
        const Eigen::Vector3d e = q.cwiseMax(0.0).cwiseProduct(x.cwiseSign());
        d = e.norm();
        n_local = e / d;
      } else {
        Eigen::Index axis = 0;
        d = q.maxCoeff(&axis);
        n_local = Eigen::Vector3d::Zero();
        n_local[axis] = x[axis] >= 0.0 ? 1.0 : -1.0;
      }
      break;
    }
  }
  normal = o.pose.linear() * n_local;
  return d;
}

}  // namespace

// Bullet's soft-rigid contacts sample each shape's distance on a sparse field, which lets the cloth sink a centimetre
// and more into small curved shapes (a neck, a head: see kCurvedSdfVoxel). The obstacles are primitives whose
// distance is known exactly: after the step, a free node closer to one than the cloth's margin is put on the margin,
// loses the velocity into the surface and, by Coulomb friction, as much of its sliding velocity (the fabric's
// friction times the obstacle's).
void Cloth::Impl::projectOutOfObstacles() noexcept {
  const double margin = parameters.thickness;
  const int n = soft->m_nodes.size();
  for (std::size_t k = 0; k < obstacles.size(); ++k) {
    const Obstacle& o = obstacles[k];
    if (!o.collides) continue;
    const double mu = parameters.friction * o.friction;
    const Eigen::Vector3d centre = o.pose.translation();
    const double reach = obstacle_radius[k] + margin;
    // Beyond the box by the margin and a hair, a node is farther than the margin (the distance's rounding aside).
    const Eigen::Vector3d box_reach = obstacle_half_extent[k].array() + (margin + 1e-9);
    for (int i = 0; i < n; ++i) {
      if (owner[static_cast<std::size_t>(i)] >= 0) continue;
      btSoftBody::Node& node = soft->m_nodes[i];
      const Eigen::Vector3d x = toEigen(node.m_x);
      if (((x - centre).cwiseAbs() - box_reach).maxCoeff() > 0.0) continue;  // beyond its bounding box's margin
      if ((x - centre).squaredNorm() >= reach * reach) continue;             // beyond its bounding sphere's
      Eigen::Vector3d normal;
      const double d = signedDistance(o, obstacle_inverse[k], x, normal);
      if (!(d < margin)) continue;
      node.m_x += toBullet(normal * (margin - d));
      Eigen::Vector3d v = toEigen(node.m_v);
      const double vn = v.dot(normal);
      if (vn >= 0.0) continue;
      const Eigen::Vector3d tangential = v - vn * normal;
      const double slide = tangential.norm(), stop = mu * -vn;
      v = slide > stop ? Eigen::Vector3d(tangential * (1.0 - stop / slide)) : Eigen::Vector3d::Zero();
      node.m_v = toBullet(v);
    }
  }
}

void Cloth::Impl::destroy() noexcept {
  if (world) {
    if (soft) world->removeSoftBody(soft.get());
    for (auto& g : grippers) world->removeRigidBody(g.get());
    obstacle_bodies.reset();
    if (table_body) world->removeRigidBody(table_body.get());
  }
  soft.reset();
  grippers.clear();
  table_body.reset();
  world.reset();
  solver.reset();
  broadphase.reset();
  dispatcher.reset();
  configuration.reset();
}

void Cloth::Impl::build() {
  destroy();
  configuration = std::make_unique<btSoftBodyRigidBodyCollisionConfiguration>();
  dispatcher = std::make_unique<btCollisionDispatcher>(configuration.get());
  broadphase = std::make_unique<btDbvtBroadphase>();
  solver = std::make_unique<btSequentialImpulseConstraintSolver>();
  world = std::make_unique<ClothWorld>(dispatcher.get(), broadphase.get(), solver.get(), configuration.get());
  world->setGravity(toBullet(gravity));
  btSoftBodyWorldInfo& info = world->getWorldInfo();
  info.m_gravity = toBullet(gravity);
  info.air_density = 0;
  info.m_sparsesdf.Initialize();
  const bool curved = std::any_of(obstacles.begin(), obstacles.end(),
                                  [](const Obstacle& o) { return o.collides && o.shape != Obstacle::Shape::Box; });
  info.m_sparsesdf.setDefaultVoxelsz(curved ? kCurvedSdfVoxel : kSdfVoxel);
  info.m_sparsesdf.Reset();

  // Table: a static box (if the scene has one).
  if (table) {
    table_shape = std::make_unique<btBoxShape>(toBullet(0.5 * table->size));
    btRigidBody::btRigidBodyConstructionInfo table_info(0.0, nullptr, table_shape.get());
    table_info.m_startWorldTransform = toBulletTransform(table->pose);
    table_info.m_friction = table->friction;
    table_body = std::make_unique<btRigidBody>(table_info);
    world->addRigidBody(table_body.get());
  }
  obstacle_bodies = std::make_unique<SceneBodies>(*world, obstacles);

  // Grippers: heavy bodies without gravity, in a collision group that collides with nothing, parked above the
  // cloth's centre until the owner moves them; always built there, so a rebuilt cloth starts as a new one does.
  poses.assign(static_cast<std::size_t>(gripper_count), Eigen::Isometry3d::Identity());
  for (int g = 0; g < gripper_count; ++g) {
    poses[static_cast<std::size_t>(g)].translation() = parameters.pose * Eigen::Vector3d(0.0, 0.0, 0.5 + 0.1 * g);
  }
  twists.assign(static_cast<std::size_t>(gripper_count), Vector6d::Zero());
  gripper_shape = std::make_unique<btSphereShape>(0.01);
  for (int g = 0; g < gripper_count; ++g) {
    btRigidBody::btRigidBodyConstructionInfo info_g(kGripperMass, nullptr, gripper_shape.get(),
                                                    btVector3(kGripperInertia, kGripperInertia, kGripperInertia));
    info_g.m_startWorldTransform = toBulletTransform(poses[static_cast<std::size_t>(g)]);
    auto body = std::make_unique<btRigidBody>(info_g);
    body->setFlags(body->getFlags() | BT_DISABLE_WORLD_GRAVITY);
    body->setActivationState(DISABLE_DEACTIVATION);
    body->setDamping(0.0, 0.0);
    world->addRigidBody(body.get(), btBroadphaseProxy::SensorTrigger, 0);
    grippers.push_back(std::move(body));
  }

  // The patch, centred on parameters.pose, in its xy plane.
  const ClothParameters& p = parameters;
  const auto corner = [&](double sx, double sy) {
    return toBullet(p.pose * Eigen::Vector3d(0.5 * sx * p.length, 0.5 * sy * p.width, 0.0));
  };
  soft.reset(btSoftBodyHelpers::CreatePatch(info, corner(-1, -1), corner(1, -1), corner(-1, 1), corner(1, 1), p.nodes_x,
                                            p.nodes_y, 0, true));
  soft->getCollisionShape()->setMargin(p.thickness);
  soft->m_materials[0]->m_kLST = p.stretch_stiffness;
  if (p.bending_stiffness > 0.0) {
    btSoftBody::Material* bending = soft->appendMaterial();
    bending->m_kLST = p.bending_stiffness;
    // Flexion links two nodes apart along the grid's axes (the mass-spring cloth's bending springs). Bullet's
    // generateBendingConstraints(2) also links every node to those two links away across the diagonals: twice the
    // links, and the link solver was a third of a fold rollout's time (docs/RESULTS.md "How much the fabric
    // stretches").
    for (int iy = 0; iy < p.nodes_y; ++iy) {
      for (int ix = 0; ix < p.nodes_x; ++ix) {
        if (ix + 2 < p.nodes_x) soft->appendLink(iy * p.nodes_x + ix, iy * p.nodes_x + ix + 2, bending);
        if (iy + 2 < p.nodes_y) soft->appendLink(iy * p.nodes_x + ix, (iy + 2) * p.nodes_x + ix, bending);
      }
    }
  }
  soft->m_cfg.piterations = p.position_iterations;
  soft->m_cfg.kDF = p.friction;
  soft->m_cfg.kDP = p.damping;
  soft->m_cfg.kAHR = 1.0;
  // VF_SS builds the face tree the self-collision detection runs on.
  soft->m_cfg.collisions = btSoftBody::fCollision::SDF_RS | (p.self_collision ? btSoftBody::fCollision::VF_SS : 0);
  soft->setTotalMass(p.mass, false);
  soft->setActivationState(DISABLE_DEACTIVATION);
  soft->m_anchors.reserve(soft->m_nodes.size());
  world->addSoftBody(soft.get());

  const int n = soft->m_nodes.size();
  rest_bt.resize(static_cast<std::size_t>(n));
  rest.resize(3, n);
  for (int i = 0; i < n; ++i) {
    rest_bt[static_cast<std::size_t>(i)] = soft->m_nodes[i].m_x;
    rest.col(i) = toEigen(soft->m_nodes[i].m_x);
  }
  triangles.resize(3, soft->m_faces.size());
  for (int f = 0; f < soft->m_faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) triangles(k, f) = static_cast<int>(soft->m_faces[f].m_n[k] - &soft->m_nodes[0]);
  }
  vertices = rest;
  velocities.setZero(3, n);
  owner.assign(static_cast<std::size_t>(n), -1);
  grasped.assign(static_cast<std::size_t>(gripper_count), 0);
  tether_node.assign(static_cast<std::size_t>(n), -1);
  tether_rest.assign(static_cast<std::size_t>(n), 0.0);
  start_x.resize(static_cast<std::size_t>(n));
  structural.clear();
  for (int l = 0; l < soft->m_links.size(); ++l) {
    if (isStructural(soft->m_links[l], &soft->m_nodes[0], p.nodes_x)) structural.push_back(l);
  }
  wrenches.assign(static_cast<std::size_t>(gripper_count), Vector6d::Zero());
  constraint_pull.assign(static_cast<std::size_t>(gripper_count), Vector6d::Zero());
  status = SimStatus::Ok;
  divergence = ClothDivergence::None;
  max_stretch = 1.0;
  max_edge_stretch = 1.0;

  if (p.self_collision) {
    const double spacing = std::max(p.length / (p.nodes_x - 1), p.width / (p.nodes_y - 1));
    world->collider.body = soft.get();
    world->collider.rest = rest_bt.data();
    world->collider.margin = 2.0 * p.thickness;
    world->collider.skip2 = (2.1 * spacing) * (2.1 * spacing);
  }
}

void Cloth::Impl::copyMesh() noexcept {
  for (int i = 0; i < soft->m_nodes.size(); ++i) {
    vertices.col(i) = toEigen(soft->m_nodes[i].m_x);
    velocities.col(i) = toEigen(soft->m_nodes[i].m_v);
  }
}

ClothDivergence Cloth::Impl::check() noexcept {
  const double speed2 = parameters.max_node_speed * parameters.max_node_speed;
  bool too_fast = false;
  for (int i = 0; i < soft->m_nodes.size(); ++i) {
    const btSoftBody::Node& node = soft->m_nodes[i];
    for (int k = 0; k < 3; ++k) {
      if (!std::isfinite(node.m_x[k]) || !std::isfinite(node.m_v[k])) return ClothDivergence::NotFinite;
    }
    too_fast = too_fast || node.m_v.length2() > speed2;
  }
  if (too_fast) return ClothDivergence::NodeSpeed;
  double stretch = 0.0, edge_stretch = 0.0;
  for (int l = 0; l < soft->m_links.size(); ++l) {
    const btSoftBody::Link& link = soft->m_links[l];
    stretch = std::max(stretch, (link.m_n[0]->m_x - link.m_n[1]->m_x).length() / link.m_rl);
  }
  for (const int l : structural) {
    const btSoftBody::Link& link = soft->m_links[l];
    edge_stretch = std::max(edge_stretch, (link.m_n[0]->m_x - link.m_n[1]->m_x).length() / link.m_rl);
  }
  max_stretch = stretch;
  max_edge_stretch = edge_stretch;
  return stretch > parameters.max_stretch ? ClothDivergence::Stretch : ClothDivergence::None;
}

Cloth::Cloth(const ClothParameters& parameters, const std::optional<Table>& table, int grippers,
             const Eigen::Vector3d& gravity, const std::vector<Obstacle>& obstacles)
    : impl_(std::make_unique<Impl>()) {
  parameters.validate("cloth");
  if (table) table->validate("cloth");
  for (const Obstacle& obstacle : obstacles) obstacle.validate("cloth");
  if (grippers < 0) throw std::invalid_argument("cloth: the number of grippers must be >= 0");
  if (!gravity.allFinite()) throw std::invalid_argument("cloth: gravity must be finite");
  impl_->parameters = parameters;
  impl_->table = table;
  impl_->gravity = gravity;
  impl_->gripper_count = grippers;
  impl_->obstacles = obstacles;
  for (const Obstacle& obstacle : obstacles) {
    impl_->obstacle_inverse.push_back(obstacle.pose.inverse());
    impl_->obstacle_radius.push_back(boundingRadius(obstacle));
    impl_->obstacle_half_extent.push_back(boundingHalfExtent(obstacle));
  }
  impl_->build();
}

Cloth::~Cloth() {
  if (impl_) impl_->destroy();
}
Cloth::Cloth(Cloth&&) noexcept = default;
Cloth& Cloth::operator=(Cloth&&) noexcept = default;

const ClothParameters& Cloth::parameters() const noexcept {
  return impl_->parameters;
}
int Cloth::nodeCount() const noexcept {
  return static_cast<int>(impl_->vertices.cols());
}
int Cloth::gripperCount() const noexcept {
  return impl_->gripper_count;
}
SimStatus Cloth::status() const noexcept {
  return impl_->status;
}
ClothDivergence Cloth::divergence() const noexcept {
  return impl_->divergence;
}
const Eigen::Matrix3Xd& Cloth::vertices() const noexcept {
  return impl_->vertices;
}
const Eigen::Matrix3Xd& Cloth::velocities() const noexcept {
  return impl_->velocities;
}
const Eigen::Matrix3Xi& Cloth::triangles() const noexcept {
  return impl_->triangles;
}
const Eigen::Matrix3Xd& Cloth::restVertices() const noexcept {
  return impl_->rest;
}
double Cloth::maxEdgeStretch() const noexcept {
  return impl_->max_edge_stretch;
}

double Cloth::maxStretch() const noexcept {
  return impl_->max_stretch;
}
int Cloth::selfContactCount() const noexcept {
  return impl_->world->collider.count;
}
const ClothTimings& Cloth::timings() const noexcept {
  return impl_->timings;
}
void Cloth::resetTimings() noexcept {
  impl_->timings = ClothTimings();
}

SimStatus Cloth::setGripperMotion(int gripper, const Eigen::Isometry3d& pose, const Vector6d& twist) noexcept {
  if (gripper < 0 || gripper >= impl_->gripper_count) return SimStatus::InvalidArgument;
  if (!pose.matrix().allFinite() || !twist.allFinite()) return SimStatus::InvalidArgument;
  const auto g = static_cast<std::size_t>(gripper);
  impl_->poses[g] = pose;
  impl_->twists[g] = twist;
  btRigidBody& body = *impl_->grippers[g];
  const btTransform transform = toBulletTransform(pose);
  body.setWorldTransform(transform);
  body.setInterpolationWorldTransform(transform);
  body.setLinearVelocity(toBullet(twist.head<3>()));
  body.setAngularVelocity(toBullet(twist.tail<3>()));
  body.setInterpolationLinearVelocity(toBullet(twist.head<3>()));
  body.setInterpolationAngularVelocity(toBullet(twist.tail<3>()));
  return SimStatus::Ok;
}

Eigen::Isometry3d Cloth::gripperPose(int gripper) const noexcept {
  if (gripper < 0 || gripper >= impl_->gripper_count) return Eigen::Isometry3d::Identity();
  return impl_->poses[static_cast<std::size_t>(gripper)];
}

SimStatus Cloth::step() noexcept {
  Impl& m = *impl_;
  if (m.status != SimStatus::Ok) return m.status;
  const double dt = m.parameters.step;
  // Each gripper starts the step with the twist it was given; what the anchors add is the cloth's pull.
  for (int g = 0; g < m.gripper_count; ++g) {
    const auto k = static_cast<std::size_t>(g);
    m.grippers[k]->setLinearVelocity(toBullet(m.twists[k].head<3>()));
    m.grippers[k]->setAngularVelocity(toBullet(m.twists[k].tail<3>()));
  }
  const double self_before = m.world->self_collision_seconds;
  const auto start = Clock::now();
  m.world->stepSimulation(dt, 0, dt);
  for (Vector6d& w : m.constraint_pull) w.setZero();
  m.pinHeldNodes(dt);
  if (m.parameters.strain_limit >= 0.0) m.limitStrain(dt);
  m.projectOutOfObstacles();
  const auto stepped = Clock::now();
  const double self_seconds = m.world->self_collision_seconds - self_before;
  m.timings.bullet += seconds(start, stepped) - self_seconds;
  m.timings.self_collision += self_seconds;
  ++m.timings.steps;

  m.divergence = m.check();
  if (m.divergence != ClothDivergence::None) {
    m.status = SimStatus::ClothDiverged;
    for (Vector6d& w : m.wrenches) w.setZero();
  } else {
    m.copyMesh();
    for (int g = 0; g < m.gripper_count; ++g) {
      const auto k = static_cast<std::size_t>(g);
      const btRigidBody& body = *m.grippers[k];
      Vector6d& w = m.wrenches[k];
      if (m.grasped[k] == 0) {
        w.setZero();
        continue;
      }
      w.head<3>() = kGripperMass / dt * (toEigen(body.getLinearVelocity()) - m.twists[k].head<3>());
      w.tail<3>() = kGripperInertia / dt * (toEigen(body.getAngularVelocity()) - m.twists[k].tail<3>());
      w += m.constraint_pull[k];
    }
  }
  m.timings.bookkeeping += seconds(stepped, Clock::now());
  return m.status;
}

SimStatus Cloth::grasp(int gripper, double radius, int* attached) noexcept {
  Impl& m = *impl_;
  if (attached != nullptr) *attached = 0;
  if (gripper < 0 || gripper >= m.gripper_count || !std::isfinite(radius) || radius < 0.0) {
    return SimStatus::InvalidArgument;
  }
  if (m.status != SimStatus::Ok) return m.status;
  const auto g = static_cast<std::size_t>(gripper);
  const btVector3 origin = toBullet(m.poses[g].translation());
  int count = 0;
  for (int i = 0; i < m.soft->m_nodes.size(); ++i) {
    if (m.owner[static_cast<std::size_t>(i)] >= 0) continue;
    if ((m.soft->m_nodes[i].m_x - origin).length() > radius) continue;
    m.soft->appendAnchor(i, m.grippers[g].get(), false, 1.0);
    m.owner[static_cast<std::size_t>(i)] = gripper;
    ++count;
  }
  m.grasped[g] += count;
  if (count > 0) m.updateTethers();
  if (attached != nullptr) *attached = count;
  return SimStatus::Ok;
}

// GCC 12 cannot see that btSoftBody::Anchor's members are initialised when an anchor is copied (Bullet's struct
// has no constructor); the copies below are of anchors Bullet filled in.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
SimStatus Cloth::release(int gripper) noexcept {
  Impl& m = *impl_;
  if (gripper < 0 || gripper >= m.gripper_count) return SimStatus::InvalidArgument;
  const auto g = static_cast<std::size_t>(gripper);
  btAlignedObjectArray<btSoftBody::Anchor>& anchors = m.soft->m_anchors;
  int kept = 0;
  for (int a = 0; a < anchors.size(); ++a) {
    if (anchors[a].m_body == m.grippers[g].get()) {
      btSoftBody::Node* node = anchors[a].m_node;
      node->m_battach = 0;
      m.owner[static_cast<std::size_t>(node - &m.soft->m_nodes[0])] = -1;
      continue;
    }
    anchors[kept++] = anchors[a];
  }
  anchors.resize(kept);
  m.grasped[g] = 0;
  m.updateTethers();
  m.wrenches[g].setZero();
  return SimStatus::Ok;
}
#pragma GCC diagnostic pop

int Cloth::graspedNodeCount(int gripper) const noexcept {
  if (gripper < 0 || gripper >= impl_->gripper_count) return 0;
  return impl_->grasped[static_cast<std::size_t>(gripper)];
}

const Vector6d& Cloth::gripperWrench(int gripper) const noexcept {
  static const Vector6d kZero = Vector6d::Zero();
  if (gripper < 0 || gripper >= impl_->gripper_count) return kZero;
  return impl_->wrenches[static_cast<std::size_t>(gripper)];
}

void Cloth::reset() {
  impl_->build();
}

}  // namespace bimanual_skills::sim
