// Loading chains from URDF: the WAM models' contents and clear errors for every bad description.
#include "bimanual_skills/kinematics/chain_model.hpp"
#include "test_support.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

using bimanual_skills::kinematics::ChainModel;
using bimanual_skills::kinematics::JointType;

namespace {

using bimanual_skills::test_support::kWamUrdf;
const std::string kBimanualUrdf = BIMANUAL_SKILLS_SOURCE_DIR "/urdf/bimanual_wam.urdf";

/// Expects loading to throw std::invalid_argument whose message contains `needle`.
template <typename Load>
void expectLoadError(Load load, const std::string& needle) {
  try {
    load();
    ADD_FAILURE() << "no exception; expected one mentioning '" << needle << "'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
        << "message '" << e.what() << "' does not mention '" << needle << "'";
  }
}

std::string robot(const std::string& body) {
  return "<?xml version=\"1.0\"?><robot name=\"r\">" + body + "</robot>";
}

}  // namespace

TEST(ChainLoading, WamHasThesisLimitsAndNames) {
  const ChainModel model = ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  ASSERT_EQ(model.nq(), 7);
  const double lower[] = {-2.6, -2.0, -2.8, -0.9, -4.8, -1.6, -2.2};
  const double upper[] = {2.6, 2.0, 2.8, 3.1, 1.3, 1.6, 2.2};
  for (int i = 0; i < 7; ++i) {
    EXPECT_EQ(model.lowerLimits()[i], lower[i]) << "joint " << i + 1;
    EXPECT_EQ(model.upperLimits()[i], upper[i]) << "joint " << i + 1;
    EXPECT_GT(model.effortLimits()[i], 0.0);
    EXPECT_TRUE(std::isfinite(model.velocityLimits()[i]));
    EXPECT_EQ(model.joints()[static_cast<std::size_t>(i)].type, JointType::Revolute);
  }
  EXPECT_EQ(model.jointNames().front(), "wam_joint1");
  EXPECT_EQ(model.frameNames().size(), 8U);
  EXPECT_EQ(model.frameNames().back(), "wam_tool");
  EXPECT_EQ(model.frameIndex("wam_link4"), 3);
  EXPECT_EQ(model.frameIndex("no_such_link"), -1);
}

TEST(ChainLoading, WamReachBoundIsTheStretchedArm) {
  const ChainModel model = ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  // Joint origins after the first: (0.045, 0, 0.55), (-0.045, 0, 0), (0, 0, 0.3), then the 0.06 m tool offset.
  EXPECT_NEAR(model.reachBound(), std::hypot(0.045, 0.55) + 0.045 + 0.3 + 0.06, 1e-12);
  EXPECT_GE(model.reachBound(), 0.91);
  EXPECT_EQ(model.firstJointOrigin().z(), 0.346);
}

TEST(ChainLoading, WithinLimitsRejectsWrongSizeNanAndOutside) {
  const ChainModel model = ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_tool");
  Eigen::VectorXd q = Eigen::VectorXd::Zero(7);
  EXPECT_TRUE(model.withinLimits(q));
  EXPECT_FALSE(model.withinLimits(Eigen::VectorXd::Zero(6)));
  q[3] = -1.0;
  EXPECT_FALSE(model.withinLimits(q));
  EXPECT_TRUE(model.withinLimits(q, 0.2));
  q[3] = std::nan("");
  EXPECT_FALSE(model.withinLimits(q, 10.0));
}

TEST(ChainLoading, BimanualChainsStartAtTheWorld) {
  const ChainModel left = ChainModel::fromUrdfFile(kBimanualUrdf, "world", "left_wam_tool");
  EXPECT_EQ(left.nq(), 7);
  EXPECT_EQ(left.jointNames().back(), "left_wam_joint7");
}

TEST(ChainLoading, MissingFileIsAClearError) {
  expectLoadError([] { ChainModel::fromUrdfFile("/nonexistent/robot.urdf", "a", "b"); },
                  "cannot read URDF file '/nonexistent/robot.urdf'");
}

TEST(ChainLoading, MalformedUrdfIsAClearError) {
  expectLoadError([] { ChainModel::fromUrdfString("<robot name='r'><link name='a'>", "a", "b"); }, "not valid URDF");
  expectLoadError([] { ChainModel::fromUrdfString("", "a", "b"); }, "not valid URDF");
}

TEST(ChainLoading, UnknownLinkIsNamed) {
  expectLoadError([] { ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_hand"); }, "unknown link 'wam_hand'");
  expectLoadError([] { ChainModel::fromUrdfFile(kWamUrdf, "table", "wam_tool"); }, "unknown link 'table'");
}

TEST(ChainLoading, NonSerialPathIsRejected) {
  // From one arm's base to the other arm's tool the path goes up to the world and down again.
  expectLoadError([] { ChainModel::fromUrdfFile(kBimanualUrdf, "right_wam_base", "left_wam_tool"); },
                  "not an ancestor");
  // Tip above base: reversed chain.
  expectLoadError([] { ChainModel::fromUrdfFile(kWamUrdf, "wam_tool", "wam_base"); }, "not an ancestor");
}

TEST(ChainLoading, FloatingJointIsRejected) {
  const std::string xml = robot(
      "<link name='a'/><link name='b'/>"
      "<joint name='free' type='floating'><parent link='a'/><child link='b'/></joint>");
  expectLoadError([&] { ChainModel::fromUrdfString(xml, "a", "b"); }, "floating or planar");
}

TEST(ChainLoading, MimicJointIsRejected) {
  const std::string xml = robot(
      "<link name='a'/><link name='b'/><link name='c'/>"
      "<joint name='j1' type='continuous'><parent link='a'/><child link='b'/></joint>"
      "<joint name='j2' type='continuous'><parent link='b'/><child link='c'/><mimic joint='j1'/></joint>");
  expectLoadError([&] { ChainModel::fromUrdfString(xml, "a", "c"); }, "mimics");
}

TEST(ChainLoading, ChainWithoutMovableJointIsRejected) {
  expectLoadError([] { ChainModel::fromUrdfFile(kWamUrdf, "wam_flange", "wam_tool"); }, "no movable joint");
  expectLoadError([] { ChainModel::fromUrdfFile(kWamUrdf, "wam_base", "wam_base"); }, "no movable joint");
}

TEST(ChainLoading, ContinuousJointsHaveInfiniteLimits) {
  const std::string xml = robot(
      "<link name='a'/><link name='b'/>"
      "<joint name='j' type='continuous'><parent link='a'/><child link='b'/><axis xyz='0 1 0'/></joint>");
  const ChainModel model = ChainModel::fromUrdfString(xml, "a", "b");
  EXPECT_TRUE(std::isinf(model.lowerLimits()[0]));
  EXPECT_TRUE(std::isinf(model.upperLimits()[0]));
}

TEST(ChainModelConstruction, InvalidJointsAreRejected) {
  using bimanual_skills::kinematics::ChainJoint;
  ChainJoint joint;
  joint.name = "j";
  joint.child_link = "b";
  joint.axis.setZero();
  expectLoadError([&] { ChainModel("a", "b", {joint}, Eigen::Isometry3d::Identity()); }, "axis is zero");
  joint.axis = Eigen::Vector3d::UnitX();
  joint.lower = 1.0;
  joint.upper = -1.0;
  expectLoadError([&] { ChainModel("a", "b", {joint}, Eigen::Isometry3d::Identity()); }, "lower > upper");
}
