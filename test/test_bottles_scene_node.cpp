// The bottles' scene through ROS (bottles_scene.test): bullet_sim publishes the free obstacles where contacts have
// moved them, on ~obstacle_poses (the scene file's order, stamped with the simulation's time) and on ~markers: of
// test/bottles_falling_sim.yaml's bottles, the two standing stay where the file puts them and the one started past
// its tipping angle lies on the table after a second; the RGB-D camera sees them there, the fallen one lying, not
// standing where the file put it.
#include "bimanual_skills/sim/sim_config.hpp"

#include <geometry_msgs/PoseArray.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

namespace {

/// The angle between a pose's z axis and the world's.
double tilt(const geometry_msgs::Pose& p) {
  const Eigen::Quaterniond q(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z);
  return std::acos(std::clamp(q.normalized().toRotationMatrix()(2, 2), -1.0, 1.0));
}

Eigen::Isometry3d poseOf(const geometry_msgs::Pose& p) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  pose.linear() =
      Eigen::Quaterniond(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z).normalized().matrix();
  return pose;
}

/// A 32FC1 depth image's value [m] where `info`'s camera at `camera` (world from optical frame) sees the world point
/// `point`, and that point's own depth; NaN for a point outside the image.
std::pair<double, double> depthAt(const sensor_msgs::Image& depth, const sensor_msgs::CameraInfo& info,
                                  const Eigen::Isometry3d& camera, const Eigen::Vector3d& point) {
  const Eigen::Vector3d c = camera.inverse() * point;
  const double u = info.P[0] * c.x() / c.z() + info.P[2], v = info.P[5] * c.y() / c.z() + info.P[6];
  const auto col = static_cast<long>(std::lround(u)), row = static_cast<long>(std::lround(v));
  if (c.z() <= 0.0 || col < 0 || row < 0 || col >= static_cast<long>(depth.width) ||
      row >= static_cast<long>(depth.height)) {
    return {std::numeric_limits<double>::quiet_NaN(), c.z()};
  }
  float d = 0.0f;
  std::memcpy(&d, &depth.data[static_cast<std::size_t>(row) * depth.step + static_cast<std::size_t>(col) * 4], 4);
  return {d, c.z()};
}

}  // namespace

TEST(BottlesScene, TheFreeObstaclesArePublishedWhereTheyAreNow) {
  const bimanual_skills::sim::SimConfig scene = bimanual_skills::sim::SimConfig::fromYamlFile(
      std::string(BIMANUAL_SKILLS_SOURCE_DIR) + "/test/bottles_falling_sim.yaml");
  ASSERT_EQ(scene.obstacles.size(), 3u);
  // A message stamped 1.5 s or later (the topic is not latched; bullet_sim runs at real time).
  const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(60.0);
  geometry_msgs::PoseArrayConstPtr poses;
  while (ros::ok() && ros::WallTime::now() < until && (!poses || poses->header.stamp.toSec() < 1.5)) {
    poses = ros::topic::waitForMessage<geometry_msgs::PoseArray>("/bullet_sim/obstacle_poses", ros::Duration(5.0));
  }
  ASSERT_TRUE(poses && poses->header.stamp.toSec() >= 1.5) << "no ~obstacle_poses stamped 1.5 s or later in 60 s";
  EXPECT_EQ(poses->header.frame_id, "world");
  ASSERT_EQ(poses->poses.size(), 3u);
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector3d file = scene.obstacles[static_cast<std::size_t>(k)].pose.translation();
    const geometry_msgs::Point& p = poses->poses[static_cast<std::size_t>(k)].position;
    EXPECT_LT((Eigen::Vector3d(p.x, p.y, p.z) - file).norm(), 0.002)
        << scene.obstacles[static_cast<std::size_t>(k)].name;
    EXPECT_LT(tilt(poses->poses[static_cast<std::size_t>(k)]), 0.01);
  }
  EXPECT_GT(tilt(poses->poses[2]), 1.2) << "the third should lie on the table";
  EXPECT_LT(poses->poses[2].position.z, scene.obstacles[2].pose.translation().z() - 0.05);

  // The markers show the same: the fallen one lying.
  const auto markers =
      ros::topic::waitForMessage<visualization_msgs::MarkerArray>("/bullet_sim/markers", ros::Duration(10.0));
  ASSERT_TRUE(markers);
  bool seen = false;
  for (const visualization_msgs::Marker& m : markers->markers) {
    if (m.ns != "obstacles" || m.id != 2) continue;
    seen = true;
    EXPECT_GT(tilt(m.pose), 1.2);
  }
  EXPECT_TRUE(seen) << "no marker of the third obstacle";

  // The RGB-D camera's depth image of then: the standing bottle's top, the fallen one's upper side where it lies,
  // and nothing any more where the file stood it.
  sensor_msgs::ImageConstPtr depth;
  while (ros::ok() && ros::WallTime::now() < until && (!depth || depth->header.stamp.toSec() < 1.5)) {
    depth = ros::topic::waitForMessage<sensor_msgs::Image>("/rgbd/depth/image_raw", ros::Duration(5.0));
  }
  ASSERT_TRUE(depth && depth->header.stamp.toSec() >= 1.5) << "no rgbd/depth/image_raw stamped 1.5 s or later";
  ASSERT_EQ(depth->encoding, "32FC1");
  const auto info = ros::topic::waitForMessage<sensor_msgs::CameraInfo>("/rgbd/depth/camera_info", ros::Duration(5.0));
  ASSERT_TRUE(info);
  tf2_ros::Buffer tf;
  tf2_ros::TransformListener listener(tf);
  const Eigen::Isometry3d camera =
      tf2::transformToEigen(tf.lookupTransform("world", info->header.frame_id, ros::Time(0), ros::Duration(10.0)));
  const auto now =
      ros::topic::waitForMessage<geometry_msgs::PoseArray>("/bullet_sim/obstacle_poses", ros::Duration(5.0));
  ASSERT_TRUE(now && now->poses.size() == 3u);
  const double radius = scene.obstacles[2].size.x(), half = 0.5 * scene.obstacles[2].size.y();
  const auto standing = depthAt(*depth, *info, camera, poseOf(now->poses[1]) * Eigen::Vector3d(0.0, 0.0, half));
  EXPECT_NEAR(standing.first, standing.second, 0.01) << "bottle_2's top";
  const Eigen::Vector3d lying = poseOf(now->poses[2]).translation() + Eigen::Vector3d(0.0, 0.0, radius);
  const auto fallen = depthAt(*depth, *info, camera, lying);
  EXPECT_NEAR(fallen.first, fallen.second, 0.015) << "the fallen bottle's upper side, where it lies now";
  const auto file = depthAt(*depth, *info, camera, scene.obstacles[2].pose * Eigen::Vector3d(0.0, 0.0, half));
  EXPECT_GT(file.first, file.second + 0.05) << "the camera still sees the fallen bottle's top where the file put it";
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_bottles_scene_node");
  ros::NodeHandle node;
  return RUN_ALL_TESTS();
}
