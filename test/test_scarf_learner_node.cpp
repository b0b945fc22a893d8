// rostest (test/scarf_learner.test): scarf_learner learning a tiny scarf placement headless. Checks that the
// mannequin, every rollout's scarf, tool path, camera image (with its CameraInfo, in a frame on tf) and the arm's
// joint states reach their topics, and that the results directory gets summary.json (one row per epoch), the
// rollouts with the task's terms, the camera's measures and the pictures (initial, final, filmstrip), and that the
// plot script draws the learning curve, the camera views and the tables from it.
#include "cli/pinned_numerics.hpp"
#include "ros_wait.hpp"

#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/JointState.h>
#include <tf2_msgs/TFMessage.h>
#include <visualization_msgs/Marker.h>
#include <visualization_msgs/MarkerArray.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace {

std::string outDir() {
  std::string out;
  ros::param::get("/scarf_learner/out", out);
  return out;
}

int lines(const std::string& path) {
  std::ifstream in(path);
  return static_cast<int>(std::count(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>(), '\n'));
}

}  // namespace

TEST(ScarfLearnerNode, PublishesEachRolloutAndWritesTheResults) {
  ros::NodeHandle node;
  int images = 0, infos = 0, scarves = 0, paths = 0, joints = 0;
  std::size_t obstacles = 0, joint_names = 0;
  std::string image_frame;
  geometry_msgs::TransformStamped camera_frame;
  const auto image_sub = node.subscribe<sensor_msgs::Image>("/scarf_learner/camera/image_raw", 10,
                                                            [&](const sensor_msgs::ImageConstPtr& m) {
                                                              ++images;
                                                              image_frame = m->header.frame_id;
                                                            });
  const auto info_sub = node.subscribe<sensor_msgs::CameraInfo>(
      "/scarf_learner/camera/camera_info", 10,
      [&](const sensor_msgs::CameraInfoConstPtr& m) { infos += m->K[0] > 0.0 ? 1 : 0; });
  const auto tf_sub = node.subscribe<tf2_msgs::TFMessage>("/tf_static", 10, [&](const tf2_msgs::TFMessageConstPtr& m) {
    for (const auto& t : m->transforms) {
      if (t.child_frame_id == "scarf_camera") camera_frame = t;
    }
  });
  const auto scene_sub = node.subscribe<visualization_msgs::MarkerArray>(
      "/scarf_learner/scene", 10,
      [&](const visualization_msgs::MarkerArrayConstPtr& m) { obstacles = m->markers.size(); });
  const auto scarf_sub = node.subscribe<visualization_msgs::Marker>(
      "/scarf_learner/scarf", 10,
      [&](const visualization_msgs::MarkerConstPtr& m) { scarves += m->points.empty() ? 0 : 1; });
  const auto path_sub = node.subscribe<visualization_msgs::MarkerArray>(
      "/scarf_learner/tool_paths", 10, [&](const visualization_msgs::MarkerArrayConstPtr&) { ++paths; });
  const auto joint_sub =
      node.subscribe<sensor_msgs::JointState>("/joint_states", 10, [&](const sensor_msgs::JointStateConstPtr& m) {
        ++joints;
        joint_names = m->name.size();
      });
  // filmstrip.png is written last; then a second more of messages.
  bimanual_skills::test::spinUntil([&] { return std::filesystem::exists(outDir() + "/filmstrip.png"); }, 200.0);
  bimanual_skills::test::spinUntil([] { return false; }, 1.0);
  ASSERT_TRUE(std::filesystem::exists(outDir() + "/filmstrip.png")) << "no results in " << outDir();
  EXPECT_EQ(obstacles, 6u) << "floor, torso, shoulders, neck, head, nose mark";
  EXPECT_GT(scarves, 0);
  EXPECT_GT(paths, 0);
  EXPECT_GT(images, 0);
  EXPECT_GT(infos, 0);
  EXPECT_EQ(image_frame, "scarf_camera");
  EXPECT_EQ(camera_frame.header.frame_id, "world") << "the camera's frame is on /tf_static";
  EXPECT_GT(joints, 0);
  EXPECT_EQ(joint_names, 14u) << "both arms";
  // 2 epochs x (the noise-free policy + 3 samples), and the header.
  EXPECT_EQ(lines(outDir() + "/rollouts.csv"), 9);
  EXPECT_EQ(lines(outDir() + "/epochs.csv"), 3);
  EXPECT_EQ(lines(outDir() + "/camera.csv"), 3) << "the demonstration and the run's final policy";
  for (const char* file : {"summary.json", "rollout_parameters.csv", "initial.png", "final_runs/PI2-CMA_run_0.png",
                           "task.txt", "world.txt"}) {
    EXPECT_TRUE(std::filesystem::exists(outDir() + "/" + file)) << file;
  }
  std::ifstream summary(outDir() + "/summary.json");
  const std::string json{std::istreambuf_iterator<char>(summary), std::istreambuf_iterator<char>()};
  EXPECT_NE(json.find("\"policy_cost\""), std::string::npos);
  EXPECT_NE(json.find("\"rollout_mean_c_torque\""), std::string::npos);
  // The plot script draws Figs. 4.7 and 4.8 and the tables from the directory.
  ASSERT_EQ(
      std::system(("/usr/bin/python3 " + std::string(PLOT_SCARF_LEARNING) + " " + outDir() + " > /dev/null").c_str()),
      0);
  for (const char* file : {"learning_curve.png", "camera_views.png", "tables.md"}) {
    EXPECT_TRUE(std::filesystem::exists(outDir() + "/" + file)) << file;
  }
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_scarf_learner_node");
  return RUN_ALL_TESTS();
}
