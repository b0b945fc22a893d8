// The camera contract of the fold's reward (ros_layer/camera_contract.hpp), on CameraInfo messages as bullet_sim's
// cameras and real ones publish them: what fits each model passes, what does not is refused with the reason.
#include "bimanual_skills/ros_layer/camera_contract.hpp"
#include "bimanual_skills/ros_layer/camera_messages.hpp"

#include <gtest/gtest.h>
#include <tf2_eigen/tf2_eigen.h>

#include <string>

namespace br = bimanual_skills::ros_layer;
namespace bv = bimanual_skills::vision;

namespace {

bv::TopDownCamera map() {
  return bv::TopDownCamera::covering(320, 240, 1.0, Eigen::Vector2d(0.55, 0.0), 1.65);
}

bv::PinholeCamera kinect() {
  return bv::PinholeCamera::lookingAt(Eigen::Vector3d(1.2, 0.0, 1.45), Eigen::Vector3d(0.55, 0.0, 0.15));
}

std_msgs::Header header(const std::string& frame) {
  std_msgs::Header h;
  h.frame_id = frame;
  return h;
}

/// Whether `problem` is a refusal that mentions `what`.
::testing::AssertionResult refusedFor(const std::string& problem, const std::string& what) {
  if (!problem.empty() && problem.find(what) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << problem << "' does not refuse for '" << what << "'";
}

}  // namespace

TEST(CameraContract, EachCameraFitsItsOwnModelOnly) {
  const sensor_msgs::CameraInfo orthographic = br::cameraInfo(map(), header("top_down_camera"));
  const sensor_msgs::CameraInfo perspective = br::cameraInfo(kinect(), header("rgbd_camera_optical_frame"));
  EXPECT_EQ(br::cameraInfoProblem(orthographic, br::CameraModel::Orthographic, map()), "");
  EXPECT_EQ(br::cameraInfoProblem(perspective, br::CameraModel::Perspective, map()), "");
  // A Kinect's 640 x 480 images taken for the reward's map would be mis-scored: refused, with what to do.
  EXPECT_TRUE(refusedFor(br::cameraInfoProblem(perspective, br::CameraModel::Orthographic, map()),
                         "set the camera model to perspective"));
  EXPECT_TRUE(refusedFor(br::cameraInfoProblem(orthographic, br::CameraModel::Perspective, map()),
                         "set the camera model to orthographic"));
  EXPECT_THROW(br::cameraModel("fisheye"), std::invalid_argument);
  EXPECT_EQ(br::cameraModel("perspective"), br::CameraModel::Perspective);
}

TEST(CameraContract, WhatTheRewardCannotUseIsRefusedWithTheReason) {
  sensor_msgs::CameraInfo info = br::cameraInfo(kinect(), header("rgbd_camera_optical_frame"));
  info.D[0] = 0.08;  // a raw, distorted image: read and rectified
  EXPECT_EQ(br::cameraInfoProblem(info, br::CameraModel::Perspective, map()), "");
  info.distortion_model = "fov";  // a model nothing here undistorts
  EXPECT_TRUE(refusedFor(br::cameraInfoProblem(info, br::CameraModel::Perspective, map()), "image_rect"));
  info = br::cameraInfo(kinect(), header("rgbd_camera_optical_frame"));
  info = br::cameraInfo(kinect(), header(""));
  EXPECT_TRUE(refusedFor(br::cameraInfoProblem(info, br::CameraModel::Perspective, map()), "names no frame"));
  info = br::cameraInfo(kinect(), header("right_optical"));
  info.P[3] = -0.05 * info.P[0];  // the right camera of a stereo pair
  EXPECT_TRUE(refusedFor(br::cameraInfoProblem(info, br::CameraModel::Perspective, map()), "stereo"));
  info = br::cameraInfo(kinect(), header("rgbd"));
  info.K[0] = 0.0;
  info.P[0] = 0.0;
  EXPECT_TRUE(refusedFor(br::cameraInfoProblem(info, br::CameraModel::Perspective, map()), "fx, fy > 0"));
  info = br::cameraInfo(kinect(), header("rgbd"));
  info.K[2] = std::nan("");
  EXPECT_TRUE(refusedFor(br::cameraInfoProblem(info, br::CameraModel::Perspective, map()), "not finite"));
  // An orthographic camera of another size or scale than the reward's map.
  bv::TopDownCamera other = map();
  other.pixel_size *= 2.0;
  info = br::cameraInfo(other, header("top_down_camera"));
  EXPECT_TRUE(refusedFor(br::cameraInfoProblem(info, br::CameraModel::Orthographic, map()), "scale"));
  other = bv::TopDownCamera::covering(640, 480, 1.0, Eigen::Vector2d(0.55, 0.0), 1.65);
  info = br::cameraInfo(other, header("top_down_camera"));
  EXPECT_TRUE(refusedFor(br::cameraInfoProblem(info, br::CameraModel::Orthographic, map()), "640 x 480"));
}

TEST(CameraContract, TheOrthographicFrameMustBeTheMapsAndThePinholeComesBackWhole) {
  const Eigen::Isometry3d pose =
      tf2::transformToEigen(br::cameraTransform(map(), "world", "top_down_camera", ros::Time(0)));
  EXPECT_EQ(br::orthographicPoseProblem(pose, map()), "");
  Eigen::Isometry3d moved = pose;
  moved.translation().x() += 0.01;
  EXPECT_TRUE(refusedFor(br::orthographicPoseProblem(moved, map()), "from the reward's map camera"));
  const bv::PinholeCamera camera = kinect();
  const Eigen::Isometry3d on_tf =
      tf2::transformToEigen(br::cameraTransform(camera, "world", "rgbd_camera_optical_frame", ros::Time(0)));
  const bv::PinholeCamera back = br::pinholeCamera(br::cameraInfo(camera, header("rgbd")), on_tf);
  EXPECT_EQ(back.width, 640);
  EXPECT_EQ(back.fx, camera.fx);
  EXPECT_EQ(back.cy, camera.cy);
  EXPECT_LT((back.pose.matrix() - camera.pose.matrix()).cwiseAbs().maxCoeff(), 1e-12);
}
