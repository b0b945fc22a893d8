// Forward kinematics and Jacobians against independent references: KDL on the same URDF, central finite
// differences of FK, and the WAM's known poses. Real-time calls are checked for heap allocations.
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "test_support.hpp"
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainjnttojacsolver.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include <Eigen/Eigenvalues>

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <tuple>

namespace bk = bimanual_skills::kinematics;
using bimanual_skills::testing::NoAllocGuard;

using bimanual_skills::test_support::kWamUrdf;
using bimanual_skills::test_support::randomWithinLimits;
using bimanual_skills::test_support::readFile;

namespace {

const std::string kBimanualUrdf = BIMANUAL_SKILLS_SOURCE_DIR "/urdf/bimanual_wam.urdf";
constexpr unsigned kSeed = 20170601;

// A chain with axes along ±x, ±y, skewed directions, a prismatic and a continuous joint, and fixed joints between
// movable ones and after the last: exercises every branch of the model's preprocessing.
const char* const kMixedUrdf = R"(<?xml version="1.0"?>
<robot name="mixed">
  <link name="base"/><link name="l1"/><link name="l1_fixed"/><link name="l2"/><link name="l3"/><link name="l4"/>
  <link name="l5"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.3 -0.2 0.1"/><axis xyz="1 0 0"/>
    <limit lower="-2" upper="2" effort="10" velocity="1"/></joint>
  <joint name="f1" type="fixed"><parent link="l1"/><child link="l1_fixed"/>
    <origin xyz="0 0.25 0" rpy="0 0.5 0"/></joint>
  <joint name="j2" type="revolute"><parent link="l1_fixed"/><child link="l2"/>
    <origin xyz="0.2 0 0.05" rpy="0 0 1.0"/><axis xyz="0 -1 0"/>
    <limit lower="-2" upper="2" effort="10" velocity="1"/></joint>
  <joint name="j3" type="prismatic"><parent link="l2"/><child link="l3"/>
    <origin xyz="0 0 0.3" rpy="0.2 0 0"/><axis xyz="0.6 0 0.8"/>
    <limit lower="-0.2" upper="0.4" effort="100" velocity="0.5"/></joint>
  <joint name="j4" type="continuous"><parent link="l3"/><child link="l4"/>
    <origin xyz="0.1 0.1 0" rpy="-0.4 0.3 0"/><axis xyz="0.2 0.5 -0.3"/></joint>
  <joint name="j5" type="revolute"><parent link="l4"/><child link="l5"/>
    <origin xyz="0 0 0.15" rpy="0 0 0"/><axis xyz="0 0 -1"/>
    <limit lower="-2" upper="2" effort="10" velocity="1"/></joint>
  <joint name="tool_joint" type="fixed"><parent link="l5"/><child link="tool"/>
    <origin xyz="0.05 0 0.1" rpy="0.1 0.2 0.3"/></joint>
</robot>)";

struct KdlReference {
  KDL::Chain chain;
  explicit KdlReference(const std::string& urdf_xml, const std::string& base, const std::string& tip) {
    KDL::Tree tree;
    if (!kdl_parser::treeFromString(urdf_xml, tree) || !tree.getChain(base, tip, chain)) {
      throw std::runtime_error("KDL could not build the reference chain");
    }
  }
};

Eigen::Isometry3d toEigen(const KDL::Frame& frame) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    out.translation()[r] = frame.p(r);
    for (int c = 0; c < 3; ++c) out.linear()(r, c) = frame.M(r, c);
  }
  return out;
}

double maxAbsDiff(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff();
}

/// Compares every frame and both Jacobians with KDL on `samples` random configurations.
void expectEqualToKdl(const std::string& urdf_xml, const std::string& base, const std::string& tip, int samples) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfString(urdf_xml, base, tip);
  bk::ChainData data(model);
  const KdlReference kdl(urdf_xml, base, tip);
  ASSERT_EQ(static_cast<int>(kdl.chain.getNrOfJoints()), model.nq());
  KDL::ChainFkSolverPos_recursive fk(kdl.chain);
  KDL::ChainJntToJacSolver jac(kdl.chain);
  KDL::JntArray q_kdl(kdl.chain.getNrOfJoints());
  KDL::Jacobian J_kdl(kdl.chain.getNrOfJoints());
  std::mt19937 rng(kSeed);
  double worst_pose = 0.0;
  double worst_jacobian = 0.0;
  for (int sample = 0; sample < samples; ++sample) {
    const Eigen::VectorXd q = randomWithinLimits(model, rng);
    q_kdl.data = q;
    ASSERT_EQ(bk::computeJacobian(model, data, q), bk::KinematicsStatus::Success);
    // Every named frame against the KDL segment of the same name.
    for (unsigned segment = 0; segment < kdl.chain.getNrOfSegments(); ++segment) {
      const int index = model.frameIndex(kdl.chain.getSegment(segment).getName());
      if (index < 0) continue;
      KDL::Frame frame;
      ASSERT_GE(fk.JntToCart(q_kdl, frame, static_cast<int>(segment) + 1), 0);
      worst_pose = std::max(worst_pose, maxAbsDiff(data.frame_poses[static_cast<std::size_t>(index)], toEigen(frame)));
    }
    KDL::Frame tip_frame;
    ASSERT_GE(fk.JntToCart(q_kdl, tip_frame), 0);
    worst_pose = std::max(worst_pose, maxAbsDiff(data.tipPose(), toEigen(tip_frame)));
    ASSERT_GE(jac.JntToJac(q_kdl, J_kdl), 0);
    worst_jacobian = std::max(worst_jacobian, (data.jacobian - J_kdl.data).cwiseAbs().maxCoeff());
    // Tip-frame Jacobian: KDL's rotated into the tip frame.
    ASSERT_EQ(bk::computeJacobian(model, data, q, bk::JacobianFrame::Tip), bk::KinematicsStatus::Success);
    J_kdl.changeBase(tip_frame.M.Inverse());
    worst_jacobian = std::max(worst_jacobian, (data.jacobian - J_kdl.data).cwiseAbs().maxCoeff());
  }
  EXPECT_LE(worst_pose, 1e-12) << base << " -> " << tip;
  EXPECT_LE(worst_jacobian, 1e-12) << base << " -> " << tip;
}

}  // namespace

TEST(ChainKinematics, WamMatchesKdlOn1000RandomConfigurations) {
  expectEqualToKdl(readFile(kWamUrdf), "wam_base", "wam_tool", 1000);
}

TEST(ChainKinematics, BimanualArmsMatchKdlFromTheWorld) {
  const std::string xml = readFile(kBimanualUrdf);
  expectEqualToKdl(xml, "world", "left_wam_tool", 200);
  expectEqualToKdl(xml, "world", "right_wam_flange", 200);
}

TEST(ChainKinematics, MixedAxesPrismaticAndFixedJointsMatchKdl) {
  expectEqualToKdl(kMixedUrdf, "base", "tool", 1000);
}

TEST(ChainKinematics, JacobianEqualsCentralFiniteDifferencesOfFk) {
  for (const auto& [xml, base, tip] :
       {std::tuple<std::string, std::string, std::string>{readFile(kWamUrdf), "wam_base", "wam_tool"},
        {kMixedUrdf, "base", "tool"}}) {
    const bk::ChainModel model = bk::ChainModel::fromUrdfString(xml, base, tip);
    bk::ChainData data(model);
    bk::ChainData probe(model);
    std::mt19937 rng(kSeed + 1);
    const double h = 1e-6;
    double worst = 0.0;
    for (int sample = 0; sample < 200; ++sample) {
      const Eigen::VectorXd q = randomWithinLimits(model, rng);
      ASSERT_EQ(bk::computeJacobian(model, data, q), bk::KinematicsStatus::Success);
      for (int j = 0; j < model.nq(); ++j) {
        Eigen::VectorXd q_plus = q;
        Eigen::VectorXd q_minus = q;
        q_plus[j] += h;
        q_minus[j] -= h;
        ASSERT_EQ(bk::forwardKinematics(model, probe, q_plus), bk::KinematicsStatus::Success);
        const Eigen::Isometry3d plus = probe.tipPose();
        ASSERT_EQ(bk::forwardKinematics(model, probe, q_minus), bk::KinematicsStatus::Success);
        const Eigen::Isometry3d minus = probe.tipPose();
        const Eigen::Vector3d v = (plus.translation() - minus.translation()) / (2 * h);
        // ω from the rotation taking the minus pose to the plus pose, expressed in the base frame.
        const Eigen::AngleAxisd turn(plus.linear() * minus.linear().transpose());
        const Eigen::Vector3d w = turn.axis() * turn.angle() / (2 * h);
        worst = std::max(worst, (data.jacobian.col(j).head<3>() - v).cwiseAbs().maxCoeff());
        worst = std::max(worst, (data.jacobian.col(j).tail<3>() - w).cwiseAbs().maxCoeff());
      }
    }
    EXPECT_LE(worst, 1e-6) << base << " -> " << tip;
  }
}

TEST(ChainKinematics, WamKnownPoses) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_flange");
  bk::ChainData data(model);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(7);
  ASSERT_EQ(bk::forwardKinematics(model, data, q), bk::KinematicsStatus::Success);
  const Eigen::Vector3d shoulder = data.frame_poses[0].translation();
  EXPECT_LE((shoulder - Eigen::Vector3d(0, 0, 0.346)).norm(), 1e-12);
  // Straight up: the flange is 0.55 + 0.3 + 0.06 m above the shoulder.
  EXPECT_LE((data.tipPose().translation() - shoulder - Eigen::Vector3d(0, 0, 0.91)).norm(), 1e-12);
  q[3] = M_PI / 2;
  ASSERT_EQ(bk::forwardKinematics(model, data, q), bk::KinematicsStatus::Success);
  EXPECT_LE((data.tipPose().translation() - shoulder - Eigen::Vector3d(0.405, 0, 0.595)).norm(), 1e-12);
}

TEST(ChainKinematics, BimanualBasesComeFromTheConfiguration) {
  const std::string xml = readFile(kBimanualUrdf);
  const bk::ChainModel arm = bk::ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  bk::ChainData arm_data(arm);
  const Eigen::VectorXd q = (Eigen::VectorXd(7) << 0.1, 0.5, -0.2, 1.4, 0.3, 0.6, -0.1).finished();
  ASSERT_EQ(bk::forwardKinematics(arm, arm_data, q), bk::KinematicsStatus::Success);
  for (const auto& [prefix, y] : {std::pair<std::string, double>{"left_", 0.4}, {"right_", -0.4}}) {
    const bk::ChainModel model = bk::ChainModel::fromUrdfString(xml, "world", prefix + "wam_tool");
    bk::ChainData data(model);
    ASSERT_EQ(bk::forwardKinematics(model, data, q), bk::KinematicsStatus::Success);
    const Eigen::Isometry3d expected = Eigen::Translation3d(0.0, y, 0.0) * arm_data.tipPose();
    EXPECT_LE(maxAbsDiff(data.tipPose(), expected), 1e-12) << prefix;
  }
}

TEST(ChainKinematics, ManipulabilityAndConditionNumberMatchTheirDefinitions) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  bk::ChainData data(model);
  std::mt19937 rng(kSeed + 2);
  for (int sample = 0; sample < 100; ++sample) {
    const Eigen::VectorXd q = randomWithinLimits(model, rng);
    ASSERT_EQ(bk::computeJacobian(model, data, q), bk::KinematicsStatus::Success);
    const Eigen::Matrix<double, 6, 6> JJt = data.jacobian * data.jacobian.transpose();
    EXPECT_NEAR(bk::manipulability(data), std::sqrt(JJt.determinant()), 1e-9);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eigen(JJt);
    const double kappa = std::sqrt(eigen.eigenvalues().maxCoeff() / eigen.eigenvalues().minCoeff());
    EXPECT_NEAR(bk::conditionNumber(data) / kappa, 1.0, 1e-6);
  }
  // Straight up, joints 1, 3, 5 and 7 share one vertical axis: a singular configuration.
  ASSERT_EQ(bk::computeJacobian(model, data, Eigen::VectorXd::Zero(7)), bk::KinematicsStatus::Success);
  EXPECT_LE(bk::manipulability(data), 1e-12);
  EXPECT_GE(bk::conditionNumber(data), 1e12);
}

TEST(ChainKinematics, LinkJacobianIgnoresLaterJoints) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfString(kMixedUrdf, "base", "tool");
  bk::ChainData data(model);
  const KdlReference kdl(kMixedUrdf, "base", "l2");
  KDL::ChainJntToJacSolver jac(kdl.chain);
  std::mt19937 rng(kSeed + 3);
  const Eigen::VectorXd q = randomWithinLimits(model, rng);
  ASSERT_EQ(bk::forwardKinematics(model, data, q), bk::KinematicsStatus::Success);
  bk::Matrix6Xd J(6, model.nq());
  ASSERT_EQ(bk::frameJacobian(model, data, model.frameIndex("l2"), bk::JacobianFrame::Base, J),
            bk::KinematicsStatus::Success);
  KDL::JntArray q_kdl(2);
  q_kdl.data = q.head(2);
  KDL::Jacobian J_kdl(2);
  ASSERT_GE(jac.JntToJac(q_kdl, J_kdl), 0);
  EXPECT_LE((J.leftCols(2) - J_kdl.data).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_TRUE(J.rightCols(model.nq() - 2).isZero(0.0));
  EXPECT_EQ(bk::frameJacobian(model, data, model.nq() + 1, bk::JacobianFrame::Base, J),
            bk::KinematicsStatus::WrongSize);
}

TEST(ChainKinematics, BadInputIsAStatusNotACrash) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  bk::ChainData data(model);
  EXPECT_EQ(bk::forwardKinematics(model, data, Eigen::VectorXd::Zero(6)), bk::KinematicsStatus::WrongSize);
  EXPECT_EQ(bk::computeJacobian(model, data, Eigen::VectorXd::Zero(8)), bk::KinematicsStatus::WrongSize);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(7);
  q[2] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(bk::forwardKinematics(model, data, q), bk::KinematicsStatus::NotFinite);
  q[2] = std::numeric_limits<double>::infinity();
  EXPECT_EQ(bk::computeJacobian(model, data, q), bk::KinematicsStatus::NotFinite);
  EXPECT_STREQ(bk::toString(bk::KinematicsStatus::NotFinite), "joint vector contains NaN or Inf");
}

TEST(ChainKinematics, RealTimeCallsDoNotAllocate) {
  const bk::ChainModel model = bk::ChainModel::fromUrdfString(kMixedUrdf, "base", "tool");
  const bk::ChainModel wam = bk::ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  bk::ChainData data(model);
  bk::ChainData wam_data(wam);
  bk::Matrix6Xd J(6, model.nq());
  const Eigen::VectorXd q = Eigen::VectorXd::Constant(model.nq(), 0.3);
  const Eigen::VectorXd q_wam = Eigen::VectorXd::Constant(7, 0.3);
  const Eigen::VectorXd q_bad = Eigen::VectorXd::Zero(3);
  double sink = 0.0;
  // One guard per call, so a failure names the call that allocated.
  const auto check = [&](int line, auto&& call) {
    NoAllocGuard guard(__FILE__, line);
    sink += static_cast<double>(call());
  };
  check(__LINE__, [&] { return bk::forwardKinematics(model, data, q); });
  check(__LINE__, [&] { return bk::computeJacobian(model, data, q, bk::JacobianFrame::Base); });
  check(__LINE__, [&] { return bk::computeJacobian(model, data, q, bk::JacobianFrame::Tip); });
  check(__LINE__, [&] { return bk::frameJacobian(model, data, 2, bk::JacobianFrame::Tip, J); });
  check(__LINE__, [&] { return bk::computeJacobian(wam, wam_data, q_wam); });
  check(__LINE__, [&] { return bk::manipulability(wam_data); });
  check(__LINE__, [&] { return bk::conditionNumber(wam_data); });
  check(__LINE__, [&] { return bk::manipulability(data); });
  check(__LINE__, [&] { return bk::conditionNumber(data); });
  check(__LINE__, [&] { return bk::forwardKinematics(wam, wam_data, q_bad); });
  check(__LINE__, [&] { return wam.withinLimits(q_wam); });
  EXPECT_TRUE(std::isfinite(sink));
}
