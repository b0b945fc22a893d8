/// \file
/// One reader of an RGB-D camera as drivers publish it (openni2, realsense2, a simulator), for every task that looks:
/// colour in any encoding cv_bridge turns into bgr8; depth as 32FC1 metres or 16UC1 millimetres (REP 118, 0 or NaN:
/// no return); raw images undistorted with their camera_info's D and R into its P (a camera_info with D = 0, R = I
/// and K = P passes as it is: image_rect, or a simulator's); depth on the colour camera's frame (depth_registered/,
/// or the same camera) used as it is, depth on a frame of its own registered into the colour camera from tf when
/// asked (what depth_image_proc/register does) and refused by name otherwise. An orthographic camera (an affine
/// camera_info: a simulator's top-down map) is decoded only. Every refusal says what to change. Offline: allocates.
#pragma once

#include "bimanual_skills/vision/camera_calibration.hpp"
#include "bimanual_skills/vision/depth_registration.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"

#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <memory>
#include <optional>
#include <string>

namespace bimanual_skills::ros_layer {

/// The calibration a CameraInfo gives (its fields as they are).
vision::CameraCalibration calibrationOf(const sensor_msgs::CameraInfo& info);

/// Whether `info` describes an orthographic (affine) camera: P's third row [0 0 0 1].
bool affine(const sensor_msgs::CameraInfo& info);

class RgbdReader {
 public:
  /// Reads the colour camera of `colour` only (a task that needs no depth). \throws std::invalid_argument with the
  /// reason a calibration cannot serve.
  explicit RgbdReader(const sensor_msgs::CameraInfo& colour);
  /// Reads colour and depth. `colour_from_depth`: the depth camera's optical frame in the colour camera's (tf),
  /// needed when their frames differ; `register_depth`: whether such depth may be registered here. \throws
  /// std::invalid_argument with what to change (frames that differ without registration, a depth camera_info of
  /// another camera model, no transform).
  RgbdReader(const sensor_msgs::CameraInfo& colour, const sensor_msgs::CameraInfo& depth,
             const std::optional<Eigen::Isometry3d>& colour_from_depth, bool register_depth);
  ~RgbdReader();
  RgbdReader(RgbdReader&&) noexcept;
  RgbdReader& operator=(RgbdReader&&) noexcept;

  /// Whether `colour` (and `depth`, when read) are the camera_infos this reader was made for (a driver that
  /// changes its calibration or resolution needs a new reader).
  bool madeFor(const sensor_msgs::CameraInfo& colour, const sensor_msgs::CameraInfo* depth = nullptr) const;

  /// The colour image as bgr8, rectified; "" or why not.
  std::string readColour(const sensor_msgs::Image& colour, cv::Mat& bgr) const;
  /// Colour (bgr8) and depth (CV_32FC1 metres, NaN: no return), both rectified and the depth on the colour camera's
  /// pixels; "" or why not.
  std::string read(const sensor_msgs::Image& colour, const sensor_msgs::Image& depth, cv::Mat& bgr,
                   cv::Mat& metres) const;

  /// The rectified colour camera (P's intrinsics) with its optical frame at `pose`.
  vision::PinholeCamera camera(const Eigen::Isometry3d& pose) const;
  /// When depth is registered here from a camera of its own: that rectified depth camera, placed by the colour
  /// camera's optical frame at `colour_pose` (what it sees past its edge has no depth on the colour's pixels).
  std::optional<vision::PinholeCamera> depthCamera(const Eigen::Isometry3d& colour_pose) const;
  /// What it does, for logs ("640 x 480 rectified from plumb_bob, 16UC1 depth registered from
  /// camera_depth_optical_frame").
  const std::string& description() const noexcept { return description_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string description_;
};

}  // namespace bimanual_skills::ros_layer
