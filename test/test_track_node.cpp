// rostest (test/track.test): the left WAM follows the can bullet_sim carries along test/track_test_sim.yaml's path,
// seen by the RGB-D camera and tracked by object_tracker, in the arm's hosted controller (set_mode follow). This node
// relays the camera's topics to the tracker (and can stop them) and the tracked object to the follower (and can
// corrupt it), and checks against the simulator's truth: the tracking error, a lost target (the arm holds, still,
// and says why), a reacquired one, bad inputs (a NaN estimate, an unknown frame, a camera that stops: a hold with
// the reason on follow_state and /diagnostics), and a grasp on set_mode grasp.
#include "bimanual_skills/FollowerState.h"
#include "bimanual_skills/SetControlMode.h"
#include "bimanual_skills/TrackedObject.h"
#include "cli/pinned_numerics.hpp"

#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace {

/// What the relayed tracked object is turned into.
enum class Corruption { None, NaN, UnknownFrame };

struct Sample {
  double t, error, speed;
};

class Track : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    node_ = new ros::NodeHandle;
    spinner_ = new ros::AsyncSpinner(2);
    spinner_->start();
    ros::NodeHandle& n = *node_;
    image_out_ = n.advertise<sensor_msgs::Image>("/relay/rgbd/image_raw", 5);
    depth_out_ = n.advertise<sensor_msgs::Image>("/relay/rgbd/depth/image_raw", 5);
    info_out_ = n.advertise<sensor_msgs::CameraInfo>("/relay/rgbd/camera_info", 5);
    depth_info_out_ = n.advertise<sensor_msgs::CameraInfo>("/relay/rgbd/depth/camera_info", 5);
    target_out_ = n.advertise<bimanual_skills::TrackedObject>("/test/target", 10);
    subscribers_.push_back(n.subscribe("/rgbd/image_raw", 5, &Track::onImage));
    subscribers_.push_back(n.subscribe("/rgbd/depth/image_raw", 5, &Track::onDepth));
    subscribers_.push_back(n.subscribe("/rgbd/camera_info", 5, &Track::onInfo));
    subscribers_.push_back(n.subscribe("/rgbd/depth/camera_info", 5, &Track::onDepthInfo));
    subscribers_.push_back(n.subscribe("/object_tracker/object", 10, &Track::onTracked));
    subscribers_.push_back(n.subscribe("/bullet_sim/object_truth", 50, &Track::onTruth));
    subscribers_.push_back(n.subscribe("/left/follow_state", 50, &Track::onFollow));
    subscribers_.push_back(n.subscribe("/diagnostics", 50, &Track::onDiagnostics));
    // The scripted path's times are the simulation's: on the robot's clock from bullet_sim's time origin (0 on the
    // simulated clock, the wall's time of its start with hardware:=true).
    const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(60.0);
    while (!ros::param::get("/bullet_sim/time_origin", origin_) && ros::WallTime::now() < until) {
      ros::WallDuration(0.05).sleep();
    }
  }
  static void TearDownTestSuite() {
    spinner_->stop();
    subscribers_.clear();
    delete spinner_;
    delete node_;
  }

  // The camera's relay: on, or stopped (a camera that stops sending).
  static void onImage(const sensor_msgs::Image::ConstPtr& m) {
    if (!camera_on_) return;
    image_out_.publish(m);
    ++relayed_;
  }
  static void onDepth(const sensor_msgs::Image::ConstPtr& m) {
    if (camera_on_) depth_out_.publish(m);
  }
  static void onInfo(const sensor_msgs::CameraInfo::ConstPtr& m) {
    if (camera_on_) info_out_.publish(m);
  }
  static void onDepthInfo(const sensor_msgs::CameraInfo::ConstPtr& m) {
    if (camera_on_) depth_info_out_.publish(m);
  }
  static void onTracked(const bimanual_skills::TrackedObject::ConstPtr& message) {
    bimanual_skills::TrackedObject out = *message;
    const Corruption c = corruption_;
    if (c == Corruption::NaN) out.pose.pose.position.x = std::numeric_limits<double>::quiet_NaN();
    if (c == Corruption::UnknownFrame) out.header.frame_id = "rgbd_camera_optical_frame";
    target_out_.publish(out);
    const std::lock_guard<std::mutex> lock(mutex_);
    tracked_ = *message;
  }
  static void onTruth(const nav_msgs::Odometry::ConstPtr& m) {
    const std::lock_guard<std::mutex> lock(mutex_);
    const auto& p = m->pose.pose.position;
    const auto& v = m->twist.twist.linear;
    truth_[std::lround(m->header.stamp.toSec() * 1000.0)] = {p.x, p.y, p.z,
                                                             std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z)};
    if (truth_.size() > 20000) truth_.erase(truth_.begin());
  }
  static void onFollow(const bimanual_skills::FollowerState::ConstPtr& m) {
    const std::lock_guard<std::mutex> lock(mutex_);
    follow_ = *m;
    ++follow_count_;
    if (!m->target_stamp.isZero() && m->target_stamp != last_target_ && std::isfinite(m->latency)) {
      latencies_.push_back(m->latency);  // an estimate used for the first time: its frame's age at its first torque
      last_target_ = m->target_stamp;
    }
    // The tool against the object's true pre-grasp point (the grasp point 7 cm above its centre, 10 cm above that),
    // while following at the pre-grasp point (the goal 17 cm above the object's estimate).
    const auto it = truth_.lower_bound(std::lround(m->header.stamp.toSec() * 1000.0) - 20);
    if (m->phase != "following" || it == truth_.end()) return;
    const std::vector<double>& o = it->second;
    const double dz = m->goal.z - (o[2] + 0.17);
    const double e =
        std::sqrt(std::pow(m->tool.x - o[0], 2) + std::pow(m->tool.y - o[1], 2) + std::pow(m->tool.z - o[2] - 0.17, 2));
    if (std::abs(dz) < 0.01) samples_.push_back({m->header.stamp.toSec(), e, o[3]});
  }
  static void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
    const std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& status : m->status) {
      for (const auto& kv : status.values) {
        diagnostics_[status.name + "/" + kv.key] = kv.value;
        if (kv.key == "last second, medians") std::printf("%s: %s\n", status.name.c_str(), kv.value.c_str());
      }
      diagnostics_[status.name + "/(message)"] = status.message;
    }
  }

  static bool waitFor(const std::function<bool()>& condition, double wall_seconds) {
    const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(wall_seconds);
    while (ros::WallTime::now() < until) {
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        if (condition()) return true;
      }
      ros::WallDuration(0.02).sleep();
    }
    return false;
  }
  static std::string diagnostic(const std::string& key) {
    for (const auto& [name, value] : diagnostics_) {
      if (name.size() >= key.size() && name.compare(name.size() - key.size(), key.size(), key) == 0) return value;
    }
    return "";
  }
  static bool setMode(const std::string& mode) {
    bimanual_skills::SetControlMode call;
    call.request.mode = mode;
    return ros::service::call("/left/set_mode", call) && call.response.success;
  }

  static ros::NodeHandle* node_;
  static ros::AsyncSpinner* spinner_;
  static std::vector<ros::Subscriber> subscribers_;
  static ros::Publisher image_out_, depth_out_, info_out_, depth_info_out_, target_out_;
  static std::atomic<bool> camera_on_;
  static std::atomic<Corruption> corruption_;
  static std::mutex mutex_;
  static bimanual_skills::TrackedObject tracked_;
  static bimanual_skills::FollowerState follow_;
  static long follow_count_;
  static std::map<long, std::vector<double>> truth_;
  static std::vector<Sample> samples_;
  static std::map<std::string, std::string> diagnostics_;
  static std::vector<double> latencies_;
  static ros::Time last_target_;
  static std::atomic<long> relayed_;
  static double origin_;
};

ros::NodeHandle* Track::node_ = nullptr;
ros::AsyncSpinner* Track::spinner_ = nullptr;
std::vector<ros::Subscriber> Track::subscribers_;
ros::Publisher Track::image_out_, Track::depth_out_, Track::info_out_, Track::depth_info_out_, Track::target_out_;
std::atomic<bool> Track::camera_on_{true};
std::atomic<Corruption> Track::corruption_{Corruption::None};
std::mutex Track::mutex_;
bimanual_skills::TrackedObject Track::tracked_;
bimanual_skills::FollowerState Track::follow_;
long Track::follow_count_ = 0;
std::map<long, std::vector<double>> Track::truth_;
std::vector<Sample> Track::samples_;
std::map<std::string, std::string> Track::diagnostics_;
std::vector<double> Track::latencies_;
ros::Time Track::last_target_;
std::atomic<long> Track::relayed_{0};
double Track::origin_ = 0.0;

TEST_F(Track, FollowsTheCarriedCanWithinTwoCentimetres) {
  ASSERT_TRUE(waitFor([] { return follow_.following && follow_.phase == "following"; }, 60.0))
      << "the left arm never followed: " << follow_.phase << " " << follow_.reason;
  // The moves before the trip out of view (3-9.5 s); samples once the tool first got within 2 cm.
  ASSERT_TRUE(waitFor([] { return follow_.header.stamp.toSec() - origin_ > 9.5; }, 60.0));
  std::vector<double> errors;
  double fastest = 0.0;
  bool reached = false;
  for (const Sample& s : samples_) {
    reached = reached || s.error < 0.02;
    if (!reached || s.t - origin_ > 9.5) continue;
    errors.push_back(s.error);
    fastest = std::max(fastest, s.speed);
  }
  // Half a second of the follower's 100 Hz states at least: on a machine 2.5 times slower the tool first got
  // within 2 cm at 8.8 s (65 samples), following as closely after.
  ASSERT_GT(errors.size(), 50u) << "too few samples while following";
  // The latency from a camera frame's stamp to the first torque computed from its estimate (the follower's state
  // publishes at 100 Hz: estimates it did not show are not counted), and frames the tracker did not get.
  std::vector<double> latency;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    latency = latencies_;
  }
  std::sort(latency.begin(), latency.end());
  ASSERT_GT(latency.size(), 50u);
  const double median = latency[latency.size() / 2], p99 = latency[latency.size() * 99 / 100];
  std::printf(
      "latency from a frame's stamp to its first torque: %zu estimates, median %.1f ms, p99 %.1f ms, max "
      "%.1f ms; frames relayed %ld, received by the tracker %u (dropped %ld)\n",
      latency.size(), 1e3 * median, 1e3 * p99, 1e3 * latency.back(), relayed_.load(), tracked_.frames,
      relayed_.load() - static_cast<long>(tracked_.frames));
  std::sort(errors.begin(), errors.end());
  const double p95 = errors[errors.size() * 95 / 100];
  std::printf("following: %zu samples at up to %.3f m/s, error p95 %.1f mm, max %.1f mm\n", errors.size(), fastest,
              1e3 * p95, 1e3 * errors.back());
  EXPECT_GT(fastest, 0.1);
  // Within 2 cm, or, where the frames reach the torques late (hardware:=true: 0.11-0.15 s median on 2 shared cores),
  // within 8 mm of the lag that latency gives at the can's top speed: the follower's own error, not the pipeline's.
  const double allowed = std::max(0.02, 0.008 + fastest * median);
  EXPECT_LT(p95, allowed) << "following error p95 " << p95 << " m, latency median " << median << " s";
  // A speed target is measured, not asserted by a timed test (the figures: RESULTS, "A robot that behaves like
  // hardware"): on 2 shared cores this rostest's p99 read 0.10-0.20 s with every process of the
  // robot beside it. Half a second of latency is what a broken pipeline (a queue that grows) gives.
  EXPECT_LT(p99, 0.5) << "frames reach the torques half a second late: the pipeline queues";
}

TEST_F(Track, HoldsStillWhenTheCanLeavesTheViewAndFollowsItWhenItComesBack) {
  ASSERT_TRUE(waitFor([] { return !tracked_.tracking && tracked_.frames > 0; }, 40.0)) << "never lost";
  std::printf("lost at t = %.2f s: %s\n", tracked_.header.stamp.toSec() - origin_, tracked_.state.c_str());
  EXPECT_NE(tracked_.state.find("lost"), std::string::npos) << tracked_.state;
  ASSERT_TRUE(waitFor([] { return follow_.phase == "holding"; }, 5.0)) << follow_.phase;
  EXPECT_NE(follow_.reason.find("not tracked"), std::string::npos) << follow_.reason;
  // Still within a second: the tool moves less than 2 mm over the next 0.5 s of the clock.
  ros::WallDuration(1.5).sleep();
  bimanual_skills::FollowerState before;
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    before = follow_;
  }
  ASSERT_TRUE(waitFor([&] { return follow_.header.stamp.toSec() > before.header.stamp.toSec() + 0.5; }, 10.0));
  const double moved =
      std::hypot(follow_.tool.x - before.tool.x, follow_.tool.y - before.tool.y, follow_.tool.z - before.tool.z);
  EXPECT_EQ(follow_.phase, "holding");
  EXPECT_LT(moved, 0.002) << "the arm moved while the target was lost";
  ASSERT_TRUE(waitFor([] { return tracked_.tracking; }, 40.0)) << "never reacquired: " << tracked_.state;
  std::printf("reacquired at t = %.2f s\n", tracked_.header.stamp.toSec() - origin_);
  ASSERT_TRUE(waitFor([] { return follow_.phase == "following"; }, 5.0)) << follow_.phase << " " << follow_.reason;
  const double back = follow_.header.stamp.toSec();
  ASSERT_TRUE(waitFor([] { return follow_.error < 0.02; }, 20.0)) << "not back at the pre-grasp point";
  std::printf("back within 2 cm %.2f s after following again\n", follow_.header.stamp.toSec() - back);
}

TEST_F(Track, HoldsWithTheReasonOnANaNEstimateAnUnknownFrameAndAStoppedCamera) {
  const auto holdsBecause = [](const std::string& why) {
    return waitFor([&] { return follow_.phase == "holding" && follow_.reason.find(why) != std::string::npos; }, 5.0);
  };
  const auto follows = [] { return waitFor([] { return follow_.phase == "following"; }, 10.0); };
  corruption_ = Corruption::NaN;
  EXPECT_TRUE(holdsBecause("non-finite")) << follow_.phase << ": " << follow_.reason;
  EXPECT_TRUE(waitFor([] { return diagnostic("following").find("non-finite") != std::string::npos; }, 5.0))
      << diagnostic("following");
  corruption_ = Corruption::None;
  EXPECT_TRUE(follows()) << follow_.reason;
  corruption_ = Corruption::UnknownFrame;
  EXPECT_TRUE(holdsBecause("frame 'rgbd_camera_optical_frame'")) << follow_.phase << ": " << follow_.reason;
  EXPECT_TRUE(
      waitFor([] { return diagnostic("following").find("rgbd_camera_optical_frame") != std::string::npos; }, 5.0))
      << diagnostic("following");
  corruption_ = Corruption::None;
  EXPECT_TRUE(follows()) << follow_.reason;
  camera_on_ = false;
  EXPECT_TRUE(holdsBecause("no camera frame")) << follow_.phase << ": " << follow_.reason;
  EXPECT_TRUE(
      waitFor([] { return diagnostic("object_tracker/(message)").find("no camera frame") != std::string::npos; }, 5.0))
      << diagnostic("object_tracker/(message)");
  camera_on_ = true;
  EXPECT_TRUE(follows()) << follow_.reason;
}

TEST_F(Track, GraspsTheCanOnSetModeGrasp) {
  ASSERT_TRUE(setMode("grasp"));
  ASSERT_TRUE(waitFor([] { return follow_.phase == "holding the object"; }, 90.0))
      << "not grasped: " << follow_.phase << " " << follow_.reason;
  std::printf("grasped at t = %.2f s\n", follow_.header.stamp.toSec() - origin_);
  EXPECT_TRUE(waitFor([] { return diagnostic("gripper").find("grasped the object") != std::string::npos; }, 5.0))
      << diagnostic("gripper");
  // Held, the can moves with the tool: its truth stays under the tool.
  ros::WallDuration(1.0).sleep();
  const std::lock_guard<std::mutex> lock(mutex_);
  const std::vector<double>& can = truth_.rbegin()->second;
  EXPECT_LT(std::hypot(can[0] - follow_.tool.x, can[1] - follow_.tool.y), 0.02);
  EXPECT_FALSE(setMode("fly")) << "an unknown mode accepted";
}

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_track");
  return RUN_ALL_TESTS();
}
