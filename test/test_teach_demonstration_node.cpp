// rostest (test/teach_demonstration.test): a scripted person teaches the fold through teach_demonstration.
// 1. Saving before anything was recorded answers failure with the reason.
// 2. Grasp, record, both hands on a folding arc (half a circle over the cloth towards the near edge), release, save:
//    the answer names the files; each DMP file loads, starts at its tool's corner and ends near its hand's last
//    target, its duration is the taught movement's; the fold task runs from them (Ok, a fold quality measured).
// 3. A hand target that is not finite, or in another frame, is refused: the node is still there and answers.
#include "bimanual_skills/primitives/dmp_yaml.hpp"
#include "bimanual_skills/rollout/fold_learning.hpp"
#include "cli/pinned_numerics.hpp"

#include <geometry_msgs/PointStamped.h>
#include <ros/package.h>
#include <ros/ros.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>

namespace bs = bimanual_skills;

namespace {

template <class Service>
bool call(const std::string& name, Service& service) {
  if (!ros::service::waitForService(name, ros::Duration(60.0))) return false;
  return ros::service::call(name, service);
}

/// The corners the tools start at (config/robots/wam_fold_start.yaml: the cloth's far corners).
const Eigen::Vector3d kCorner[2] = {Eigen::Vector3d(0.79, 0.29, 0.165), Eigen::Vector3d(0.79, -0.29, 0.165)};

/// The hands' folding arc at s in [0, 1] (minimum jerk): half a circle of radius 0.25 m over the cloth.
Eigen::Vector3d hand(int arm, double s) {
  const double m = s * s * s * (10.0 + s * (-15.0 + 6.0 * s)), angle = M_PI * m;
  const Eigen::Vector3d c = kCorner[arm];
  return {c.x() - 0.25 + 0.25 * std::cos(angle), c.y(), c.z() + 0.12 * std::sin(angle) + 0.02 * m};
}

}  // namespace

TEST(TeachDemonstration, SavingBeforeRecordingIsRefused) {
  std_srvs::Trigger save;
  ASSERT_TRUE(call("/teach_demonstration/save", save));
  EXPECT_FALSE(save.response.success);
  EXPECT_NE(save.response.message.find("nothing was taught"), std::string::npos) << save.response.message;
}

TEST(TeachDemonstration, APersonTeachesTheFold) {
  ros::NodeHandle node;
  ros::Publisher hands[2] = {node.advertise<geometry_msgs::PointStamped>("/left/hand_target", 10),
                             node.advertise<geometry_msgs::PointStamped>("/right/hand_target", 10)};
  // Targets published before teach_demonstration is connected are lost (the arm would skip the arc), and before
  // the first /clock the robot's time reads 0.
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(30.0);
  while ((hands[0].getNumSubscribers() == 0 || hands[1].getNumSubscribers() == 0) && ros::WallTime::now() < deadline)
    ros::WallDuration(0.01).sleep();
  ASSERT_GT(hands[0].getNumSubscribers() * hands[1].getNumSubscribers(), 0U) << "teach_demonstration never subscribed";
  ASSERT_TRUE(ros::Time::waitForValid(ros::WallDuration(30.0))) << "no /clock";
  std_srvs::SetBool grasp;
  grasp.request.data = true;
  ASSERT_TRUE(call("/teach_demonstration/grasp", grasp));
  EXPECT_TRUE(grasp.response.success) << grasp.response.message;
  std_srvs::Trigger start;
  ASSERT_TRUE(call("/teach_demonstration/start", start));
  ASSERT_TRUE(start.response.success);
  // 4 s of the robot's clock along the arc, a target every 20 ms.
  const double duration = 4.0;
  const ros::Time t0 = ros::Time::now();
  for (double s = 0.0; s <= 1.0 && ros::ok();) {
    s = std::min(1.0, (ros::Time::now() - t0).toSec() / duration);
    for (int arm = 0; arm < 2; ++arm) {
      geometry_msgs::PointStamped target;
      target.header.frame_id = "world";
      const Eigen::Vector3d p = hand(arm, s);
      target.point.x = p.x();
      target.point.y = p.y();
      target.point.z = p.z();
      hands[arm].publish(target);
    }
    if (s >= 1.0) break;
    ros::WallDuration(0.01).sleep();
  }
  ros::Duration(1.0).sleep();  // the arms come to rest
  grasp.request.data = false;
  ASSERT_TRUE(call("/teach_demonstration/grasp", grasp));
  EXPECT_TRUE(grasp.response.success) << grasp.response.message;
  ros::Duration(0.5).sleep();
  std_srvs::Trigger save;
  ASSERT_TRUE(call("/teach_demonstration/save", save));
  ASSERT_TRUE(save.response.success) << save.response.message;
  std::printf("teach_demonstration: %s\n", save.response.message.c_str());

  std::string out;
  ASSERT_TRUE(ros::param::get("/teach_demonstration/out", out));
  std::vector<std::string> files;
  for (int arm = 0; arm < 2; ++arm) {
    const std::string file = out + (arm == 0 ? "/taught_left.yaml" : "/taught_right.yaml");
    ASSERT_TRUE(std::filesystem::exists(file)) << file;
    files.push_back(file);
    const bs::primitives::CartesianDmp dmp = bs::primitives::loadCartesianDmp(file);
    EXPECT_EQ(dmp.parameters().kernels, 20);
    EXPECT_GT(dmp.duration(), 2.0);
    EXPECT_LT(dmp.duration(), duration + 1.5);
    EXPECT_LT((dmp.start().position - kCorner[arm]).norm(), 0.03) << "arm " << arm;
    EXPECT_LT((dmp.goal().position - hand(arm, 1.0)).norm(), 0.04) << "arm " << arm;
  }
  bs::rollout::FoldLearningConfig config = bs::rollout::FoldLearningConfig::fromYamlFile(
      ros::package::getPath("bimanual_skills") + "/config/fold_demo.yaml");
  config.task.demonstration_files = files;
  ros::param::get("/teach_demonstration/robot", config.task.robot);  // the taught pair's robot file ("" the WAM's)
  bs::tasks::ClothFoldTask task(config.task);
  const bs::tasks::FoldRollout rollout = task.run(task.demonstrationParameters());
  EXPECT_EQ(rollout.outcome, bs::tasks::FoldOutcome::Ok) << rollout.reason;
  std::printf("the fold task from the taught demonstration: q = %.3f\n", rollout.fold.q);
  EXPECT_GT(rollout.fold.q, 0.2);  // it folds
}

TEST(TeachDemonstration, BadHandTargetsAreRefused) {
  ros::NodeHandle node;
  ros::Publisher hand_pub = node.advertise<geometry_msgs::PointStamped>("/left/hand_target", 10);
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(10.0);
  while (hand_pub.getNumSubscribers() == 0 && ros::WallTime::now() < deadline) ros::WallDuration(0.05).sleep();
  geometry_msgs::PointStamped target;
  target.header.frame_id = "world";
  target.point.x = std::numeric_limits<double>::quiet_NaN();
  hand_pub.publish(target);
  target.header.frame_id = "no_such_frame";
  target.point.x = 0.5;
  hand_pub.publish(target);
  ros::Duration(0.5).sleep();
  std_srvs::Trigger start;
  ASSERT_TRUE(call("/teach_demonstration/start", start));  // still answering
  EXPECT_TRUE(start.response.success);
}

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_teach_demonstration");
  ros::NodeHandle keep_alive;
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
