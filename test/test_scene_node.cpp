// The scarf experiment's scene through ROS (scarf_scene.test): bullet_sim publishes the mannequin's shapes on
// ~markers in their colours; the scarf hangs from the left tool that holds its end, its far part on the floor; its
// perspective camera sends images of the mannequin, the red mark on its nose above the neck it looks at, the blue
// scarf, and nothing where nothing is.
#include "bimanual_skills/sim/sim_config.hpp"
#include "cli/pinned_numerics.hpp"

#include <ros/package.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <visualization_msgs/MarkerArray.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

namespace {

const std::string kPackage = BIMANUAL_SKILLS_SOURCE_DIR;

}  // namespace

TEST(ScarfScene, TheMannequinIsOnTheMarkersAndInTheCamerasImages) {
  const bimanual_skills::sim::SimConfig scene =
      bimanual_skills::sim::SimConfig::fromYamlFile(kPackage + "/config/scarf_sim.yaml");
  const auto markers =
      ros::topic::waitForMessage<visualization_msgs::MarkerArray>("/bullet_sim/markers", ros::Duration(60.0));
  ASSERT_TRUE(markers) << "no ~markers";
  int obstacles = 0;
  for (const visualization_msgs::Marker& m : markers->markers) {
    if (m.ns != "obstacles") continue;
    ++obstacles;
    ASSERT_LT(static_cast<std::size_t>(m.id), scene.obstacles.size());
    const bimanual_skills::sim::Obstacle& o = scene.obstacles[static_cast<std::size_t>(m.id)];
    EXPECT_NEAR(m.pose.position.z, o.pose.translation().z(), 1e-9) << o.name;
    EXPECT_NEAR(m.color.r, o.colour.x(), 1e-6) << o.name;
  }
  EXPECT_EQ(obstacles, static_cast<int>(scene.obstacles.size()));
  EXPECT_EQ(markers->markers.size(), scene.obstacles.size() + 1) << "the obstacles and the scarf, no table";

  // The scarf, held at its end at (0.25, 0.2, 0.6) from the reset on: after 3 s it hangs from there, its last 0.6 m
  // on the floor (and not through it).
  // ~cloth is latched and sent at most ~max_scene_rate per wall second: on a slow machine the latched cloud can be
  // one of before 3 s, so the test waits for a cloud stamped 3 s or later.
  const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(60.0);
  sensor_msgs::PointCloud2ConstPtr scarf;
  while (ros::ok() && ros::WallTime::now() < until && (!scarf || scarf->header.stamp.toSec() < 3.0)) {
    scarf = ros::topic::waitForMessage<sensor_msgs::PointCloud2>("/bullet_sim/cloth", ros::Duration(5.0));
    if (scarf && scarf->header.stamp.toSec() < 3.0) ros::WallDuration(0.05).sleep();
  }
  ASSERT_TRUE(scarf && scarf->header.stamp.toSec() >= 3.0) << "no ~cloth stamped 3 s or later within 60 s";
  float lowest = 10.0f, highest = -10.0f;
  for (sensor_msgs::PointCloud2ConstIterator<float> z(*scarf, "z"); z != z.end(); ++z) {
    lowest = std::min(lowest, *z);
    highest = std::max(highest, *z);
  }
  EXPECT_NEAR(highest, 0.6, 0.03) << "held at the tool";
  EXPECT_NEAR(lowest, 0.0, 0.02) << "it lies on the floor";

  const auto info = ros::topic::waitForMessage<sensor_msgs::CameraInfo>("/rgbd/camera_info", ros::Duration(60.0));
  const auto image = ros::topic::waitForMessage<sensor_msgs::Image>("/rgbd/image_raw", ros::Duration(60.0));
  const auto depth = ros::topic::waitForMessage<sensor_msgs::Image>("/rgbd/depth/image_raw", ros::Duration(60.0));
  ASSERT_TRUE(info && image && depth) << "the camera sends no images without a cloth";
  ASSERT_EQ(image->encoding, "bgr8");
  ASSERT_EQ(depth->encoding, "32FC1");
  ASSERT_EQ(image->width, 640u);
  // The nose mark: the red pixels (R high, G and B low); the camera looks at the neck from 1 m, so the mark is near
  // the image's middle, above it.
  long red = 0;
  double u_sum = 0.0, v_sum = 0.0;
  for (std::uint32_t v = 0; v < image->height; ++v) {
    for (std::uint32_t u = 0; u < image->width; ++u) {
      const std::uint8_t* p = &image->data[v * image->step + 3 * u];
      if (p[2] > 150 && p[1] < 80 && p[0] < 80) {
        ++red;
        u_sum += u;
        v_sum += v;
      }
    }
  }
  ASSERT_GT(red, 20) << "the nose mark is not seen";
  long blue = 0;
  for (std::uint32_t v = 0; v < image->height; ++v) {
    for (std::uint32_t u = 0; u < image->width; ++u) {
      const std::uint8_t* p = &image->data[v * image->step + 3 * u];
      blue += p[0] > 120 && p[0] > 2 * p[2] && p[0] > p[1] + 40 ? 1 : 0;
    }
  }
  EXPECT_GT(blue, 500) << "the scarf is not seen";
  const double u_mark = u_sum / red, v_mark = v_sum / red;
  EXPECT_LT(v_mark, info->K[5]) << "the nose is above the neck the camera looks at";
  EXPECT_LT(std::abs(u_mark - info->K[2]), 160.0);
  // At the image's centre: the neck (radius 0.045 m) the camera looks at, from where bullet_sim put the camera; the
  // top row: nothing (sky, no return).
  std::vector<double> eye, target;
  ASSERT_TRUE(ros::param::get("/bullet_sim/rgbd_eye", eye) && ros::param::get("/bullet_sim/rgbd_target", target));
  const double to_neck =
      std::sqrt(std::pow(eye[0] - target[0], 2) + std::pow(eye[1] - target[1], 2) + std::pow(eye[2] - target[2], 2)) -
      0.045;
  const auto at = [&](std::uint32_t v, std::uint32_t u) {
    float z;
    std::memcpy(&z, &depth->data[v * depth->step + 4 * u], sizeof(float));
    return z;
  };
  // (the nearest return to the centre: a random hole may fall on it).
  float centre = std::numeric_limits<float>::quiet_NaN();
  const int v0 = static_cast<int>(depth->height / 2), u0 = static_cast<int>(depth->width / 2);
  for (int r = 0; r < 6 && !std::isfinite(centre); ++r) {
    for (int dv = -r; dv <= r && !std::isfinite(centre); ++dv) {
      for (int du = -r; du <= r && !std::isfinite(centre); ++du) {
        centre = at(static_cast<std::uint32_t>(v0 + dv), static_cast<std::uint32_t>(u0 + du));
      }
    }
  }
  EXPECT_NEAR(centre, to_neck, 0.02);
  int returns_on_top_row = 0;
  for (std::uint32_t u = 0; u < depth->width; ++u) returns_on_top_row += std::isfinite(at(0, u)) ? 1 : 0;
  EXPECT_EQ(returns_on_top_row, 0);
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_scene");
  // Held for the whole run: without it each waitForMessage's own handle would start and, going, shut down the node
  // (ros::ok() false, ros::Time not advancing), and the waits for a moment of simulated time would not wait.
  ros::NodeHandle node;
  return RUN_ALL_TESTS();
}
