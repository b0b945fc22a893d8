/// \file
/// What the fold's reward can use of a camera, checked on its sensor_msgs/CameraInfo and its frame: either the
/// orthographic top-down camera of the reward itself (bullet_sim's camera/..., an affine CameraInfo whose size and
/// scale are the reward's map), or a perspective RGB-D camera (a Kinect or RealSense: pinhole, raw or rectified (read
/// by RgbdReader), any pose on tf) whose depth is re-projected into that map (vision::HeightMapProjector). Anything
/// else is refused with the reason: a perspective camera's images given as orthographic would be silently mis-scored.
#pragma once

#include "bimanual_skills/vision/perspective_camera.hpp"
#include "bimanual_skills/vision/top_down_camera.hpp"

#include <sensor_msgs/CameraInfo.h>
#include <Eigen/Geometry>

#include <string>

namespace bimanual_skills::ros_layer {

enum class CameraModel { Orthographic, Perspective };

/// "orthographic" or "perspective". \throws std::invalid_argument for another name.
CameraModel cameraModel(const std::string& name);

/// Why `info` cannot serve as a camera of `model` for a reward whose map is `map`; "" when it can.
std::string cameraInfoProblem(const sensor_msgs::CameraInfo& info, CameraModel model, const vision::TopDownCamera& map);

/// Why `info` is not a perspective RGB-D camera's that RgbdReader can bring to a vision::PinholeCamera (pinhole K and
/// P, a distortion model it undistorts, not the second of a stereo pair, 8-8192 pixels a side); "" when it is.
std::string perspectiveInfoProblem(const sensor_msgs::CameraInfo& info);

/// Why an orthographic camera whose optical frame lies at `pose` (in the reward's world frame) is not the reward's
/// map camera (above its centre, looking down, within 1 mm and 1 mrad); "" when it is.
std::string orthographicPoseProblem(const Eigen::Isometry3d& pose, const vision::TopDownCamera& map);

/// The pinhole camera of a perspective CameraInfo's rectified images (P; checked by cameraInfoProblem) with its
/// optical frame at `pose`.
vision::PinholeCamera pinholeCamera(const sensor_msgs::CameraInfo& info, const Eigen::Isometry3d& pose);

}  // namespace bimanual_skills::ros_layer
