// The simulated arms (Bullet btMultiBody driven by the true plant) against independent references: the project's
// forward dynamics (RNEA + Cholesky, equal to KDL), virtual work by finite differences of forward kinematics for
// external wrenches; plus joint limits, the table, friction holding the arm, determinism, reset and bad input.
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "test_support.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

namespace bs = bimanual_skills;
using bs::sim::ArmPlantParameters;
using bs::sim::ArmState;
using bs::sim::BimanualSimulation;
using bs::sim::JointState;
using bs::sim::RobotStatus;
using bs::sim::SimConfig;
using bs::sim::SimStatus;

namespace {

const std::string kBimanualUrdf = BIMANUAL_SKILLS_SOURCE_DIR "/urdf/bimanual_wam.urdf";
const std::string kPlantFile = BIMANUAL_SKILLS_SOURCE_DIR "/config/plant.yaml";

/// The left arm of the bimanual URDF alone, no table, an ideal plant (rigid body only).
SimConfig leftArm() {
  SimConfig config;
  config.urdf_path = kBimanualUrdf;
  config.arms = {{"left", "left_wam_base", "left_wam_tool", {}, "", {}}};
  config.has_table = false;
  config.plant.arms = {{"left", ArmPlantParameters::ideal()}};
  return config;
}

Eigen::VectorXd randomVector(int n, double scale, std::mt19937& rng) {
  std::uniform_real_distribution<double> uniform(-scale, scale);
  return Eigen::VectorXd::NullaryExpr(n, [&] { return uniform(rng); });
}

/// Torques uniform within half the URDF effort limits (the WAM's wrist has tiny inertias: larger ones spin it
/// beyond 100 rad/s in one step).
Eigen::VectorXd randomTorque(const bs::kinematics::ChainModel& model, std::mt19937& rng) {
  return randomVector(model.nq(), 0.5, rng).cwiseProduct(model.effortLimits());
}

/// q within the limits, at least `margin` inside them.
Eigen::VectorXd randomInside(const bs::kinematics::ChainModel& model, std::mt19937& rng, double margin = 0.1) {
  Eigen::VectorXd q(model.nq());
  for (int i = 0; i < model.nq(); ++i) {
    q[i] =
        std::uniform_real_distribution<double>(model.lowerLimits()[i] + margin, model.upperLimits()[i] - margin)(rng);
  }
  return q;
}

/// One step from (q, q̇) under τ; returns Bullet's q̈.
Eigen::VectorXd stepFrom(BimanualSimulation& sim, const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                         const Eigen::VectorXd& tau) {
  EXPECT_EQ(sim.reset({ArmState{q, qd}}), SimStatus::Ok);
  EXPECT_EQ(sim.writeJointTorques(0, tau), RobotStatus::Ok);
  EXPECT_EQ(sim.step(), SimStatus::Ok);
  return sim.lastAcceleration(0);
}

/// The WAM of urdf/wam.urdf mounted on a tilted, shifted plate under a `world` root.
std::string tiltedWamUrdf() {
  std::string text = bs::test_support::readFile(bs::test_support::kWamUrdf);
  const std::string robot = "<robot name=\"wam\">";
  text.replace(text.find(robot), robot.size(),
               robot + R"(<link name="world"/><joint name="mount" type="fixed"><parent link="world"/>
               <child link="wam_base"/><origin xyz="0.1 -0.2 0.3" rpy="0.3 -0.5 1.0"/></joint>)");
  const std::string path = (std::filesystem::temp_directory_path() / "bimanual_skills_tilted_wam.urdf").string();
  std::ofstream(path) << text;
  return path;
}

}  // namespace

TEST(SimArms, BulletStepMatchesForwardDynamics) {
  BimanualSimulation sim(leftArm());
  const bs::kinematics::ChainModel reference =
      bs::kinematics::ChainModel::fromUrdfFile(kBimanualUrdf, "left_wam_base", "left_wam_tool");
  bs::dynamics::DynamicsData data(reference);
  std::mt19937 rng(3);
  Eigen::VectorXd expected(7);
  for (int trial = 0; trial < 30; ++trial) {
    const Eigen::VectorXd q = randomInside(reference, rng);
    const Eigen::VectorXd qd = randomVector(7, 1.5, rng);
    const Eigen::VectorXd tau = randomTorque(reference, rng);
    const Eigen::VectorXd qdd = stepFrom(sim, q, qd, tau);
    ASSERT_EQ(bs::dynamics::forwardDynamics(reference, data, q, qd, tau, expected),
              bs::dynamics::DynamicsStatus::Success);
    EXPECT_LT((qdd - expected).norm(), 1e-8 * (1.0 + expected.norm())) << "trial " << trial;
    // Semi-implicit Euler: q⁺ = q + Δt q̇⁺.
    const ArmState& state = sim.trueState(0);
    EXPECT_LT((state.q - (q + sim.stepSize() * state.qd)).norm(), 1e-12);
  }
}

TEST(SimArms, RotorInertiaAndPayloadMatchForwardDynamics) {
  SimConfig config = leftArm();
  const bs::kinematics::ChainModel with_rotors = bs::test_support::wamWithRotors();
  config.plant.arms[0].second.rotor_inertia = with_rotors.rotorInertia();
  BimanualSimulation sim(config);
  const bs::kinematics::ChainModel reference =
      bs::kinematics::ChainModel::fromUrdfFile(kBimanualUrdf, "left_wam_base", "left_wam_tool")
          .withRotorInertia(with_rotors.rotorInertia());
  bs::dynamics::DynamicsData data(reference);
  std::mt19937 rng(4);
  Eigen::VectorXd expected(7);
  for (int trial = 0; trial < 20; ++trial) {
    bs::dynamics::Payload payload;
    if (trial % 2 == 1) payload = {0.8 + 0.1 * trial, Eigen::Vector3d(0.03, -0.02, 0.1)};
    ASSERT_EQ(sim.setPayload(0, payload), SimStatus::Ok);
    const Eigen::VectorXd q = randomInside(reference, rng);
    const Eigen::VectorXd qd = randomVector(7, 1.5, rng);
    const Eigen::VectorXd tau = randomTorque(reference, rng);
    const Eigen::VectorXd qdd = stepFrom(sim, q, qd, tau);
    ASSERT_EQ(bs::dynamics::forwardDynamics(reference, data, q, qd, tau, expected, payload),
              bs::dynamics::DynamicsStatus::Success);
    EXPECT_LT((qdd - expected).norm(), 1e-8 * (1.0 + expected.norm())) << "trial " << trial;
    // (M + J_m) q̈ + h = τ: the rotor inertias matter (the same step without them differs).
    bs::dynamics::DynamicsData bare_data(sim.armModel(0));
    Eigen::VectorXd without(7);
    ASSERT_EQ(bs::dynamics::forwardDynamics(sim.armModel(0), bare_data, q, qd, tau, without, payload),
              bs::dynamics::DynamicsStatus::Success);
    EXPECT_GT((without - expected).norm(), 0.01 * expected.norm());
  }
}

TEST(SimArms, TiltedBaseAndZeroGravity) {
  const std::string urdf = tiltedWamUrdf();
  for (const Eigen::Vector3d& gravity : {Eigen::Vector3d(0.0, 0.0, -9.81), Eigen::Vector3d(0.0, 0.0, 0.0)}) {
    SimConfig config;
    config.urdf_path = urdf;
    config.arms = {{"arm", "wam_base", "wam_tool", {}, "", {}}};
    config.has_table = false;
    config.gravity = gravity;
    config.plant.arms = {{"arm", ArmPlantParameters::ideal()}};
    BimanualSimulation sim(config);
    EXPECT_TRUE(sim.basePose(0).translation().isApprox(Eigen::Vector3d(0.1, -0.2, 0.3)));
    // Reference: the chain from its base, gravity rotated into the base frame.
    const bs::kinematics::ChainModel reference =
        bs::test_support::wam().withGravity(sim.basePose(0).linear().transpose() * gravity);
    bs::dynamics::DynamicsData data(reference);
    std::mt19937 rng(6);
    Eigen::VectorXd expected(7);
    for (int trial = 0; trial < 10; ++trial) {
      const Eigen::VectorXd q = randomInside(reference, rng);
      const Eigen::VectorXd qd = randomVector(7, 1.0, rng);
      const Eigen::VectorXd tau = randomTorque(reference, rng);
      const Eigen::VectorXd qdd = stepFrom(sim, q, qd, tau);
      ASSERT_EQ(bs::dynamics::forwardDynamics(reference, data, q, qd, tau, expected),
                bs::dynamics::DynamicsStatus::Success);
      EXPECT_LT((qdd - expected).norm(), 1e-8 * (1.0 + expected.norm())) << "trial " << trial;
    }
    // The tool pose agrees with the kinematics in the world frame.
    const Eigen::VectorXd q = randomInside(reference, rng);
    ASSERT_EQ(sim.reset({ArmState{q, Eigen::VectorXd::Zero(7)}}), SimStatus::Ok);
    EXPECT_TRUE(sim.toolPose(0).isApprox(sim.basePose(0) * bs::test_support::tipPose(reference, q), 1e-12));
  }
}

TEST(SimArms, ExternalWrenchActsThroughVirtualWork) {
  BimanualSimulation sim(leftArm());
  const bs::kinematics::ChainModel& model = sim.armModel(0);
  bs::dynamics::DynamicsData data(model);
  std::mt19937 rng(8);
  struct Case {
    std::string link;
    Eigen::Vector3d point;
  };
  for (const Case& c :
       {Case{"left_wam_tool", Eigen::Vector3d::Zero()}, Case{"left_wam_link4", Eigen::Vector3d(0.05, -0.02, 0.1)},
        Case{"left_wam_flange", Eigen::Vector3d(0.0, 0.03, 0.02)}}) {
    const bs::sim::LinkHandle link = sim.link(c.link);
    const Eigen::VectorXd q = randomInside(model, rng);
    const Eigen::VectorXd qd = randomVector(7, 1.0, rng);
    const Eigen::VectorXd tau = randomTorque(model, rng);
    const Eigen::Vector3d force(12.0, -7.0, 20.0), torque(0.8, 1.5, -0.6);

    // τ_i = F · ∂p/∂q_i + T · ω_i, by central differences of the link's world pose.
    bs::kinematics::ChainData fk(model);
    const auto pose = [&](const Eigen::VectorXd& qq) {
      EXPECT_EQ(bs::kinematics::forwardKinematics(model, fk, qq), bs::kinematics::KinematicsStatus::Success);
      return Eigen::Isometry3d(sim.basePose(0) * fk.frame_poses[static_cast<std::size_t>(link.frame)] * link.offset);
    };
    Eigen::VectorXd virtual_work(7);
    const double h = 1e-6;
    const Eigen::Isometry3d at = pose(q);
    for (int i = 0; i < 7; ++i) {
      Eigen::VectorXd qp = q, qm = q;
      qp[i] += h;
      qm[i] -= h;
      const Eigen::Isometry3d plus = pose(qp), minus = pose(qm);
      const Eigen::Vector3d dp = ((plus * c.point) - (minus * c.point)) / (2 * h);
      const Eigen::Matrix3d dR = (plus.linear() - minus.linear()) / (2 * h) * at.linear().transpose();
      const Eigen::Vector3d omega(dR(2, 1), dR(0, 2), dR(1, 0));
      virtual_work[i] = force.dot(dp) + torque.dot(omega);
    }

    ASSERT_EQ(sim.reset({ArmState{q, qd}}), SimStatus::Ok);
    ASSERT_EQ(sim.setExternalWrench(link, force, torque, c.point), SimStatus::Ok);
    ASSERT_EQ(sim.writeJointTorques(0, tau), RobotStatus::Ok);
    ASSERT_EQ(sim.step(), SimStatus::Ok);
    Eigen::VectorXd expected(7);
    ASSERT_EQ(bs::dynamics::forwardDynamics(model, data, q, qd, tau + virtual_work, expected),
              bs::dynamics::DynamicsStatus::Success);
    EXPECT_LT((sim.lastAcceleration(0) - expected).norm(), 1e-6 * (1.0 + expected.norm())) << c.link;
  }
  EXPECT_THROW(sim.link("right_wam_link3"), std::invalid_argument);  // not simulated here
  EXPECT_THROW(sim.link("left_wam_base"), std::invalid_argument);    // does not move
  EXPECT_THROW(sim.link("no_such_link"), std::invalid_argument);
}

TEST(SimArms, JointLimitsHold) {
  BimanualSimulation sim(leftArm());
  const bs::kinematics::ChainModel& model = sim.armModel(0);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(7);
  q[3] = 2.9;  // joint 4, limit 3.1
  ASSERT_EQ(sim.reset({ArmState{q, Eigen::VectorXd::Zero(7)}}), SimStatus::Ok);
  bs::dynamics::DynamicsData data(model);
  Eigen::VectorXd gravity(7);
  double highest = -10.0;
  for (int k = 0; k < 1500; ++k) {
    ASSERT_EQ(bs::dynamics::gravityTorques(model, data, sim.trueState(0).q, gravity),
              bs::dynamics::DynamicsStatus::Success);
    Eigen::VectorXd tau = gravity;
    tau[3] += 15.0;  // pushes joint 4 into its upper limit
    ASSERT_EQ(sim.writeJointTorques(0, tau), RobotStatus::Ok);
    ASSERT_EQ(sim.step(), SimStatus::Ok);
    highest = std::max(highest, sim.trueState(0).q[3]);
  }
  EXPECT_LT(highest, model.upperLimits()[3] + 0.01);
  EXPECT_NEAR(sim.trueState(0).q[3], model.upperLimits()[3], 2e-3);
  EXPECT_LT(std::abs(sim.trueState(0).qd[3]), 0.01);
}

TEST(SimArms, TrueFrictionHoldsTheArmBelowBreakaway) {
  SimConfig config = leftArm();
  config.plant = bs::sim::PlantModel::fromYamlFile(kPlantFile);
  BimanualSimulation sim(config);
  const bs::kinematics::ChainModel& model = sim.armModel(0);
  bs::dynamics::DynamicsData data(model);
  const Eigen::VectorXd q0 = (Eigen::VectorXd(7) << 0.3, 0.6, -0.2, 1.4, 0.1, 0.5, 0.2).finished();
  Eigen::VectorXd gravity(7);
  ASSERT_EQ(bs::dynamics::gravityTorques(model, data, q0, gravity), bs::dynamics::DynamicsStatus::Success);
  for (const double push : {0.6, 1.8}) {  // joint 1: breakaway ρ F_s ≈ 2.3 ± 12 %
    ASSERT_EQ(sim.reset({ArmState{q0, Eigen::VectorXd::Zero(7)}}), SimStatus::Ok);
    Eigen::VectorXd tau = gravity;
    tau[0] += push;
    ASSERT_EQ(sim.writeJointTorques(0, tau), RobotStatus::Ok);
    for (int k = 0; k < 500; ++k) ASSERT_EQ(sim.step(), SimStatus::Ok);
    EXPECT_LT((sim.trueState(0).q - q0).norm(), 1e-9) << "push " << push;
    EXPECT_LT(sim.trueState(0).qd.norm(), 1e-9) << "push " << push;
  }
  ASSERT_EQ(sim.reset({ArmState{q0, Eigen::VectorXd::Zero(7)}}), SimStatus::Ok);
  Eigen::VectorXd tau = gravity;
  tau[0] += 4.0;  // beyond breakaway: joint 1 turns
  ASSERT_EQ(sim.writeJointTorques(0, tau), RobotStatus::Ok);
  for (int k = 0; k < 500; ++k) ASSERT_EQ(sim.step(), SimStatus::Ok);
  EXPECT_GT(sim.trueState(0).q[0] - q0[0], 0.05);
}

TEST(SimArms, TableAndObstaclesStopTheArm) {
  // The lowest the tool gets when the shoulder pushes the arm down: onto the table (top at z = 0.15), onto an
  // obstacle box of the table's size, through a box that does not collide (a mark), or with nothing there.
  enum class Under { Table, Obstacle, Mark, Nothing };
  const auto lowest = [](Under under) {
    SimConfig config = leftArm();
    config.has_table = under == Under::Table;
    config.table.pose.translation() = Eigen::Vector3d(0.55, 0.4, 0.0);
    config.table.size = Eigen::Vector3d(0.7, 1.2, 0.3);
    if (under == Under::Obstacle || under == Under::Mark) {
      bs::sim::Obstacle box;
      box.name = "box";
      box.pose = config.table.pose;
      box.size = config.table.size;
      box.collides = under == Under::Obstacle;
      config.obstacles.push_back(box);
    }
    BimanualSimulation sim(config);
    const bs::kinematics::ChainModel& model = sim.armModel(0);
    bs::dynamics::DynamicsData data(model);
    const Eigen::VectorXd q0 = (Eigen::VectorXd(7) << 0.0, 0.9, 0.0, 1.2, 0.0, 0.6, 0.0).finished();
    EXPECT_EQ(sim.reset({ArmState{q0, Eigen::VectorXd::Zero(7)}}), SimStatus::Ok);
    EXPECT_GT(sim.toolPose(0).translation().z(), 0.2);
    Eigen::VectorXd gravity(7);
    double low = 10.0;
    for (int k = 0; k < 1500; ++k) {
      EXPECT_EQ(bs::dynamics::gravityTorques(model, data, sim.trueState(0).q, gravity),
                bs::dynamics::DynamicsStatus::Success);
      Eigen::VectorXd tau = gravity;
      tau[1] += 15.0;  // shoulder forward and down, into the table
      EXPECT_EQ(sim.writeJointTorques(0, tau), RobotStatus::Ok);
      const SimStatus status = sim.step();
      if (status != SimStatus::Ok) {
        ADD_FAILURE() << toString(status);
        break;
      }
      low = std::min(low, sim.toolPose(0).translation().z());
    }
    return low;
  };
  EXPECT_GT(lowest(Under::Table), 0.15 - 0.02);
  EXPECT_NEAR(lowest(Under::Obstacle), lowest(Under::Table), 1e-9);
  EXPECT_LT(lowest(Under::Mark), 0.0);
  EXPECT_LT(lowest(Under::Nothing), 0.0);
}

TEST(SimArms, SameSeedAndCommandsGiveBitIdenticalTrajectoriesAlsoAfterReset) {
  SimConfig config = leftArm();
  config.arms.push_back({"right", "right_wam_base", "right_wam_tool", {}, "", {}});
  config.plant = bs::sim::PlantModel::fromYamlFile(kPlantFile);
  config.has_table = true;
  config.table.pose.translation() = Eigen::Vector3d(0.55, 0.0, 0.0);
  const auto run = [&](BimanualSimulation& sim, std::uint32_t command_seed, int steps) {
    std::mt19937 commands(command_seed);
    std::vector<Eigen::VectorXd> trajectory;
    JointState state(7);
    for (int k = 0; k < steps; ++k) {
      for (int a = 0; a < 2; ++a) {
        EXPECT_EQ(sim.writeJointTorques(a, 0.3 * randomTorque(sim.armModel(a), commands)), RobotStatus::Ok);
      }
      EXPECT_EQ(sim.step(), SimStatus::Ok);
      for (int a = 0; a < 2; ++a) {
        EXPECT_EQ(sim.readJointState(a, state), RobotStatus::Ok);
        Eigen::VectorXd row(28);
        row << sim.trueState(a).q, sim.trueState(a).qd, state.position, state.velocity;
        trajectory.push_back(row);
      }
    }
    return trajectory;
  };
  const Eigen::VectorXd q0 = (Eigen::VectorXd(7) << 0.1, 0.5, 0.0, 1.5, 0.0, 0.4, 0.0).finished();
  const Eigen::VectorXd mirrored = q0.cwiseProduct((Eigen::VectorXd(7) << -1, 1, -1, 1, -1, 1, -1).finished());
  const std::vector<ArmState> start = {ArmState{q0, Eigen::VectorXd::Zero(7)},
                                       ArmState{mirrored, Eigen::VectorXd::Zero(7)}};
  BimanualSimulation a(config, std::mt19937(21)), b(config, std::mt19937(21)), c(config, std::mt19937(22));
  for (BimanualSimulation* sim : {&a, &b, &c}) ASSERT_EQ(sim->reset(start), SimStatus::Ok);
  const auto ta = run(a, 5, 400), tb = run(b, 5, 400), tc = run(c, 5, 400);
  ASSERT_EQ(ta.size(), tb.size());
  for (std::size_t k = 0; k < ta.size(); ++k) ASSERT_EQ(ta[k], tb[k]) << "row " << k;
  bool noise_differs = false;
  for (std::size_t k = 0; k < ta.size(); ++k) noise_differs = noise_differs || ta[k].tail<7>() != tc[k].tail<7>();
  EXPECT_TRUE(noise_differs) << "another seed gives other sensor noise";
  // Reset after running: the future is that of a new simulation in that state.
  (void)run(a, 99, 250);
  ASSERT_EQ(a.reset(start), SimStatus::Ok);
  a.setRandomGenerator(std::mt19937(21));
  BimanualSimulation fresh(config, std::mt19937(21));
  ASSERT_EQ(fresh.reset(start), SimStatus::Ok);
  fresh.setRandomGenerator(std::mt19937(21));
  const auto ra = run(a, 5, 400), rf = run(fresh, 5, 400);
  for (std::size_t k = 0; k < ra.size(); ++k) ASSERT_EQ(ra[k], rf[k]) << "row " << k;
}

TEST(SimArms, CommandsAndReadsAreValidated) {
  SimConfig config = leftArm();
  config.plant.arms[0].second.saturate_torque = true;
  BimanualSimulation sim(config);
  const Eigen::VectorXd q0 = (Eigen::VectorXd(7) << 0.2, 0.4, 0.1, 1.2, 0.3, 0.2, 0.1).finished();
  const Eigen::VectorXd tau = (Eigen::VectorXd(7) << 1, 2, 1, 0.5, 0.1, 0.1, 0.01).finished();
  // Reference: the good command alone.
  ASSERT_EQ(sim.reset({ArmState{q0, Eigen::VectorXd::Zero(7)}}), SimStatus::Ok);
  ASSERT_EQ(sim.writeJointTorques(0, tau), RobotStatus::Ok);
  for (int k = 0; k < 20; ++k) ASSERT_EQ(sim.step(), SimStatus::Ok);
  const Eigen::VectorXd reference = sim.trueState(0).q;
  // Bad commands in between are rejected and the previous one holds.
  ASSERT_EQ(sim.reset({ArmState{q0, Eigen::VectorXd::Zero(7)}}), SimStatus::Ok);
  ASSERT_EQ(sim.writeJointTorques(0, tau), RobotStatus::Ok);
  Eigen::VectorXd nan = tau;
  nan[2] = std::nan("");
  Eigen::VectorXd inf = tau;
  inf[6] = INFINITY;
  for (int k = 0; k < 20; ++k) {
    EXPECT_EQ(sim.writeJointTorques(0, nan), RobotStatus::InvalidCommand);
    EXPECT_EQ(sim.writeJointTorques(0, inf), RobotStatus::InvalidCommand);
    EXPECT_EQ(sim.writeJointTorques(0, Eigen::VectorXd::Zero(6)), RobotStatus::InvalidCommand);
    ASSERT_EQ(sim.step(), SimStatus::Ok);
  }
  EXPECT_EQ(sim.trueState(0).q, reference);
  EXPECT_EQ(sim.writeJointTorques(1, tau), RobotStatus::UnknownArm);
  JointState wrong(6), right(7);
  EXPECT_EQ(sim.readJointState(0, wrong), RobotStatus::WrongSize);
  EXPECT_EQ(sim.readJointState(-1, right), RobotStatus::UnknownArm);
  // Saturation at the URDF effort limits; the state reports the applied torque and the time.
  ASSERT_EQ(sim.writeJointTorques(0, Eigen::VectorXd::Constant(7, 1000.0)), RobotStatus::Ok);
  ASSERT_EQ(sim.readJointState(0, right), RobotStatus::Ok);
  EXPECT_EQ(right.effort, sim.armModel(0).effortLimits());
  EXPECT_DOUBLE_EQ(right.time, 20 * sim.stepSize());
  EXPECT_EQ(sim.setPayload(0, {-1.0, Eigen::Vector3d::Zero()}), SimStatus::InvalidArgument);
  EXPECT_EQ(sim.setPayload(3, {}), SimStatus::UnknownArm);
  EXPECT_EQ(sim.setExternalWrench(bs::sim::LinkHandle{}, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()),
            SimStatus::UnknownLink);
  EXPECT_EQ(sim.setExternalWrench(sim.link("left_wam_tool"), Eigen::Vector3d::Constant(NAN), Eigen::Vector3d::Zero()),
            SimStatus::InvalidArgument);
  EXPECT_EQ(sim.grasp(0), SimStatus::NoCloth);
  // Reset outside the limits or with wrong sizes is refused.
  Eigen::VectorXd outside = q0;
  outside[3] = 3.5;
  EXPECT_EQ(sim.reset({ArmState{outside, Eigen::VectorXd::Zero(7)}}), SimStatus::InvalidArgument);
  EXPECT_EQ(sim.reset({ArmState{q0, Eigen::VectorXd::Zero(6)}}), SimStatus::InvalidArgument);
  EXPECT_EQ(sim.reset({}), SimStatus::InvalidArgument);
}

TEST(SimArms, DivergenceIsReportedAndResetRecovers) {
  BimanualSimulation sim(leftArm());
  const Eigen::VectorXd q0 = (Eigen::VectorXd(7) << 0.2, 0.4, 0.1, 1.2, 0.3, 0.2, 0.1).finished();
  ASSERT_EQ(sim.reset({ArmState{q0, Eigen::VectorXd::Zero(7)}}), SimStatus::Ok);
  ASSERT_EQ(sim.setExternalWrench(sim.link("left_wam_tool"), Eigen::Vector3d(0.0, 1e9, 0.0), Eigen::Vector3d::Zero()),
            SimStatus::Ok);
  EXPECT_EQ(sim.step(), SimStatus::ArmDiverged);
  EXPECT_EQ(sim.step(), SimStatus::ArmDiverged);
  EXPECT_TRUE(sim.trueState(0).q.allFinite());
  JointState state(7);
  EXPECT_EQ(sim.readJointState(0, state), RobotStatus::Fault);
  ASSERT_EQ(sim.reset({ArmState{q0, Eigen::VectorXd::Zero(7)}}), SimStatus::Ok);
  EXPECT_EQ(sim.step(), SimStatus::Ok);
  EXPECT_EQ(sim.readJointState(0, state), RobotStatus::Ok);
}

TEST(SimArms, ConstructionErrorsNameTheProblem) {
  const auto message = [](const SimConfig& config) {
    try {
      BimanualSimulation sim(config);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  SimConfig unknown = leftArm();
  unknown.arms[0].tip_link = "left_wam_hand";
  EXPECT_NE(message(unknown).find("left_wam_hand"), std::string::npos) << message(unknown);
  SimConfig moving = leftArm();
  moving.arms[0].base_link = "left_wam_link2";
  EXPECT_NE(message(moving).find("not fixed to the world"), std::string::npos) << message(moving);
  SimConfig no_plant = leftArm();
  no_plant.plant.arms[0].first = "other";
  EXPECT_NE(message(no_plant).find("no arm 'left'"), std::string::npos) << message(no_plant);
  SimConfig no_file = leftArm();
  no_file.urdf_path = "/nonexistent.urdf";
  EXPECT_NE(message(no_file).find("/nonexistent.urdf"), std::string::npos) << message(no_file);
  SimConfig bad_rotor = leftArm();
  bad_rotor.plant.arms[0].second.rotor_inertia = Eigen::VectorXd::Ones(6);
  EXPECT_NE(message(bad_rotor).find("rotor_inertia"), std::string::npos) << message(bad_rotor);
  SimConfig bad_step = leftArm();
  bad_step.step = -1.0;
  EXPECT_NE(message(bad_step).find("step"), std::string::npos) << message(bad_step);
}

TEST(SimArms, RobotInterfaceAndFreeMotionStepDoNotAllocate) {
  SimConfig config = leftArm();
  config.plant = bs::sim::PlantModel::fromYamlFile(kPlantFile);
  BimanualSimulation sim(config);
  bs::sim::RobotInterface& robot = sim;
  const Eigen::VectorXd q0 = (Eigen::VectorXd(7) << 0.2, 0.4, 0.1, 1.2, 0.3, 0.2, 0.1).finished();
  ASSERT_EQ(sim.reset({ArmState{q0, Eigen::VectorXd::Zero(7)}}), SimStatus::Ok);
  const Eigen::VectorXd tau = (Eigen::VectorXd(7) << 3, 20, 1, 8, 0.5, 0.5, 0.05).finished();
  JointState state(7);
  for (int k = 0; k < 50; ++k) {  // warm-up: Bullet sizes its scratch arrays
    ASSERT_EQ(robot.writeJointTorques(0, tau), RobotStatus::Ok);
    ASSERT_EQ(sim.step(), SimStatus::Ok);
  }
  ASSERT_EQ(sim.setExternalWrench(sim.link("left_wam_tool"), Eigen::Vector3d(1, 2, 3), Eigen::Vector3d::Zero()),
            SimStatus::Ok);
  RobotStatus read = RobotStatus::Fault, write = RobotStatus::Fault;
  SimStatus stepped = SimStatus::InvalidArgument;
  {
    bs::testing::NoAllocGuard guard;
    for (int k = 0; k < 20; ++k) {
      read = robot.readJointState(0, state);
      write = robot.writeJointTorques(0, tau);
      stepped = sim.step();
    }
  }
  EXPECT_EQ(read, RobotStatus::Ok);
  EXPECT_EQ(write, RobotStatus::Ok);
  EXPECT_EQ(stepped, SimStatus::Ok);
}
