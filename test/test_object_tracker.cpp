// The tracked object (thesis Sec. 4.3.2): rendered 30 Hz frames of the can carried along seeded paths, measured and
// filtered, against the path's true centre; lost when it leaves the view and found again when it comes back; the
// reasons for a camera that stops, a frame that cannot be used, duplicate, reordered and reset stamps.
#include "bimanual_skills/sim/object_path.hpp"
#include "bimanual_skills/sim/sim_config.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "bimanual_skills/tracking/object_tracker.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>

namespace bs = bimanual_skills;
using bs::tracking::ObjectTracker;
using bs::tracking::TrackedState;
using bs::tracking::TrackReason;

namespace {

class Scene {
 public:
  explicit Scene(std::uint32_t seed)
      : config_(load()), camera_(bs::tasks::rendererFor(config_), bs::tasks::rgbdCameraFor(config_)), rng_(seed) {
    object_ = camera_.addMovingSolid(bs::tasks::sceneSolid(config_.object.body));
    config_.object.path.seed = seed;
    path_ = std::make_unique<bs::sim::ObjectPath>(config_.object.path);
  }

  static bs::sim::SimConfig load() {
    return bs::sim::SimConfig::fromYamlFile(std::string(BIMANUAL_SKILLS_SOURCE_DIR) + "/config/track_sim.yaml");
  }

  bs::tracking::ObjectTrackerConfig trackerConfig() const {
    bs::tracking::ObjectTrackerConfig config;
    config.locator.shape = bs::tasks::sceneSolid(config_.object.body);
    return config;
  }

  /// The frame at t with the object where its path has it.
  void render(double t) {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = path_->at(t).position;
    camera_.setMovingPose(object_, pose);
    (void)camera_.render(Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xi(3, 0), rng_);
  }
  const TrackedState& frame(ObjectTracker& tracker, double t) {
    render(t);
    return tracker.frame(t, camera_.bgr(), camera_.depth(), camera_.camera());
  }

  const bs::sim::ObjectPath& path() const { return *path_; }
  bs::vision::PerspectiveRenderer& camera() { return camera_; }

 private:
  bs::sim::SimConfig config_;
  bs::vision::PerspectiveRenderer camera_;
  std::mt19937 rng_;
  int object_ = 0;
  std::unique_ptr<bs::sim::ObjectPath> path_;
};

}  // namespace

TEST(ObjectTracker, FollowsTheCanLosesItOutOfViewAndFindsItAgain) {
  Scene scene(3);
  ObjectTracker tracker(scene.trackerConfig());
  double sum = 0.0, worst = 0.0;
  int in_view = 0, tracked_in_view = 0, out_of_view = 0, lost_out_of_view = 0, reacquired = 0;
  bool was_lost = false;
  for (double t = 0.0; t < 40.0; t += 1.0 / 30.0) {
    const TrackedState& s = scene.frame(tracker, t);
    const Eigen::Vector3d truth = scene.path().at(t).position;
    Eigen::Vector3d uvz;
    ASSERT_TRUE(scene.camera().camera().project(truth, uvz));
    // Wholly in view (30 px inside the image), or wholly out of it (60 px outside).
    const bool inside = uvz.x() > 30 && uvz.y() > 30 && uvz.x() < 610 && uvz.y() < 450;
    const bool outside = uvz.x() < -60 || uvz.y() < -60 || uvz.x() > 700 || uvz.y() > 540;
    if (inside && t > 0.2) {
      ++in_view;
      tracked_in_view += s.tracking;
      if (s.tracking) {
        const double e = (s.position - truth).norm();
        sum += e * e;
        worst = std::max(worst, e);
      }
    }
    if (outside) {
      ++out_of_view;
      lost_out_of_view += !s.tracking;
    }
    if (was_lost && s.tracking) ++reacquired;
    was_lost = !s.tracking;
    if (!s.tracking && tracker.last().accepted > 0) {
      EXPECT_TRUE(s.reason == TrackReason::NotSeen || s.reason == TrackReason::Jumped) << toString(s.reason);
      EXPECT_TRUE(s.velocity.isZero());
    }
  }
  const double rms = std::sqrt(sum / std::max(1, tracked_in_view));
  std::printf(
      "tracked %d of %d frames in view: rms %.2f mm, max %.2f mm; lost %d of %d out of view; reacquired %d "
      "times\n",
      tracked_in_view, in_view, 1e3 * rms, 1e3 * worst, lost_out_of_view, out_of_view, reacquired);
  EXPECT_GT(in_view, 500);
  EXPECT_EQ(tracked_in_view, in_view);
  EXPECT_LT(rms, 0.003);
  EXPECT_LT(worst, 0.012);
  EXPECT_GT(out_of_view, 30) << "the path never left the view: choose another seed";
  // Lost within lost_after (0.5 s, 15 frames) of leaving the view.
  EXPECT_GE(lost_out_of_view, out_of_view - 15);
  EXPECT_GE(reacquired, 1);
  EXPECT_EQ(tracker.last().dropped, 0);
}

TEST(ObjectTracker, SaysWhyItIsNotTracking) {
  Scene scene(6);
  ObjectTracker tracker(scene.trackerConfig());
  // Before any frame, and a frame whose depth has the wrong encoding.
  EXPECT_EQ(tracker.at(0.0).reason, TrackReason::NeverSeen);
  scene.render(0.0);
  cv::Mat millimetres;
  scene.camera().depth().convertTo(millimetres, CV_16UC1, 1000.0);
  const TrackedState& bad = tracker.frame(0.0, scene.camera().bgr(), millimetres, scene.camera().camera());
  EXPECT_EQ(bad.located, bs::vision::LocateStatus::WrongImage);
  EXPECT_EQ(bad.reason, TrackReason::NeverSeen);
  EXPECT_NE(ObjectTracker::describe(bad).find("WrongImage"), std::string::npos) << ObjectTracker::describe(bad);
  for (double t = 0.1; t < 1.0; t += 1.0 / 30.0) ASSERT_TRUE(scene.frame(tracker, t).tracking || t < 0.2);
  const double last = tracker.last().last_frame;
  // A duplicate and a reordered frame are dropped, the state unchanged.
  scene.render(last);
  EXPECT_EQ(tracker.frame(last, scene.camera().bgr(), scene.camera().depth(), scene.camera().camera()).dropped, 1);
  EXPECT_EQ(tracker.frame(last - 0.1, scene.camera().bgr(), scene.camera().depth(), scene.camera().camera()).dropped,
            2);
  // Frames that stop: tracking until camera_timeout after the last, then lost with the reason.
  EXPECT_TRUE(tracker.at(last + 0.3).tracking);
  const TrackedState stopped = tracker.at(last + 0.6);
  EXPECT_FALSE(stopped.tracking);
  EXPECT_EQ(stopped.reason, TrackReason::CameraStopped);
  EXPECT_NE(ObjectTracker::describe(stopped).find("no camera frame for 0.60 s"), std::string::npos)
      << ObjectTracker::describe(stopped);
  // A camera pose that is not rigid (a NaN on tf) for longer than lost_after: lost because of the frames.
  bs::vision::PinholeCamera broken = scene.camera().camera();
  broken.pose.translation().x() = std::nan("");
  TrackedState s;
  for (double t = last + 0.7; t < last + 1.5; t += 1.0 / 30.0) {
    s = tracker.frame(t, scene.camera().bgr(), scene.camera().depth(), broken);
  }
  EXPECT_FALSE(s.tracking);
  EXPECT_EQ(s.reason, TrackReason::BadFrame);
  // The clock going back (a simulation reset) starts afresh: found again at once.
  const TrackedState& again = scene.frame(tracker, 0.05);
  EXPECT_TRUE(again.tracking);
  EXPECT_EQ(again.update, bs::signal::TargetTracker::Update::Started);
  EXPECT_LT((again.position - scene.path().at(0.05).position).norm(), 0.005);
}

TEST(ObjectTracker, AJumpIsNotFollowedUntilItStays) {
  Scene scene(7);
  bs::tracking::ObjectTrackerConfig config = scene.trackerConfig();
  ObjectTracker tracker(config);
  for (double t = 0.0; t < 1.0; t += 1.0 / 30.0) ASSERT_TRUE(scene.frame(tracker, t).tracking || t < 0.1);
  const Eigen::Vector3d before = tracker.last().position;
  // The object (seen as) 0.2 m aside at once: rejected reject_limit times in a row, then a new track there.
  Eigen::Isometry3d moved = Eigen::Isometry3d::Identity();
  moved.translation() = scene.path().at(1.0).position + Eigen::Vector3d(0.0, 0.2, 0.0);
  int rejected = 0;
  double t = 1.0;
  for (; t < 2.0; t += 1.0 / 30.0) {
    scene.camera().setMovingPose(0, moved);
    (void)scene.camera().render(Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xi(3, 0));
    const TrackedState& s = tracker.frame(t, scene.camera().bgr(), scene.camera().depth(), scene.camera().camera());
    if (s.update == bs::signal::TargetTracker::Update::Rejected) {
      ++rejected;
      if (s.tracking) {
        EXPECT_LT((s.position - before).norm(), 0.05) << "followed the jump";
      }
    }
    if (s.update == bs::signal::TargetTracker::Update::Started) break;
  }
  EXPECT_EQ(rejected, config.filter.reject_limit);
  EXPECT_TRUE(tracker.last().tracking);
  EXPECT_LT((tracker.last().position - moved.translation()).norm(), 0.005);
}
