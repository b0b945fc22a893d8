// The cloth: resting on the table, mesh access, grasp/hang/release with the pull on the grippers equal to the
// cloth's weight, self-collision of a fold (checked against the same fold without it), divergence reported as a
// status; and the cloth in the full simulation, grasped by the arms' tools.
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "bimanual_skills/sim/cloth.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <tuple>

namespace bs = bimanual_skills;
using bs::sim::Cloth;
using bs::sim::ClothDivergence;
using bs::sim::ClothParameters;
using bs::sim::SimStatus;
using bs::sim::Table;
using bs::sim::Vector6d;

namespace {

constexpr double kTop = 0.15;  // table top [m]

Table table() {
  Table t;
  t.pose.translation() = Eigen::Vector3d(0.55, 0.0, 0.0);
  t.size = Eigen::Vector3d(0.7, 1.2, 0.3);
  return t;
}

/// The default patch (0.5 × 0.6 m, 20 × 24 nodes, 0.22 kg) lying on the table, centred at x = 0.5.
ClothParameters patch() {
  ClothParameters p;
  p.pose.translation() = Eigen::Vector3d(0.5, 0.0, kTop + p.thickness);
  return p;
}

Eigen::Isometry3d at(const Eigen::Vector3d& position) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = position;
  return pose;
}

/// A colliding obstacle (Obstacle::size's convention for `shape`) centred at `position`, upright.
bs::sim::Obstacle obstacle(const std::string& name, bs::sim::Obstacle::Shape shape, const Eigen::Vector3d& size,
                           const Eigen::Vector3d& position) {
  bs::sim::Obstacle o;
  o.name = name;
  o.shape = shape;
  o.size = size;
  o.pose = at(position);
  return o;
}

/// Moves gripper g along p(t) (velocity by differences) for `duration` seconds of cloth steps.
template <typename Path>
void follow(Cloth& cloth, const Path& path, double t0, double duration) {
  const double dt = cloth.parameters().step;
  for (double t = t0; t < t0 + duration - 1e-12; t += dt) {
    for (int g = 0; g < cloth.gripperCount(); ++g) {
      const Eigen::Vector3d p = path(g, t), p_next = path(g, t + dt);
      Vector6d twist = Vector6d::Zero();
      twist.head<3>() = (p_next - p) / dt;
      ASSERT_EQ(cloth.setGripperMotion(g, at(p), twist), SimStatus::Ok);
    }
    ASSERT_EQ(cloth.step(), SimStatus::Ok) << "t = " << t << " " << toString(cloth.divergence());
  }
}

/// Folds the patch in half along y: the grippers take the two corners of the far edge (x = 0.75) over to the near
/// edge (x = 0.25) on half circles, lay them down, release; then the cloth settles. Returns the cloth.
Cloth fold(bool self_collision) {
  ClothParameters p = patch();
  p.self_collision = self_collision;
  Cloth cloth(p, table(), 2);
  const double far = 0.75, centre = 0.5, radius = 0.24, lift = 0.03;
  const auto corner = [&](int g) { return Eigen::Vector3d(far, g == 0 ? -0.3 : 0.3, kTop + lift); };
  for (int g = 0; g < 2; ++g) {
    EXPECT_EQ(cloth.setGripperMotion(g, at(corner(g)), Vector6d::Zero()), SimStatus::Ok);
    int attached = 0;
    EXPECT_EQ(cloth.grasp(g, 0.045, &attached), SimStatus::Ok);
    EXPECT_GT(attached, 0);
  }
  const double T = 2.5;
  const auto path = [&](int g, double t) {
    double s = std::min(1.0, std::max(0.0, t / T));
    s = s * s * (3.0 - 2.0 * s);
    const double angle = M_PI * s;
    return Eigen::Vector3d(centre + radius * std::cos(angle), corner(g).y(),
                           kTop + lift + 0.8 * radius * std::sin(angle));
  };
  follow(cloth, path, 0.0, T + 0.3);
  for (int g = 0; g < 2; ++g) EXPECT_EQ(cloth.release(g), SimStatus::Ok);
  const auto still = [&](int g, double) { return path(g, T); };
  follow(cloth, still, T + 0.3, 0.7);
  return cloth;
}

}  // namespace

TEST(SimCloth, RestsOnTheTableAndExposesItsMesh) {
  Cloth cloth(patch(), table(), 2);
  EXPECT_EQ(cloth.nodeCount(), 20 * 24);
  ASSERT_EQ(cloth.vertices().cols(), 480);
  ASSERT_EQ(cloth.triangles().cols(), 19 * 23 * 2);
  for (int f = 0; f < cloth.triangles().cols(); ++f) {
    const Eigen::Vector3i t = cloth.triangles().col(f);
    EXPECT_TRUE(t.minCoeff() >= 0 && t.maxCoeff() < 480 && t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
  }
  // Node (i, j) is column j·nodes_x + i: corners of the patch.
  EXPECT_TRUE(cloth.restVertices().col(0).head<2>().isApprox(Eigen::Vector2d(0.25, -0.3)));
  EXPECT_TRUE(cloth.restVertices().col(19).head<2>().isApprox(Eigen::Vector2d(0.75, -0.3)));
  EXPECT_TRUE(cloth.restVertices().col(479).head<2>().isApprox(Eigen::Vector2d(0.75, 0.3)));
  for (int k = 0; k < 100; ++k) ASSERT_EQ(cloth.step(), SimStatus::Ok);
  // It lies on the table top at its thickness (Bullet's default SDF resolution put it 2-3 cm inside).
  EXPECT_GT(cloth.vertices().row(2).minCoeff(), kTop + 0.5 * cloth.parameters().thickness);
  EXPECT_LT(cloth.vertices().row(2).maxCoeff(), kTop + 2.0 * cloth.parameters().thickness);
  EXPECT_LT(cloth.velocities().cwiseAbs().maxCoeff(), 0.05);
  EXPECT_EQ(cloth.gripperWrench(0), Vector6d::Zero());
}

TEST(SimCloth, HangingFromTwoCornersPullsItsWeightAndReleaseDropsIt) {
  Cloth cloth(patch(), table(), 2);
  const Eigen::Vector3d corners[2] = {Eigen::Vector3d(0.75, -0.3, kTop + 0.01),
                                      Eigen::Vector3d(0.75, 0.3, kTop + 0.01)};
  for (int g = 0; g < 2; ++g) {
    ASSERT_EQ(cloth.setGripperMotion(g, at(corners[g]), Vector6d::Zero()), SimStatus::Ok);
    int attached = 0;
    ASSERT_EQ(cloth.grasp(g, 0.03, &attached), SimStatus::Ok);
    int expected = 0;
    for (int i = 0; i < cloth.nodeCount(); ++i) expected += (cloth.vertices().col(i) - corners[g]).norm() <= 0.03;
    EXPECT_EQ(attached, expected);
    EXPECT_EQ(cloth.graspedNodeCount(g), attached);
  }
  // Lift 0.65 m in 0.65 s, then hold: the 0.5 m long patch hangs free.
  const auto path = [&](int g, double t) {
    return Eigen::Vector3d(corners[g] + Eigen::Vector3d(0.0, 0.0, std::min(t, 0.65)));
  };
  follow(cloth, path, 0.0, 0.65);
  for (int g = 0; g < 2; ++g) ASSERT_EQ(cloth.setGripperMotion(g, at(path(g, 0.65)), Vector6d::Zero()), SimStatus::Ok);
  const int hold_steps = static_cast<int>(3.0 / cloth.parameters().step);
  Eigen::Vector3d mean_force = Eigen::Vector3d::Zero();
  int samples = 0;
  for (int k = 0; k < hold_steps; ++k) {
    ASSERT_EQ(cloth.step(), SimStatus::Ok);
    if (k >= 2 * hold_steps / 3) {  // the last second, after the swing of the lift has died out
      mean_force += cloth.gripperWrench(0).head<3>() + cloth.gripperWrench(1).head<3>();
      ++samples;
    }
  }
  mean_force /= samples;
  const double weight = cloth.parameters().mass * 9.81;
  EXPECT_NEAR(mean_force.z(), -weight, 0.02 * weight) << mean_force.transpose();
  EXPECT_LT(mean_force.head<2>().norm(), 0.02 * weight);
  // The grasped nodes moved with the grippers.
  EXPECT_GT(cloth.vertices().row(2).maxCoeff(), kTop + 0.6);
  // Release: nothing held, no pull, and the cloth falls.
  const double highest = cloth.vertices().row(2).maxCoeff();
  for (int g = 0; g < 2; ++g) ASSERT_EQ(cloth.release(g), SimStatus::Ok);
  EXPECT_EQ(cloth.graspedNodeCount(0), 0);
  for (int k = 0; k < 50; ++k) ASSERT_EQ(cloth.step(), SimStatus::Ok);
  EXPECT_EQ(cloth.gripperWrench(0), Vector6d::Zero());
  EXPECT_LT(cloth.vertices().row(2).maxCoeff(), highest - 0.05);
}

TEST(SimCloth, SelfCollisionKeepsAFoldOnTopOfTheCloth) {
  // Nodes of the folded-over half lying over the bottom half (away from the crease and the near edge, past which the
  // fold may slide) that ended up at table level, through the bottom layer, instead of on it.
  const auto sunk = [](const Cloth& cloth) {
    int count = 0, total = 0;
    for (int i = 0; i < cloth.nodeCount(); ++i) {
      const Eigen::Vector3d rest = cloth.restVertices().col(i), now = cloth.vertices().col(i);
      if (rest.x() < 0.55 || std::abs(rest.y()) > 0.25 || now.x() < 0.28 || now.x() > 0.42) continue;
      ++total;
      count += now.z() < kTop + 1.5 * cloth.parameters().thickness;
    }
    return std::pair{count, total};
  };
  const Cloth with = fold(true);
  const auto [sunk_with, total] = sunk(with);
  ASSERT_GT(total, 40);
  EXPECT_EQ(sunk_with, 0) << "the fold lies on the cloth";
  // The folded half is above the bottom half: about two thicknesses above the table.
  double top_layer = 0.0;
  for (int i = 0; i < with.nodeCount(); ++i) {
    if (with.restVertices()(0, i) > 0.6 && std::abs(with.restVertices()(1, i)) < 0.25) {
      top_layer = std::max(top_layer, with.vertices()(2, i));
    }
  }
  EXPECT_GT(top_layer, kTop + 2.0 * with.parameters().thickness);
  // The same fold without self-collision sinks through (so the check above can fail).
  const Cloth without = fold(false);
  const auto [sunk_without, total_without] = sunk(without);
  EXPECT_GT(sunk_without, total_without / 2) << total_without;
}

TEST(SimCloth, DivergenceIsAStatusNotACrash) {
  // Yank: a grasped corner teleported 5 m away in one step.
  Cloth cloth(patch(), table(), 1);
  const Eigen::Vector3d corner(0.75, -0.3, kTop + 0.01);
  ASSERT_EQ(cloth.setGripperMotion(0, at(corner), Vector6d::Zero()), SimStatus::Ok);
  ASSERT_EQ(cloth.grasp(0, 0.03), SimStatus::Ok);
  for (int k = 0; k < 5; ++k) ASSERT_EQ(cloth.step(), SimStatus::Ok);
  const Eigen::Matrix3Xd before = cloth.vertices();
  ASSERT_EQ(cloth.setGripperMotion(0, at(corner + Eigen::Vector3d(0.0, 0.0, 5.0)), Vector6d::Zero()), SimStatus::Ok);
  EXPECT_EQ(cloth.step(), SimStatus::ClothDiverged);
  EXPECT_NE(cloth.divergence(), ClothDivergence::None);
  EXPECT_EQ(cloth.step(), SimStatus::ClothDiverged);  // frozen
  EXPECT_EQ(cloth.vertices(), before);                // the last valid mesh
  EXPECT_EQ(cloth.gripperWrench(0), Vector6d::Zero());
  EXPECT_EQ(cloth.grasp(0, 0.03), SimStatus::ClothDiverged);
  cloth.reset();
  EXPECT_EQ(cloth.status(), SimStatus::Ok);
  EXPECT_EQ(cloth.vertices(), cloth.restVertices());
  EXPECT_EQ(cloth.graspedNodeCount(0), 0);
  EXPECT_EQ(cloth.step(), SimStatus::Ok);

  // Speed: a gripper moving at 100 m/s drags its nodes beyond the 20 m/s bound.
  Cloth fast(patch(), table(), 1);
  ASSERT_EQ(fast.setGripperMotion(0, at(corner), Vector6d::Zero()), SimStatus::Ok);
  ASSERT_EQ(fast.grasp(0, 0.03), SimStatus::Ok);
  Vector6d twist = Vector6d::Zero();
  twist[2] = 100.0;
  ASSERT_EQ(fast.setGripperMotion(0, at(corner), twist), SimStatus::Ok);
  EXPECT_EQ(fast.step(), SimStatus::ClothDiverged);
  EXPECT_EQ(fast.divergence(), ClothDivergence::NodeSpeed);

  // Stretch: an absurdly tight bound (5 %) breaks as soon as the cloth hangs from a corner.
  ClothParameters tight = patch();
  tight.max_stretch = 1.05;
  tight.stretch_stiffness = 0.2;
  tight.strain_limit = -1.0;
  Cloth stretched(tight, table(), 1);
  ASSERT_EQ(stretched.setGripperMotion(0, at(corner), Vector6d::Zero()), SimStatus::Ok);
  ASSERT_EQ(stretched.grasp(0, 0.03), SimStatus::Ok);
  SimStatus status = SimStatus::Ok;
  for (int k = 0; k < 500 && status == SimStatus::Ok; ++k) {
    Vector6d up = Vector6d::Zero();
    up[2] = 1.0;
    ASSERT_EQ(stretched.setGripperMotion(0, at(corner + Eigen::Vector3d(0.0, 0.0, 0.004 * k)), up), SimStatus::Ok);
    status = stretched.step();
  }
  EXPECT_EQ(status, SimStatus::ClothDiverged);
  EXPECT_EQ(stretched.divergence(), ClothDivergence::Stretch);

  // NaN: a node mass so small its inverse overflows.
  ClothParameters absurd = patch();
  absurd.mass = 1e-320;
  Cloth nan(absurd, table(), 0);
  status = SimStatus::Ok;
  for (int k = 0; k < 10 && status == SimStatus::Ok; ++k) status = nan.step();
  EXPECT_EQ(status, SimStatus::ClothDiverged);
  EXPECT_EQ(nan.divergence(), ClothDivergence::NotFinite);
  EXPECT_TRUE(nan.vertices().allFinite());
}

TEST(SimCloth, EdgeStretchIsTheLargestOfTheMeshNeighbours) {
  // A corner lifted 0.3 m: the cloth hangs from it and its edges stretch. The reference: the length ratio of every
  // pair of grid neighbours, computed from the mesh the cloth exposes.
  const ClothParameters parameters = patch();
  Cloth cloth(parameters, table(), 1);
  EXPECT_DOUBLE_EQ(cloth.maxEdgeStretch(), 1.0);
  const Eigen::Vector3d corner(0.75, -0.3, kTop + 0.01);
  ASSERT_EQ(cloth.setGripperMotion(0, at(corner), Vector6d::Zero()), SimStatus::Ok);
  ASSERT_EQ(cloth.grasp(0, 0.03), SimStatus::Ok);
  follow(
      cloth, [&](int, double t) { return Eigen::Vector3d(corner + Eigen::Vector3d(0.0, 0.0, std::min(t, 0.3))); }, 0.0,
      0.5);
  const int nx = parameters.nodes_x, ny = parameters.nodes_y;
  const Eigen::Matrix3Xd &x = cloth.vertices(), &rest = cloth.restVertices();
  double reference = 0.0;
  for (int iy = 0; iy < ny; ++iy) {
    for (int ix = 0; ix < nx; ++ix) {
      const int a = iy * nx + ix;
      for (const int b : {ix + 1 < nx ? a + 1 : -1, iy + 1 < ny ? a + nx : -1}) {
        if (b < 0) continue;
        reference = std::max(reference, (x.col(a) - x.col(b)).norm() / (rest.col(a) - rest.col(b)).norm());
      }
    }
  }
  EXPECT_GT(reference, 1.001);
  EXPECT_NEAR(cloth.maxEdgeStretch(), reference, 1e-6);
  EXPECT_LE(cloth.maxEdgeStretch(), cloth.maxStretch());
}

TEST(SimCloth, StrainLimitKeepsAHangingClothFromStretching) {
  // Two corners jerked up at 1 m/s for 0.4 s and held there for 0.6 s: the cloth hangs from them. Without the strain
  // limit Bullet's links alone let its edges stretch by 30-45 %; with it (the default 5 %) no edge ends a step
  // beyond 8 % (four passes per step do not converge fully where a held node meets a hanging chain), and the held
  // nodes keep their rest distances (the grip is rigid).
  const auto hang = [](double strain_limit) {
    ClothParameters parameters = patch();
    parameters.strain_limit = strain_limit;
    Cloth cloth(parameters, table(), 2);
    const auto corner = [](int g) { return Eigen::Vector3d(0.75, g == 0 ? -0.3 : 0.3, kTop + 0.01); };
    for (int g = 0; g < 2; ++g) {
      EXPECT_EQ(cloth.setGripperMotion(g, at(corner(g)), Vector6d::Zero()), SimStatus::Ok);
      EXPECT_EQ(cloth.grasp(g, 0.03), SimStatus::Ok);
    }
    double worst = 1.0, hanging = 1.0;
    const double dt = parameters.step;
    for (double t = 0.0; t < 1.0; t += dt) {
      for (int g = 0; g < 2; ++g) {
        Vector6d twist = Vector6d::Zero();
        twist[2] = t < 0.4 ? 1.0 : 0.0;
        EXPECT_EQ(cloth.setGripperMotion(g, at(corner(g) + Eigen::Vector3d(0.0, 0.0, std::min(t, 0.4))), twist),
                  SimStatus::Ok);
      }
      EXPECT_EQ(cloth.step(), SimStatus::Ok);
      worst = std::max(worst, cloth.maxEdgeStretch());
      if (t > 0.7) hanging = std::max(hanging, cloth.maxEdgeStretch());
    }
    return std::make_tuple(worst, hanging, std::move(cloth));
  };
  const auto [limited, limited_hanging, cloth] = hang(0.05);
  const auto [free, free_hanging, unlimited] = hang(-1.0);
  EXPECT_LE(limited, 1.08) << "without the limit: " << free;
  EXPECT_LE(limited_hanging, 1.08) << "without the limit: " << free_hanging;
  EXPECT_GT(free, 1.3);
  EXPECT_GT(free_hanging, 1.2);
  // Held nodes: the two nearest the first corner (19, 0) and (19, 1), rest distance apart.
  const int nx = cloth.parameters().nodes_x;
  const Eigen::Matrix3Xd &x = cloth.vertices(), &rest = cloth.restVertices();
  EXPECT_EQ(cloth.graspedNodeCount(0), unlimited.graspedNodeCount(0));
  EXPECT_NEAR((x.col(nx - 1) - x.col(2 * nx - 1)).norm(), (rest.col(nx - 1) - rest.col(2 * nx - 1)).norm(), 1e-9);
}

TEST(SimCloth, BadArgumentsAreRejected) {
  Cloth cloth(patch(), table(), 1);
  EXPECT_EQ(cloth.setGripperMotion(1, at(Eigen::Vector3d::Zero()), Vector6d::Zero()), SimStatus::InvalidArgument);
  EXPECT_EQ(cloth.setGripperMotion(0, at(Eigen::Vector3d::Constant(NAN)), Vector6d::Zero()),
            SimStatus::InvalidArgument);
  EXPECT_EQ(cloth.grasp(0, -1.0), SimStatus::InvalidArgument);
  EXPECT_EQ(cloth.grasp(3, 0.1), SimStatus::InvalidArgument);
  EXPECT_EQ(cloth.release(-1), SimStatus::InvalidArgument);
  const auto message = [](const ClothParameters& p) {
    try {
      Cloth c(p, table(), 1);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  ClothParameters p = patch();
  p.nodes_x = 1;
  EXPECT_NE(message(p).find("nodes"), std::string::npos);
  p = patch();
  p.stretch_stiffness = 1.5;
  EXPECT_NE(message(p).find("stretch_stiffness"), std::string::npos);
  p = patch();
  p.step = 0.0;
  EXPECT_NE(message(p).find("step"), std::string::npos);
  p = patch();
  p.strain_limit = NAN;
  EXPECT_NE(message(p).find("strain_limit"), std::string::npos);
}

TEST(SimCloth, TheArmsGraspItAndFeelItsWeight) {
  bs::sim::SimConfig config = bs::sim::SimConfig::fromYamlFile(BIMANUAL_SKILLS_SOURCE_DIR "/config/sim.yaml");
  ASSERT_TRUE(config.has_cloth);
  bs::sim::BimanualSimulation sim(config);
  ASSERT_TRUE(sim.hasCloth());
  // Joint targets: tools pointing down over the two corners of the far edge, and 0.3 m higher.
  const auto solve = [&](int arm, const Eigen::Vector3d& world_position, const Eigen::VectorXd& seed) {
    Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
    target.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
    target.translation() = world_position;
    bs::kinematics::GlobalIkParameters parameters;
    parameters.timeout = 0.5;
    bs::kinematics::GlobalIkSolver solver(sim.armModel(arm), parameters);
    Eigen::VectorXd q(7);
    const auto result = solver.solve(sim.basePose(arm).inverse() * target, seed, q);
    EXPECT_EQ(result.status, bs::kinematics::IkStatus::Converged);
    return q;
  };
  const Eigen::VectorXd seed = (Eigen::VectorXd(7) << 0.0, 0.8, 0.0, 1.6, 0.0, 0.7, 0.0).finished();
  const double far = 0.75, half_width = 0.3, z = kTop + 0.02;
  std::vector<Eigen::VectorXd> low, high;
  for (int arm = 0; arm < 2; ++arm) {
    const double y = arm == 0 ? half_width : -half_width;  // left arm (y > 0) takes the left corner
    low.push_back(solve(arm, Eigen::Vector3d(far, y, z), seed));
    high.push_back(solve(arm, Eigen::Vector3d(far, y, z + 0.3), low.back()));
  }
  ASSERT_EQ(sim.reset({{low[0], Eigen::VectorXd::Zero(7)}, {low[1], Eigen::VectorXd::Zero(7)}}), SimStatus::Ok);
  for (int arm = 0; arm < 2; ++arm) {
    int attached = 0;
    ASSERT_EQ(sim.grasp(arm, &attached), SimStatus::Ok);
    EXPECT_GT(attached, 0) << "arm " << arm;
  }
  // Joint PD + gravity compensation from low to high in 1 s, then hold for 1 s.
  const Eigen::VectorXd kp = (Eigen::VectorXd(7) << 400, 400, 200, 150, 30, 30, 6).finished();
  const Eigen::VectorXd kd = (Eigen::VectorXd(7) << 40, 40, 15, 10, 1.5, 1.5, 0.2).finished();
  std::vector<bs::dynamics::DynamicsData> data;
  for (int arm = 0; arm < 2; ++arm) data.emplace_back(sim.armModel(arm));
  bs::sim::JointState state(7);
  Eigen::VectorXd gravity(7);
  Eigen::Vector3d mean_force = Eigen::Vector3d::Zero();
  int samples = 0;
  for (int k = 0; k < 2000; ++k) {
    const double s = std::min(1.0, k * 0.001);
    const double blend = s * s * (3.0 - 2.0 * s);
    for (int arm = 0; arm < 2; ++arm) {
      const auto a = static_cast<std::size_t>(arm);
      ASSERT_EQ(sim.readJointState(arm, state), bs::sim::RobotStatus::Ok);
      ASSERT_EQ(bs::dynamics::gravityTorques(sim.armModel(arm), data[a], state.position, gravity),
                bs::dynamics::DynamicsStatus::Success);
      const Eigen::VectorXd target = (1.0 - blend) * low[a] + blend * high[a];
      const Eigen::VectorXd tau = gravity + kp.cwiseProduct(target - state.position) - kd.cwiseProduct(state.velocity);
      ASSERT_EQ(sim.writeJointTorques(arm, tau), bs::sim::RobotStatus::Ok);
    }
    ASSERT_EQ(sim.step(), SimStatus::Ok) << "t = " << sim.time();
    if (k >= 1500) {
      mean_force += sim.clothWrench(0).head<3>() + sim.clothWrench(1).head<3>();
      ++samples;
    }
  }
  mean_force /= samples;
  // Raised 0.32 m above the table, the 0.5 m long patch hangs about 0.3 m: roughly half its weight or more.
  const double weight = config.cloth.mass * 9.81;
  EXPECT_LT(mean_force.z(), -0.4 * weight) << mean_force.transpose();
  EXPECT_GT(mean_force.z(), -1.05 * weight) << mean_force.transpose();
  // The grasped corners are at the tools.
  for (int arm = 0; arm < 2; ++arm) {
    const Eigen::Vector3d tool = sim.toolPose(arm).translation();
    double nearest = 1.0;
    for (int i = 0; i < sim.cloth().nodeCount(); ++i) {
      nearest = std::min(nearest, (sim.cloth().vertices().col(i) - tool).norm());
    }
    EXPECT_LT(nearest, config.grasp_radius + 0.01) << "arm " << arm;
    EXPECT_GT(tool.z(), kTop + 0.25) << "arm " << arm;
  }
  EXPECT_EQ(sim.release(0), SimStatus::Ok);
  EXPECT_EQ(sim.clothWrench(0), Vector6d::Zero());
}

// ---- obstacles (a mannequin's shapes): the cloth rests on them; a mark that does not collide changes nothing ----

TEST(ClothObstacles, CollidingShapesHoldTheClothUpExactlyAMarkDoesNot) {
  // A 0.1 m ball on the table under the patch's centre, the patch released 0.25 m above the table.
  bs::sim::Obstacle ball;
  ball.name = "ball";
  ball.shape = bs::sim::Obstacle::Shape::Sphere;
  ball.size = Eigen::Vector3d(0.1, 0.0, 0.0);
  ball.pose.translation() = Eigen::Vector3d(0.5, 0.0, kTop + 0.1);
  bs::sim::Obstacle mark = ball;
  mark.name = "mark";
  mark.collides = false;
  ClothParameters p = patch();
  p.pose.translation().z() = kTop + 0.25;
  const auto settle = [&](const std::vector<bs::sim::Obstacle>& obstacles) {
    Cloth cloth(p, table(), 0, Eigen::Vector3d(0.0, 0.0, -9.81), obstacles);
    for (int k = 0; k < 500; ++k) EXPECT_EQ(cloth.step(), SimStatus::Ok) << k;  // 2 s
    return Eigen::Matrix3Xd(cloth.vertices());
  };
  const Eigen::Matrix3Xd on_ball = settle({ball}), on_table = settle({}), with_mark = settle({mark});
  // The node nearest the patch's centre: on the ball's top (0.2 m above the table) by the cloth's margin, else on
  // the table. Bullet's sampled distance field alone let it sink 0.9-1.4 cm (the exact projection in cloth.cpp).
  Eigen::Index centre = 0;
  (on_table.topRows<2>().colwise() - Eigen::Vector2d(0.5, 0.0)).colwise().squaredNorm().minCoeff(&centre);
  EXPECT_NEAR(on_ball(2, centre), kTop + 0.2 + p.thickness, 0.002);
  EXPECT_NEAR(on_table(2, centre), kTop + p.thickness, 0.005);
  // No node inside the ball.
  const double inside = ((on_ball.colwise() - ball.pose.translation()).colwise().norm().array() - 0.1).minCoeff();
  EXPECT_GT(inside, 0.0);
  // A thin vertical cylinder (a neck) with a box on it (a head's stand-in): the cloth drapes over both, no node
  // inside either.
  const bs::sim::Obstacle neck = obstacle("neck", bs::sim::Obstacle::Shape::Cylinder, Eigen::Vector3d(0.045, 0.15, 0.0),
                                          Eigen::Vector3d(0.5, 0.0, kTop + 0.075));
  bs::sim::Obstacle block = obstacle("block", bs::sim::Obstacle::Shape::Box, Eigen::Vector3d(0.06, 0.06, 0.02),
                                     Eigen::Vector3d(0.5, 0.0, kTop + 0.16));
  block.pose.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Matrix3Xd draped = settle({neck, block});
  for (Eigen::Index k = 0; k < draped.cols(); ++k) {
    const Eigen::Vector3d x = draped.col(k) - neck.pose.translation();
    EXPECT_FALSE(x.head<2>().norm() < 0.045 && std::abs(x.z()) < 0.075) << "node " << k << " inside the neck";
    const Eigen::Vector3d b = block.pose.inverse() * Eigen::Vector3d(draped.col(k));
    EXPECT_FALSE((b.cwiseAbs().array() < 0.5 * block.size.array()).all()) << "node " << k << " inside the block";
  }
  EXPECT_NEAR(draped(2, centre), kTop + 0.17 + p.thickness, 0.002) << "the centre rests on the block";
  // A mark is seen, not felt: the cloth falls as without it, bit for bit.
  EXPECT_EQ(with_mark, on_table);
  // Obstacles are checked.
  bs::sim::Obstacle flat = ball;
  flat.size.setZero();
  EXPECT_THROW(Cloth(p, table(), 0, Eigen::Vector3d(0.0, 0.0, -9.81), {flat}), std::invalid_argument);
}

// A reset cloth falls on curved obstacles as a new one does, bit for bit, whatever it did before (its contact field
// of the obstacles filled elsewhere, its self-contacts): the learners' rollouts may run on a reset simulation.
TEST(ClothObstacles, AResetClothFallsAsANewOneDoes) {
  const bs::sim::Obstacle neck = obstacle("neck", bs::sim::Obstacle::Shape::Cylinder, Eigen::Vector3d(0.045, 0.15, 0.0),
                                          Eigen::Vector3d(0.5, 0.05, kTop + 0.075));
  const bs::sim::Obstacle ball = obstacle("head", bs::sim::Obstacle::Shape::Sphere, Eigen::Vector3d(0.07, 0.0, 0.0),
                                          Eigen::Vector3d(0.45, -0.05, kTop + 0.2));
  ClothParameters p = patch();
  p.pose.translation().z() = kTop + 0.35;
  const auto fall = [](Cloth& cloth, int steps) {
    for (int k = 0; k < steps; ++k) EXPECT_EQ(cloth.step(), SimStatus::Ok) << k;
    return Eigen::Matrix3Xd(cloth.vertices());
  };
  Cloth fresh(p, table(), 0, Eigen::Vector3d(0.0, 0.0, -9.81), {neck, ball});
  const Eigen::Matrix3Xd once = fall(fresh, 300);
  Cloth reused(p, table(), 0, Eigen::Vector3d(0.0, 0.0, -9.81), {neck, ball});
  fall(reused, 450);  // longer than the fall compared: onto the neck and the head
  reused.reset();
  EXPECT_EQ(fall(reused, 300), once);
  reused.reset();
  EXPECT_EQ(fall(reused, 300), once);
}
