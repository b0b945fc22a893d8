// Rigid-body dynamics against independent references: KDL's RNE and ChainDynParam on the same URDF, the identity
// M q̈ + h = RNEA, energy conservation of a free motion integrated with forward dynamics, an equivalent URDF for the
// payload, and KDL joint inertia for the rotor terms. Real-time calls are checked for heap allocations.
#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "test_support.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>
#include <kdl/chaindynparam.hpp>
#include <kdl/chainidsolver_recursive_newton_euler.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace bd = bimanual_skills::dynamics;
namespace bk = bimanual_skills::kinematics;
using bimanual_skills::testing::NoAllocGuard;

using bimanual_skills::test_support::kWamUrdf;
using bimanual_skills::test_support::readFile;

namespace {

constexpr unsigned kSeed = 424242;

// Skewed axes, a prismatic joint, inertial frames rotated off the link frames, and a heavy link fixed to a moving
// one (merged into its body by the loader; a separate segment for KDL).
const char* const kMixedUrdf = R"(<?xml version="1.0"?>
<robot name="mixed">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0.05 0.1 0.02" rpy="0.3 0.1 -0.2"/><mass value="2.0"/>
    <inertia ixx="0.03" ixy="0.001" ixz="-0.002" iyy="0.02" iyz="0.0015" izz="0.025"/></inertial></link>
  <link name="l1_block"><inertial><origin xyz="0.1 0 0.05" rpy="0 0 0.4"/><mass value="1.5"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.012" iyz="0" izz="0.008"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0 0.05 0.2" rpy="0 0 0"/><mass value="1.2"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.004"/></inertial></link>
  <link name="l3"><inertial><origin xyz="0.02 -0.01 0.1" rpy="0.5 0 0"/><mass value="0.8"/>
    <inertia ixx="0.004" ixy="0.0002" ixz="0" iyy="0.005" iyz="0" izz="0.003"/></inertial></link>
  <link name="l4"><inertial><origin xyz="0 0 0.05" rpy="0 0.2 0"/><mass value="0.4"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.0012" iyz="0" izz="0.0008"/></inertial></link>
  <link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.3" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="100" velocity="2"/></joint>
  <joint name="block" type="fixed"><parent link="l1"/><child link="l1_block"/><origin xyz="0 0.2 0.1" rpy="0.3 0 0"/></joint>
  <joint name="j2" type="revolute"><parent link="l1_block"/><child link="l2"/>
    <origin xyz="0.1 0 0.05" rpy="0 0.4 0"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="100" velocity="2"/></joint>
  <joint name="j3" type="prismatic"><parent link="l2"/><child link="l3"/>
    <origin xyz="0 0 0.4" rpy="0 0 0"/><axis xyz="0.6 0 0.8"/><limit lower="-0.2" upper="0.3" effort="100" velocity="1"/></joint>
  <joint name="j4" type="revolute"><parent link="l3"/><child link="l4"/>
    <origin xyz="0 0.05 0.2" rpy="0.2 0 0.3"/><axis xyz="0.2 -0.5 0.4"/><limit lower="-2" upper="2" effort="100" velocity="2"/></joint>
  <joint name="tool_joint" type="fixed"><parent link="l4"/><child link="tool"/><origin xyz="0 0 0.1" rpy="0 0 0"/></joint>
</robot>)";

KDL::Chain kdlChain(const std::string& xml, const std::string& base, const std::string& tip) {
  KDL::Tree tree;
  KDL::Chain chain;
  if (!kdl_parser::treeFromString(xml, tree) || !tree.getChain(base, tip, chain)) throw std::runtime_error("KDL");
  return chain;
}

struct State {
  Eigen::VectorXd q, qd, qdd;
};

State randomState(const bk::ChainModel& model, std::mt19937& rng) {
  State s{Eigen::VectorXd(model.nq()), Eigen::VectorXd(model.nq()), Eigen::VectorXd(model.nq())};
  std::uniform_real_distribution<double> rate(-2.0, 2.0);
  for (int i = 0; i < model.nq(); ++i) {
    s.q[i] = std::uniform_real_distribution<double>(model.lowerLimits()[i], model.upperLimits()[i])(rng);
    s.qd[i] = rate(rng);
    s.qdd[i] = rate(rng);
  }
  return s;
}

void expectEqualToKdl(const std::string& xml, const std::string& base, const std::string& tip) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfString(xml, base, tip);
  bd::DynamicsData data(model);
  const KDL::Chain chain = kdlChain(xml, base, tip);
  const unsigned n = chain.getNrOfJoints();
  ASSERT_EQ(static_cast<int>(n), model.nq());
  const KDL::Vector gravity(0.0, 0.0, -9.81);
  KDL::ChainIdSolver_RNE rne(chain, gravity);
  KDL::ChainDynParam dynparam(chain, gravity);
  KDL::JntArray q(n), qd(n), qdd(n), tau(n), coriolis(n), gravity_torques(n);
  KDL::JntSpaceInertiaMatrix M(n);
  KDL::Wrenches no_wrenches(chain.getNrOfSegments(), KDL::Wrench::Zero());
  Eigen::VectorXd ours(n);
  std::mt19937 rng(kSeed);
  double worst_tau = 0.0, worst_m = 0.0, worst_c = 0.0, worst_g = 0.0;
  for (int sample = 0; sample < 1000; ++sample) {
    const State s = randomState(model, rng);
    q.data = s.q;
    qd.data = s.qd;
    qdd.data = s.qdd;
    ASSERT_GE(rne.CartToJnt(q, qd, qdd, no_wrenches, tau), 0);
    ASSERT_EQ(bd::inverseDynamics(model, data, s.q, s.qd, s.qdd, ours), bd::DynamicsStatus::Success);
    worst_tau = std::max(worst_tau, (ours - tau.data).cwiseAbs().maxCoeff());
    ASSERT_GE(dynparam.JntToMass(q, M), 0);
    ASSERT_EQ(bd::massMatrix(model, data, s.q), bd::DynamicsStatus::Success);
    worst_m = std::max(worst_m, (data.mass_matrix - M.data).cwiseAbs().maxCoeff());
    ASSERT_GE(dynparam.JntToCoriolis(q, qd, coriolis), 0);
    ASSERT_EQ(bd::coriolisTorques(model, data, s.q, s.qd, ours), bd::DynamicsStatus::Success);
    worst_c = std::max(worst_c, (ours - coriolis.data).cwiseAbs().maxCoeff());
    ASSERT_GE(dynparam.JntToGravity(q, gravity_torques), 0);
    ASSERT_EQ(bd::gravityTorques(model, data, s.q, ours), bd::DynamicsStatus::Success);
    worst_g = std::max(worst_g, (ours - gravity_torques.data).cwiseAbs().maxCoeff());
  }
  EXPECT_LE(worst_tau, 1e-9) << base << " -> " << tip;
  EXPECT_LE(worst_m, 1e-9);
  EXPECT_LE(worst_c, 1e-9);
  EXPECT_LE(worst_g, 1e-9);
}

}  // namespace

TEST(RigidBodyDynamics, WamMatchesKdlOn1000RandomStates) {
  expectEqualToKdl(readFile(kWamUrdf), "wam_base", "wam_tool");
}

TEST(RigidBodyDynamics, MixedChainMatchesKdl) {
  expectEqualToKdl(kMixedUrdf, "base", "tool");
}

TEST(RigidBodyDynamics, MassMatrixIsSymmetricPositiveDefiniteAndConsistentWithRnea) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  bd::DynamicsData data(model);
  std::mt19937 rng(kSeed + 1);
  Eigen::VectorXd tau(7), c(7), g(7);
  for (int sample = 0; sample < 200; ++sample) {
    const State s = randomState(model, rng);
    ASSERT_EQ(bd::massMatrix(model, data, s.q), bd::DynamicsStatus::Success);
    const Eigen::MatrixXd M = data.mass_matrix;
    EXPECT_LE((M - M.transpose()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(M).eigenvalues().minCoeff(), 0.0);
    ASSERT_EQ(bd::inverseDynamics(model, data, s.q, s.qd, s.qdd, tau), bd::DynamicsStatus::Success);
    ASSERT_EQ(bd::coriolisTorques(model, data, s.q, s.qd, c), bd::DynamicsStatus::Success);
    ASSERT_EQ(bd::gravityTorques(model, data, s.q, g), bd::DynamicsStatus::Success);
    EXPECT_LE((M * s.qdd + c + g - tau).cwiseAbs().maxCoeff(), 1e-9);
    // Forward dynamics inverts inverse dynamics.
    Eigen::VectorXd qdd(7);
    ASSERT_EQ(bd::forwardDynamics(model, data, s.q, s.qd, tau, qdd), bd::DynamicsStatus::Success);
    EXPECT_LE((qdd - s.qdd).cwiseAbs().maxCoeff(), 1e-8);
  }
}

TEST(RigidBodyDynamics, CompositeRigidBodyEqualsTheRneaColumns) {
  // massMatrix() is the CRBA; the reference is column j = RNEA(q, 0, e_j) without gravity, on the WAM with rotors and
  // a payload, the 14-joint chain and the chain with prismatic and skewed joints.
  const std::vector<bk::ChainModel> models = {bimanual_skills::test_support::wamWithRotors(),
                                              bimanual_skills::test_support::twoWamsInSeries(),
                                              bk::ChainModel::fromUrdfString(kMixedUrdf, "base", "tool")};
  const bd::Payload payload{1.7, Eigen::Vector3d(0.03, -0.02, 0.09)};
  std::mt19937 rng(kSeed + 5);
  for (const bk::ChainModel& model : models) {
    const int n = model.nq();
    const bk::ChainModel no_gravity = model.withGravity(Eigen::Vector3d::Zero());
    bd::DynamicsData data(model), reference(no_gravity);
    Eigen::MatrixXd M(n, n);
    Eigen::VectorXd unit(n), column(n);
    double worst = 0.0;
    for (int sample = 0; sample < 100; ++sample) {
      const State s = randomState(model, rng);
      for (const bd::Payload& load : {bd::Payload{}, payload}) {
        for (int j = 0; j < n; ++j) {
          unit.setZero();
          unit[j] = 1.0;
          ASSERT_EQ(bd::inverseDynamics(no_gravity, reference, s.q, Eigen::VectorXd::Zero(n), unit, column, load),
                    bd::DynamicsStatus::Success);
          M.col(j) = column;
        }
        ASSERT_EQ(bd::massMatrix(model, data, s.q, load), bd::DynamicsStatus::Success);
        worst = std::max(worst, (data.mass_matrix - M).cwiseAbs().maxCoeff());
      }
    }
    EXPECT_LE(worst, 1e-12 * std::max(1.0, M.cwiseAbs().maxCoeff())) << n << " joints";
  }
}

TEST(RigidBodyDynamics, FreeMotionConservesEnergy) {
  // τ = 0 under gravity: kinetic + potential energy must stay constant along an RK4 integration (dt = 0.1 ms, 1 s).
  const bk::ChainModel model = bk::ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  bd::DynamicsData data(model);
  bk::ChainData kinematics(model);
  const auto energy = [&](const Eigen::VectorXd& q, const Eigen::VectorXd& qd) {
    EXPECT_EQ(bd::massMatrix(model, data, q), bd::DynamicsStatus::Success);
    EXPECT_EQ(bk::forwardKinematics(model, kinematics, q), bk::KinematicsStatus::Success);
    double potential = 0.0;
    for (int i = 0; i < 7; ++i) {
      const bk::BodyInertia& body = model.joints()[static_cast<std::size_t>(i)].body;
      potential -= body.mass * model.gravity().dot(kinematics.frame_poses[static_cast<std::size_t>(i)] * body.com);
    }
    return 0.5 * qd.dot(data.mass_matrix * qd) + potential;
  };
  Eigen::VectorXd q = (Eigen::VectorXd(7) << 0.3, 0.8, -0.4, 1.6, 0.5, -0.6, 0.2).finished();
  Eigen::VectorXd qd = (Eigen::VectorXd(7) << 0.5, -0.3, 0.8, 0.2, -1.0, 0.6, 1.2).finished();
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(7);
  const auto accel = [&](const Eigen::VectorXd& qq, const Eigen::VectorXd& vv) {
    Eigen::VectorXd a(7);
    EXPECT_EQ(bd::forwardDynamics(model, data, qq, vv, zero, a), bd::DynamicsStatus::Success);
    return a;
  };
  const double e0 = energy(q, qd);
  const double dt = 1e-4;
  double worst = 0.0;
  for (int k = 0; k < 10000; ++k) {
    const Eigen::VectorXd k1q = qd, k1v = accel(q, qd);
    const Eigen::VectorXd k2q = qd + 0.5 * dt * k1v, k2v = accel(q + 0.5 * dt * k1q, k2q);
    const Eigen::VectorXd k3q = qd + 0.5 * dt * k2v, k3v = accel(q + 0.5 * dt * k2q, k3q);
    const Eigen::VectorXd k4q = qd + dt * k3v, k4v = accel(q + dt * k3q, k4q);
    q += dt / 6.0 * (k1q + 2 * k2q + 2 * k3q + k4q);
    qd += dt / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v);
    if (k % 1000 == 999) worst = std::max(worst, std::abs(energy(q, qd) - e0));
  }
  EXPECT_GT(qd.norm(), 0.5);  // it really moved
  EXPECT_LE(worst, 1e-8 * std::max(1.0, std::abs(e0)));
}

TEST(RigidBodyDynamics, RotorInertiaMatchesKdlJointInertia) {
  const std::string xml = readFile(kWamUrdf);
  const Eigen::VectorXd rotor = (Eigen::VectorXd(7) << 0.164, 0.148, 0.053, 0.030, 0.0028, 0.0028, 0.0003).finished();
  const bk::ChainModel model = bk::ChainModel::fromUrdfString(xml, "wam_base", "wam_tool").withRotorInertia(rotor);
  bd::DynamicsData data(model);
  const KDL::Chain plain = kdlChain(xml, "wam_base", "wam_tool");
  KDL::Chain chain;
  int j = 0;
  for (const KDL::Segment& segment : plain.segments) {
    const KDL::Joint& joint = segment.getJoint();
    if (joint.getType() == KDL::Joint::None) {
      chain.addSegment(segment);
      continue;
    }
    const KDL::Joint with_rotor(joint.getName(), joint.JointOrigin(), joint.JointAxis(), joint.getType(), 1.0, 0.0,
                                rotor[j++]);
    chain.addSegment(KDL::Segment(segment.getName(), with_rotor, segment.getFrameToTip(), segment.getInertia()));
  }
  KDL::ChainIdSolver_RNE rne(chain, KDL::Vector(0, 0, -9.81));
  std::mt19937 rng(kSeed + 2);
  KDL::JntArray q(7), qd(7), qdd(7), tau(7);
  KDL::Wrenches none(chain.getNrOfSegments(), KDL::Wrench::Zero());
  Eigen::VectorXd ours(7);
  for (int sample = 0; sample < 100; ++sample) {
    const State s = randomState(model, rng);
    q.data = s.q;
    qd.data = s.qd;
    qdd.data = s.qdd;
    ASSERT_GE(rne.CartToJnt(q, qd, qdd, none, tau), 0);
    ASSERT_EQ(bd::inverseDynamics(model, data, s.q, s.qd, s.qdd, ours), bd::DynamicsStatus::Success);
    EXPECT_LE((ours - tau.data).cwiseAbs().maxCoeff(), 1e-9);
  }
  // On the mass matrix the rotor inertias are exactly the extra diagonal.
  const bk::ChainModel without = bk::ChainModel::fromUrdfString(xml, "wam_base", "wam_tool");
  bd::DynamicsData data_without(without);
  const Eigen::VectorXd q0 = Eigen::VectorXd::Constant(7, 0.4);
  ASSERT_EQ(bd::massMatrix(model, data, q0), bd::DynamicsStatus::Success);
  ASSERT_EQ(bd::massMatrix(without, data_without, q0), bd::DynamicsStatus::Success);
  EXPECT_LE((data.mass_matrix - data_without.mass_matrix - Eigen::MatrixXd(rotor.asDiagonal())).cwiseAbs().maxCoeff(),
            1e-12);
}

TEST(RigidBodyDynamics, PayloadEqualsAPointMassLinkAtTheTip) {
  std::string xml = readFile(kWamUrdf);
  const bk::ChainModel model = bk::ChainModel::fromUrdfString(xml, "wam_base", "wam_tool");
  // The same payload as a URDF link fixed to the tool (a point mass: zero inertia about its centre).
  const std::string extra =
      "  <link name=\"payload\"><inertial><origin xyz=\"0.02 -0.01 0.08\" rpy=\"0 0 0\"/><mass value=\"1.3\"/>"
      "<inertia ixx=\"0\" ixy=\"0\" ixz=\"0\" iyy=\"0\" iyz=\"0\" izz=\"0\"/></inertial></link>\n"
      "  <joint name=\"payload_joint\" type=\"fixed\"><parent link=\"wam_tool\"/><child link=\"payload\"/>"
      "<origin xyz=\"0 0 0\" rpy=\"0 0 0\"/></joint>\n";
  xml.insert(xml.rfind("</robot>"), extra);
  const bk::ChainModel loaded = bk::ChainModel::fromUrdfString(xml, "wam_base", "payload");
  bd::Payload payload;
  payload.mass = 1.3;
  payload.com = Eigen::Vector3d(0.02, -0.01, 0.08);
  bd::DynamicsData a(model), b(loaded);
  std::mt19937 rng(kSeed + 3);
  Eigen::VectorXd tau_a(7), tau_b(7);
  for (int sample = 0; sample < 100; ++sample) {
    const State s = randomState(model, rng);
    ASSERT_EQ(bd::inverseDynamics(model, a, s.q, s.qd, s.qdd, tau_a, payload), bd::DynamicsStatus::Success);
    ASSERT_EQ(bd::inverseDynamics(loaded, b, s.q, s.qd, s.qdd, tau_b), bd::DynamicsStatus::Success);
    EXPECT_LE((tau_a - tau_b).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(RigidBodyDynamics, BadInputIsAStatus) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  bd::DynamicsData data(model);
  const Eigen::VectorXd ok = Eigen::VectorXd::Zero(7);
  Eigen::VectorXd out(7), wrong_out(6);
  EXPECT_EQ(bd::inverseDynamics(model, data, Eigen::VectorXd::Zero(6), ok, ok, out), bd::DynamicsStatus::WrongSize);
  EXPECT_EQ(bd::inverseDynamics(model, data, ok, ok, ok, wrong_out), bd::DynamicsStatus::WrongSize);
  Eigen::VectorXd nan = ok;
  nan[4] = std::nan("");
  EXPECT_EQ(bd::inverseDynamics(model, data, ok, nan, ok, out), bd::DynamicsStatus::NotFinite);
  EXPECT_EQ(bd::forwardDynamics(model, data, ok, ok, nan, out), bd::DynamicsStatus::NotFinite);
  EXPECT_EQ(bd::massMatrix(model, data, nan), bd::DynamicsStatus::NotFinite);
  EXPECT_THROW(model.withRotorInertia(Eigen::VectorXd::Constant(7, -1.0)), std::invalid_argument);
}

TEST(RigidBodyDynamics, RealTimeCallsDoNotAllocate) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfString(kMixedUrdf, "base", "tool");
  bd::DynamicsData data(model);
  const int n = model.nq();
  const Eigen::VectorXd q = Eigen::VectorXd::Constant(n, 0.1);
  const Eigen::VectorXd qd = Eigen::VectorXd::Constant(n, 0.3);
  Eigen::VectorXd out(n);
  bd::Payload payload;
  payload.mass = 0.5;
  NoAllocGuard guard;
  EXPECT_EQ(bd::inverseDynamics(model, data, q, qd, qd, out, payload), bd::DynamicsStatus::Success);
  EXPECT_EQ(bd::massMatrix(model, data, q, payload), bd::DynamicsStatus::Success);
  EXPECT_EQ(bd::coriolisTorques(model, data, q, qd, out), bd::DynamicsStatus::Success);
  EXPECT_EQ(bd::gravityTorques(model, data, q, out), bd::DynamicsStatus::Success);
  EXPECT_EQ(bd::forwardDynamics(model, data, q, qd, qd, out, payload), bd::DynamicsStatus::Success);
}
