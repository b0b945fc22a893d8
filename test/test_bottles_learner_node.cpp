// rostest (test/bottles_learner.test): bottles.launch learning the bottle task headless (REPS and DREPS, 2 updates x 4
// rollouts each). Checks that the table and line, the two bottles, the rollouts' tool paths and the arms' joint
// states (the played policy moving the right arm) reach their topics, and that the results directory gets one
// epochs.csv row per epoch, every rollout with the task's terms, summary.json, final_paths.csv and the files that
// lock it to the task. Then SIGKILLs the second learner (the same learning into another directory) mid-run, starts it
// again, and checks that it takes the rollouts on disk and ends with the same epochs to the last digit.
#include "cli/pinned_numerics.hpp"
#include "node_pid.hpp"

#include "ros_wait.hpp"

#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <visualization_msgs/MarkerArray.h>

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <string>

namespace {

std::string param(const std::string& name) {
  std::string value;
  ros::param::get(name, value);
  return value;
}

int lines(const std::string& path) {
  std::ifstream in(path);
  return static_cast<int>(std::count(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>(), '\n'));
}

std::string text(const std::string& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// 2 algorithms x 3 epochs x (the noise-free policy + 4 samples), and the header.
constexpr int kRolloutLines = 31;
constexpr int kEpochLines = 7;

}  // namespace

TEST(BottlesLearnerNode, PublishesTheLearningAndWritesTheResults) {
  ros::NodeHandle node;
  std::size_t scene = 0, bottles = 0, joint_names = 0;
  int paths = 0, joints = 0;
  std::map<double, int> elbow;  // the right arm's 4th joint over the played motion
  const auto scene_sub = node.subscribe<visualization_msgs::MarkerArray>(
      "/bottles_learner/scene", 10,
      [&](const visualization_msgs::MarkerArrayConstPtr& m) { scene = m->markers.size(); });
  const auto bottle_sub = node.subscribe<visualization_msgs::MarkerArray>(
      "/bottles_learner/bottles", 10,
      [&](const visualization_msgs::MarkerArrayConstPtr& m) { bottles = m->markers.size(); });
  const auto path_sub = node.subscribe<visualization_msgs::MarkerArray>(
      "/bottles_learner/tool_paths", 10, [&](const visualization_msgs::MarkerArrayConstPtr& m) {
        paths = std::max(paths, static_cast<int>(m->markers.size()));
      });
  const auto joint_sub =
      node.subscribe<sensor_msgs::JointState>("/joint_states", 100, [&](const sensor_msgs::JointStateConstPtr& m) {
        ++joints;
        joint_names = m->name.size();
        for (std::size_t j = 0; j < m->name.size(); ++j) {
          if (m->name[j] == "right_wam_joint4") ++elbow[m->position[j]];
        }
      });
  // The second learner is killed a third of the way through its learning.
  const std::string killed = param("/bottles_killed/out");
  const int pid = bimanual_skills::test::nodePid("/bottles_killed");
  ASSERT_GT(pid, 0);
  ASSERT_TRUE(bimanual_skills::test::spinUntil([&] { return lines(killed + "/rollouts.csv") >= 10; }, 120.0));
  ASSERT_EQ(kill(pid, SIGKILL), 0);
  bimanual_skills::test::spinUntil([] { return false; }, 0.5);
  const int before = lines(killed + "/rollouts.csv") - 1;
  ASSERT_LT(before, kRolloutLines - 1) << "the learner ended before it was killed";

  const std::string out = param("/bottles_learner/out");
  ASSERT_TRUE(
      bimanual_skills::test::spinUntil([&] { return std::filesystem::exists(out + "/final_paths.csv"); }, 240.0))
      << "no results in " << out;
  // The node plays the best final policy now: a few seconds of its motion.
  bimanual_skills::test::spinUntil([] { return false; }, 3.0);
  EXPECT_EQ(scene, 2u) << "the table and the line";
  EXPECT_EQ(bottles, 2u);
  EXPECT_GE(paths, 5) << "the last rollouts' tool paths and the policy's";
  EXPECT_GT(joints, 20);
  EXPECT_EQ(joint_names, 14u) << "both arms";
  EXPECT_GT(elbow.size(), 10u) << "the played motion moves the right arm";
  EXPECT_EQ(lines(out + "/rollouts.csv"), kRolloutLines);
  EXPECT_EQ(lines(out + "/epochs.csv"), kEpochLines);
  for (const char* file : {"summary.json", "rollout_parameters.csv", "task.yaml", "world.txt"}) {
    EXPECT_TRUE(std::filesystem::exists(out + "/" + file)) << file;
  }
  const std::string json = text(out + "/summary.json");
  EXPECT_NE(json.find("\"policy_satisfactory\""), std::string::npos);
  EXPECT_NE(json.find("\"rollout_mean_bottles_down\""), std::string::npos);
  EXPECT_NE(json.find("\"DREPS\""), std::string::npos);
  const std::string final_paths = text(out + "/final_paths.csv");
  EXPECT_NE(final_paths.find("\nREPS,0,Ok,"), std::string::npos);
  EXPECT_NE(final_paths.find("\nDREPS,0,Ok,"), std::string::npos);

  // The second learner, started again after its kill, resumes to the same learning.
  const std::string log = killed + ".log";
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const std::string out_arg = "_out:=" + killed;
    std::freopen(log.c_str(), "w", stdout);
    execl(BOTTLES_LEARNER, BOTTLES_LEARNER, "__name:=bottles_resumed", out_arg.c_str(), "_updates:=2", "_rollouts:=4",
          "_jobs:=2", static_cast<char*>(nullptr));
    _exit(127);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << text(log);
  EXPECT_NE(text(log).find("taken from"), std::string::npos) << text(log);
  EXPECT_EQ(lines(killed + "/rollouts.csv"), kRolloutLines) << "nothing lost, nothing doubled";
  EXPECT_EQ(text(killed + "/epochs.csv"), text(out + "/epochs.csv"));
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_bottles_learner_node");
  return RUN_ALL_TESTS();
}
