// rostest (test/fold_learner.test): fold_learner learning a tiny fold headless. Checks that every rollout's camera
// images, cloth mesh and tool paths reach their topics, that the results directory gets summary.json, the top-down
// images and rollouts.csv, and that best_rollout.bag holds a replay: joint states of both arms, cloth frames, the
// camera image. The images come with their CameraInfo, in a frame on tf. ~reward:=goal replaces the learning file's
// reward setting, and the directory records it.
#include "cli/pinned_numerics.hpp"
#include "ros_wait.hpp"

#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/JointState.h>
#include <tf2_msgs/TFMessage.h>
#include <visualization_msgs/Marker.h>
#include <visualization_msgs/MarkerArray.h>

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace {

std::string outDir() {
  std::string out;
  ros::param::get("/fold_learner/out", out);  // the learner's own parameter: one directory per launch
  return out;
}

}  // namespace

TEST(FoldLearnerNode, PublishesEachRolloutAndWritesTheResults) {
  ros::NodeHandle node;
  int images = 0, depths = 0, cloths = 0, paths = 0;
  sensor_msgs::Image last_image;
  visualization_msgs::Marker last_cloth;
  const auto image_sub = node.subscribe<sensor_msgs::Image>("/fold_learner/camera/image_raw", 10,
                                                            [&](const sensor_msgs::ImageConstPtr& m) {
                                                              ++images;
                                                              last_image = *m;
                                                            });
  sensor_msgs::CameraInfo last_info;
  int infos = 0;
  const auto info_sub = node.subscribe<sensor_msgs::CameraInfo>("/fold_learner/camera/camera_info", 10,
                                                                [&](const sensor_msgs::CameraInfoConstPtr& m) {
                                                                  ++infos;
                                                                  last_info = *m;
                                                                });
  geometry_msgs::TransformStamped camera_frame;
  const auto tf_sub = node.subscribe<tf2_msgs::TFMessage>("/tf_static", 10, [&](const tf2_msgs::TFMessageConstPtr& m) {
    for (const auto& t : m->transforms) {
      if (t.child_frame_id == "top_down_camera") camera_frame = t;
    }
  });
  const auto depth_sub = node.subscribe<sensor_msgs::Image>("/fold_learner/camera/depth/image_raw", 10,
                                                            [&](const sensor_msgs::ImageConstPtr&) { ++depths; });
  const auto cloth_sub = node.subscribe<visualization_msgs::Marker>("/fold_learner/cloth", 10,
                                                                    [&](const visualization_msgs::MarkerConstPtr& m) {
                                                                      ++cloths;
                                                                      last_cloth = *m;
                                                                    });
  const auto path_sub = node.subscribe<visualization_msgs::MarkerArray>(
      "/fold_learner/tool_paths", 10, [&](const visualization_msgs::MarkerArrayConstPtr&) { ++paths; });
  const std::string bag_path = outDir() + "/best_rollout.bag";
  // summary.json is written last, after the images and the bag.
  bimanual_skills::test::spinUntil(
      [&] {
        return std::filesystem::exists(bag_path) && std::filesystem::exists(outDir() + "/summary.json") && images > 0;
      },
      200.0);
  ros::WallDuration(2.0).sleep();  // the bag is closed after the file appears
  ros::spinOnce();
  EXPECT_GT(images, 0);
  EXPECT_GT(depths, 0);
  EXPECT_GT(cloths, 0);
  EXPECT_GT(paths, 0);
  EXPECT_EQ(last_image.encoding, "bgr8");
  EXPECT_EQ(last_image.width, 320u);
  EXPECT_EQ(last_image.height, 240u);
  EXPECT_EQ(last_image.header.frame_id, "top_down_camera");
  EXPECT_GT(infos, 0);
  EXPECT_EQ(last_info.width, 320u);
  EXPECT_EQ(last_info.height, 240u);
  EXPECT_EQ(last_info.header.frame_id, "top_down_camera");
  EXPECT_NEAR(last_info.P[0], 320.0, 1e-9);  // 1 / pixel size (3.125 mm)
  EXPECT_EQ(last_info.P[11], 1.0);           // orthographic: the affine camera's last row
  EXPECT_EQ(camera_frame.header.frame_id, "world");
  EXPECT_NEAR(camera_frame.transform.translation.z, 1.65, 1e-9);  // 1.5 m above the table top (0.15 m)
  EXPECT_EQ(last_cloth.type, visualization_msgs::Marker::TRIANGLE_LIST);
  EXPECT_GT(last_cloth.points.size(), 300u);
  for (const char* file :
       {"summary.json", "epochs.csv", "rollouts.csv", "initial.png", "final.png", "initial_frames.csv",
        "final_frames.csv", "final_top_5.png", "final_runs/IDR-DMP_CMU_run_0.png"}) {
    EXPECT_TRUE(std::filesystem::exists(outDir() + "/" + file)) << file;
  }
  // make demo's pictures: the filmstrips and animations of the initial and the final policy.
  ASSERT_EQ(
      std::system(("/usr/bin/python3 " + std::string(PLOT_FOLD_LEARNING) + " " + outDir() + " > /dev/null").c_str()),
      0);
  for (const char* file : {"learning_curve.png", "filmstrip_initial.png", "filmstrip_final.png", "initial.gif",
                           "final.gif", "final_runs.png"}) {
    EXPECT_TRUE(std::filesystem::exists(outDir() + "/" + file)) << file;
  }
  // An ablation beside it (here the run itself): a row per ablation in table75.md; a malformed one is refused.
  const std::string plot = "/usr/bin/python3 " + std::string(PLOT_FOLD_LEARNING) + " " + outDir();
  ASSERT_EQ(std::system((plot + " --beside 'the same run=" + outDir() + "' > /dev/null 2>&1").c_str()), 0);
  std::ifstream table_file(outDir() + "/table75.md");
  const std::string table((std::istreambuf_iterator<char>(table_file)), std::istreambuf_iterator<char>());
  EXPECT_NE(table.find(", the same run | 1 |"), std::string::npos) << table;
  EXPECT_NE(std::system((plot + " --beside nolabel > /dev/null 2>&1").c_str()), 0);
  std::ifstream summary_file(outDir() + "/summary.json");
  const std::string summary((std::istreambuf_iterator<char>(summary_file)), std::istreambuf_iterator<char>());
  EXPECT_NE(summary.find("\"fold_quality\""), std::string::npos);
  EXPECT_NE(summary.find("\"final_policy_fold_quality\""), std::string::npos);
  EXPECT_NE(summary.find("\"reward_setting\": \"goal\""), std::string::npos);
  std::ifstream reward_file(outDir() + "/reward.txt");
  std::string setting;
  std::getline(reward_file, setting);
  EXPECT_EQ(setting, "setting goal");
  std::ifstream rollouts(outDir() + "/rollouts.csv");
  int lines = 0;
  for (std::string line; std::getline(rollouts, line);) ++lines;
  EXPECT_EQ(lines, 1 + 2 * 3 + 2);  // header, 2 epochs x 3 samples, 2 mean-policy rollouts

  ASSERT_TRUE(std::filesystem::exists(bag_path));
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  int states = 0, frames = 0, bag_images = 0;
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    if (const auto js = m.instantiate<sensor_msgs::JointState>()) {
      ++states;
      EXPECT_EQ(js->position.size(), 14u);
      EXPECT_EQ(js->name.size(), 14u);
    }
    if (m.getTopic() == "/fold_learner/cloth") ++frames;
    if (m.getTopic() == "/fold_learner/camera/image_raw") ++bag_images;
  }
  EXPECT_GT(states, 100);  // 50 Hz over the rollout
  EXPECT_GT(frames, 40);   // 20 Hz
  EXPECT_EQ(bag_images, 1);
  bag.close();
  std::filesystem::remove_all(outDir());
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_fold_learner_node");
  return RUN_ALL_TESTS();
}
