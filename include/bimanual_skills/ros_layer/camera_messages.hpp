/// \file
/// The top-down camera (vision::TopDownCamera) as ROS describes a camera: its sensor_msgs/CameraInfo and its
/// optical frame on tf. The camera is orthographic, which CameraInfo's pinhole model holds as an affine camera:
/// P = [1/s 0 0 W/2; 0 1/s 0 H/2; 0 0 0 1] maps a point (x, y, z) of the optical frame to the pixel (x/s + W/2,
/// y/s + H/2) whatever its depth z (image_geometry's PinholeCameraModel::project3dToPixel divides by P's third row,
/// here 1); K holds the same pixel scale. The optical frame sits above the image centre at the camera height with
/// x_c = world x, y_c = world −y, z_c = world −z (looking down).
#pragma once

#include "bimanual_skills/vision/camera_calibration.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"
#include "bimanual_skills/vision/top_down_camera.hpp"

#include <cv_bridge/cv_bridge.h>
#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <Eigen/Geometry>

#include <string>

namespace bimanual_skills::ros_layer {

inline sensor_msgs::CameraInfo cameraInfo(const vision::TopDownCamera& camera, const std_msgs::Header& header) {
  sensor_msgs::CameraInfo info;
  info.header = header;
  info.width = static_cast<std::uint32_t>(camera.columns);
  info.height = static_cast<std::uint32_t>(camera.rows);
  info.distortion_model = "plumb_bob";
  info.D.assign(5, 0.0);
  const double f = 1.0 / camera.pixel_size, cx = 0.5 * camera.columns, cy = 0.5 * camera.rows;
  info.K = {f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0};
  info.R = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  info.P = {f, 0.0, 0.0, cx, 0.0, f, 0.0, cy, 0.0, 0.0, 0.0, 1.0};
  return info;
}

/// The optical frame `frame` in `parent` (the world): above the image centre, rotated by π about x.
inline geometry_msgs::TransformStamped cameraTransform(const vision::TopDownCamera& camera, const std::string& parent,
                                                       const std::string& frame, const ros::Time& stamp) {
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = parent;
  t.child_frame_id = frame;
  t.transform.translation.x = camera.centre.x();
  t.transform.translation.y = camera.centre.y();
  t.transform.translation.z = camera.height;
  t.transform.rotation.x = 1.0;  // π about x: y_c = −y, z_c = −z
  t.transform.rotation.w = 0.0;
  return t;
}

/// A perspective camera's sensor_msgs/CameraInfo: plumb_bob without distortion (rectified images), K from its
/// intrinsics, R the identity, P = [K | 0] (a monocular camera).
inline sensor_msgs::CameraInfo cameraInfo(const vision::PinholeCamera& camera, const std_msgs::Header& header) {
  sensor_msgs::CameraInfo info;
  info.header = header;
  info.width = static_cast<std::uint32_t>(camera.width);
  info.height = static_cast<std::uint32_t>(camera.height);
  info.distortion_model = "plumb_bob";
  info.D.assign(5, 0.0);
  info.K = {camera.fx, 0.0, camera.cx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 1.0};
  info.R = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  info.P = {camera.fx, 0.0, camera.cx, 0.0, 0.0, camera.fy, camera.cy, 0.0, 0.0, 0.0, 1.0, 0.0};
  return info;
}

/// A calibrated camera's sensor_msgs/CameraInfo (its K, D, R and P as they are).
inline sensor_msgs::CameraInfo cameraInfo(const vision::CameraCalibration& c, const std_msgs::Header& header) {
  sensor_msgs::CameraInfo info;
  info.header = header;
  info.width = static_cast<std::uint32_t>(c.width);
  info.height = static_cast<std::uint32_t>(c.height);
  info.distortion_model = c.distortion_model;
  info.D = c.D.empty() ? std::vector<double>(5, 0.0) : c.D;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      info.K[static_cast<std::size_t>(3 * i + j)] = c.K(i, j);
      info.R[static_cast<std::size_t>(3 * i + j)] = c.R(i, j);
    }
    for (int j = 0; j < 4; ++j) info.P[static_cast<std::size_t>(4 * i + j)] = c.P(i, j);
  }
  return info;
}

/// A perspective camera's optical frame `frame` in `parent` (the world): its pose.
inline geometry_msgs::TransformStamped cameraTransform(const vision::PinholeCamera& camera, const std::string& parent,
                                                       const std::string& frame, const ros::Time& stamp) {
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = parent;
  t.child_frame_id = frame;
  const Eigen::Vector3d p = camera.pose.translation();
  const Eigen::Quaterniond q(camera.pose.linear());
  t.transform.translation.x = p.x();
  t.transform.translation.y = p.y();
  t.transform.translation.z = p.z();
  t.transform.rotation.x = q.x();
  t.transform.rotation.y = q.y();
  t.transform.rotation.z = q.z();
  t.transform.rotation.w = q.w();
  return t;
}

/// One frame of an RGB-D camera as ROS carries it: the colour image (bgr8), the depth image (32FC1, metres) and the
/// camera_info of both, under one header (stamp and optical frame). The one place the project's cameras and their
/// recordings build these messages.
struct RgbdFrame {
  sensor_msgs::ImagePtr colour, depth;
  sensor_msgs::CameraInfo info;

  RgbdFrame(const std_msgs::Header& header, const cv::Mat& bgr, const cv::Mat& metres, sensor_msgs::CameraInfo info_)
      : colour(cv_bridge::CvImage(header, "bgr8", bgr).toImageMsg()),
        depth(cv_bridge::CvImage(header, "32FC1", metres).toImageMsg()),
        info(std::move(info_)) {
    info.header = header;
  }

  /// Each message with its topic relative to `ns` (camera/image_raw, camera/camera_info, camera/depth/image_raw,
  /// camera/depth/camera_info), for a writer such as rosbag::Bag::write.
  template <typename Writer>
  void write(const std::string& ns, const ros::Time& time, Writer&& writer) const {
    writer(ns + "camera/image_raw", time, colour);
    writer(ns + "camera/camera_info", time, info);
    writer(ns + "camera/depth/image_raw", time, depth);
    writer(ns + "camera/depth/camera_info", time, info);
  }
};

/// Publishes RgbdFrames on NS/image_raw, NS/camera_info, NS/depth/image_raw and NS/depth/camera_info relative to a
/// node handle (NS "camera" by default; camera_info after its image, as image_transport's CameraPublisher does).
class RgbdPublisher {
 public:
  RgbdPublisher() = default;
  RgbdPublisher(ros::NodeHandle& node, bool latch, const std::string& ns = "camera")
      : colour_(node.advertise<sensor_msgs::Image>(ns + "/image_raw", 1, latch)),
        info_(node.advertise<sensor_msgs::CameraInfo>(ns + "/camera_info", 1, latch)),
        depth_(node.advertise<sensor_msgs::Image>(ns + "/depth/image_raw", 1, latch)),
        depth_info_(node.advertise<sensor_msgs::CameraInfo>(ns + "/depth/camera_info", 1, latch)) {}

  void publish(const RgbdFrame& frame) const {
    colour_.publish(frame.colour);
    info_.publish(frame.info);
    depth_.publish(frame.depth);
    depth_info_.publish(frame.info);
  }

 private:
  ros::Publisher colour_, info_, depth_, depth_info_;
};

}  // namespace bimanual_skills::ros_layer
