// The bottles' scene through ROS (bottles_scene.test): bullet_sim publishes the free obstacles where contacts have
// moved them, on ~obstacle_poses (the scene file's order, stamped with the simulation's time) and on ~markers: of
// test/bottles_falling_sim.yaml's bottles, the two standing stay where the file puts them and the one started past
// its tipping angle lies on the table after a second.
#include "bimanual_skills/sim/sim_config.hpp"

#include <geometry_msgs/PoseArray.h>
#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <string>

namespace {

/// The angle between a pose's z axis and the world's.
double tilt(const geometry_msgs::Pose& p) {
  const Eigen::Quaterniond q(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z);
  return std::acos(std::clamp(q.normalized().toRotationMatrix()(2, 2), -1.0, 1.0));
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
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_bottles_scene_node");
  ros::NodeHandle node;
  return RUN_ALL_TESTS();
}
