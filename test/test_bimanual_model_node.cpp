// rostest: the launched bimanual model publishes joint states and transforms that agree with the core library.
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "cli/pinned_numerics.hpp"

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/transform_listener.h>

#include <string>
#include <vector>

namespace bk = bimanual_skills::kinematics;

namespace {

/// The robot file's start posture (config/robots/wam.yaml: both arms), which bimanual_fk_demo commands.
const std::vector<double> kStart = {0.0, 0.6, 0.0, 2.0, 0.0, 0.5, 0.0};

}  // namespace

TEST(BimanualModel, JointStatesCarryBothArmsCommandedConfigurations) {
  const auto msg = ros::topic::waitForMessage<sensor_msgs::JointState>("joint_states", ros::Duration(20.0));
  ASSERT_TRUE(msg) << "no /joint_states within 20 s";
  ASSERT_EQ(msg->name.size(), 14U);
  ASSERT_EQ(msg->position.size(), 14U);
  EXPECT_EQ(msg->name[0], "left_wam_joint1");
  EXPECT_EQ(msg->name[7], "right_wam_joint1");
  for (std::size_t i = 0; i < 7; ++i) {
    EXPECT_EQ(msg->position[i], kStart[i]);
    EXPECT_EQ(msg->position[7 + i], kStart[i]);
  }
}

TEST(BimanualModel, PublishedTransformsEqualCoreForwardKinematics) {
  std::string description;
  ASSERT_TRUE(ros::param::get("/robot_description", description));
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  for (const std::string arm : {"left", "right"}) {
    const bk::ChainModel model = bk::ChainModel::fromUrdfString(description, "world", arm + "_wam_tool");
    bk::ChainData data(model);
    const std::vector<double>& q = kStart;
    ASSERT_EQ(bk::forwardKinematics(model, data, Eigen::Map<const Eigen::VectorXd>(q.data(), 7)),
              bk::KinematicsStatus::Success);
    std::string error;
    ASSERT_TRUE(buffer.canTransform("world", arm + "_wam_tool", ros::Time(0), ros::Duration(20.0), &error)) << error;
    const Eigen::Isometry3d tf =
        tf2::transformToEigen(buffer.lookupTransform("world", arm + "_wam_tool", ros::Time(0)));
    EXPECT_LE((tf.matrix() - data.tipPose().matrix()).cwiseAbs().maxCoeff(), 1e-9) << arm;
    // Each arm's mounting plate stands where config/robots/wam/placement.yaml puts it.
    const Eigen::Isometry3d base =
        tf2::transformToEigen(buffer.lookupTransform("world", arm + "_wam_base", ros::Time(0)));
    EXPECT_NEAR(base.translation().y(), arm == "left" ? 0.4 : -0.4, 1e-12);
  }
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_bimanual_model");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
