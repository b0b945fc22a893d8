// rostest (test/workspace_markers.test): workspace_markers publishes a coarse map of the WAM, latched: the reachable
// voxels up to the slice y = 0 (the cutaway) as one CUBE_LIST in the base frame with a colour per voxel, and arrows for
// the tool cones of the slice y = 0, each of the voxel's edge in length and pointing along a unit axis.
#include "cli/pinned_numerics.hpp"

#include <ros/ros.h>
#include <visualization_msgs/MarkerArray.h>

#include <gtest/gtest.h>

#include <cmath>

namespace {

visualization_msgs::MarkerArrayConstPtr wait(const std::string& topic) {
  return ros::topic::waitForMessage<visualization_msgs::MarkerArray>(topic, ros::Duration(120.0));
}

}  // namespace

TEST(WorkspaceMarkers, PublishesTheMapAndTheCones) {
  const auto map = wait("/workspace_markers/map");
  ASSERT_TRUE(map) << "no map within 2 minutes";
  ASSERT_EQ(map->markers.size(), 1u);
  const visualization_msgs::Marker& cubes = map->markers.front();
  EXPECT_EQ(cubes.type, visualization_msgs::Marker::CUBE_LIST);
  EXPECT_EQ(cubes.header.frame_id, "left_wam_base");  // the robot file's first arm
  EXPECT_GT(cubes.points.size(), 10u);
  EXPECT_EQ(cubes.colors.size(), cubes.points.size());
  EXPECT_NEAR(cubes.scale.x, 0.9 * 0.3, 1e-12);
  for (const geometry_msgs::Point& p : cubes.points) {
    EXPECT_LT(std::hypot(p.x, p.y, p.z - 0.346), 1.3) << "a voxel beyond the WAM's reach from its shoulder";
    EXPECT_LE(p.y, 0.15 + 1e-9) << "the cutaway keeps the voxels up to the slice y = 0";
  }

  const auto cones = wait("/workspace_markers/cones");
  ASSERT_TRUE(cones);
  ASSERT_FALSE(cones->markers.empty());
  for (const visualization_msgs::Marker& arrow : cones->markers) {
    ASSERT_EQ(arrow.type, visualization_msgs::Marker::ARROW);
    ASSERT_EQ(arrow.points.size(), 2u);
    EXPECT_NEAR(arrow.points[0].y, 0.0, 0.15) << "the slice y = 0";
    const double length = std::hypot(arrow.points[1].x - arrow.points[0].x, arrow.points[1].y - arrow.points[0].y,
                                     arrow.points[1].z - arrow.points[0].z);
    EXPECT_NEAR(length, 0.8 * 0.3, 1e-9);
  }
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_workspace_markers");
  ros::NodeHandle node;
  return RUN_ALL_TESTS();
}
