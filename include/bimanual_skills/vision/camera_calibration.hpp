/// \file
/// A camera's calibration as a driver reports it (sensor_msgs/CameraInfo's fields, without ROS) and the step from its
/// raw images to rectified ones: the images a PinholeCamera (no distortion) models. Conventions are CameraInfo's
/// (REP 104): K the raw images' intrinsics, D their distortion ("plumb_bob" and "rational_polynomial": OpenCV's
/// radial-tangential model, 5 or 8 coefficients; "equidistant": the fisheye model, 4), R the rectifying rotation,
/// P = [K' | t] the projection of the rectified images. A raw image with D = 0 and R = I is its own rectified image
/// when K = P's left 3 × 3; otherwise Rectifier remaps it (cv::initUndistortRectifyMap): colour bilinearly, depth by
/// the nearest raw pixel (a depth is never blended across an edge).
#pragma once

#include "bimanual_skills/vision/perspective_camera.hpp"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace bimanual_skills::vision {

struct CameraCalibration {
  int width = 0, height = 0;
  std::string distortion_model = "plumb_bob";
  std::vector<double> D;                                                ///< As CameraInfo; empty or all zero: none.
  Eigen::Matrix3d K = Eigen::Matrix3d::Identity();                      ///< The raw images' intrinsics.
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();                      ///< Rectifying rotation.
  Eigen::Matrix<double, 3, 4> P = Eigen::Matrix<double, 3, 4>::Zero();  ///< Projection of the rectified images.

  /// Why it cannot serve (a size out of 8–8192, non-finite or non-pinhole K or P, a distortion model or coefficient
  /// count that is not handled, the second camera of a stereo pair); "" when it can.
  std::string problem() const;
  /// Whether its raw images are rectified already (no distortion, R = I, K = P's left 3 × 3).
  bool rectified() const;
  /// The pinhole camera of its rectified images (P's intrinsics, `pose` of the optical frame).
  PinholeCamera rectifiedCamera(const Eigen::Isometry3d& pose = Eigen::Isometry3d::Identity()) const;
};

/// Raw images of a calibrated camera to rectified ones. Maps built once at construction; rectify() allocates only
/// the first time for each output.
class Rectifier {
 public:
  /// \throws std::invalid_argument with the calibration's problem().
  explicit Rectifier(const CameraCalibration& calibration);

  /// Whether the images need a remap at all (else rectify() copies).
  bool remaps() const noexcept { return !identity_; }
  /// Colour (any type OpenCV remaps; bilinear) into `out`; false for an image of another size.
  bool rectifyColour(const cv::Mat& raw, cv::Mat& out) const;
  /// Depth (CV_32FC1 [m], NaN: no return; nearest pixel) into `out`; false for an image of another size or type.
  bool rectifyDepth(const cv::Mat& raw, cv::Mat& out) const;
  const CameraCalibration& calibration() const noexcept { return calibration_; }

 private:
  CameraCalibration calibration_;
  bool identity_ = true;
  cv::Mat map_x_, map_y_;
};

/// A depth image in REP 118's encodings to metres (CV_32FC1, NaN where there is no return): "32FC1" is metres
/// (0 also means no return), "16UC1" millimetres (0: no return). False, `out` untouched, for another type.
bool depthToMetres(const cv::Mat& depth, bool millimetres, cv::Mat& out);

}  // namespace bimanual_skills::vision
