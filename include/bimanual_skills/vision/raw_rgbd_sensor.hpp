/// \file
/// An RGB-D sensor as a Kinect's or a RealSense's driver delivers its images, for a simulator that stands in for
/// hardware: the colour camera's raw images, distorted by its lens (plumb_bob: the images a PinholeCamera would
/// take, remapped through the distortion), and the depth camera's own images, from beside the colour camera (a
/// Kinect's IR camera sits 2.5 cm from it), in 16UC1 millimetres (0: no return), the two cameras' calibrations for
/// their sensor_msgs/CameraInfo. Both are rendered by PerspectiveRenderer (its sensor noise on the depth); moving
/// solids (a carried object, the arms' links) are drawn in both.
#pragma once

#include "bimanual_skills/vision/camera_calibration.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <random>
#include <vector>

namespace bimanual_skills::vision {

struct RawRgbdSensorConfig {
  PinholeCamera colour;  ///< The colour camera's rectified model (its pose: the colour optical frame).
  /// The colour lens' plumb_bob distortion (k1, k2, p1, p2, k3): a Kinect v1's colour camera (Smisek et al. 2011).
  std::vector<double> distortion = {0.19, -0.45, 0.001, -0.002, 0.2};
  /// The depth optical frame in the colour optical frame: 2.5 cm along the colour camera's −x (a Kinect's IR camera).
  Eigen::Isometry3d colour_from_depth = Eigen::Isometry3d(Eigen::Translation3d(-0.025, 0.0, 0.0));
  double depth_fx = 580.0, depth_fy = 580.0;  ///< The depth camera's focal lengths [pixels] (its size: the colour's).
  DepthSensorNoise noise;                     ///< The depth's errors; its colour_stddev applies to the colour.

  /// \throws std::invalid_argument naming the entry that is out of range.
  void validate() const;
};

class RawRgbdSensor {
 public:
  /// \throws std::invalid_argument for an invalid configuration or scene.
  RawRgbdSensor(const ClothRendererParameters& scene, const RawRgbdSensorConfig& config);

  /// A moving solid in both cameras (see PerspectiveRenderer::addMovingSolid); returns its index.
  int addMovingSolid(const SceneSolid& solid);
  void setMovingPose(int index, const Eigen::Isometry3d& pose) noexcept;

  /// Renders the cloth mesh (empty: the scene alone) into rawBgr() and depthMillimetres(), the sensor's noise from
  /// `rng`. Returns the colour camera's status.
  VisionStatus render(const Eigen::Ref<const Eigen::Matrix3Xd>& vertices,
                      const Eigen::Ref<const Eigen::Matrix3Xi>& triangles, std::mt19937& rng);

  /// CV_8UC3 bgr8: the colour camera's raw (distorted) image.
  const cv::Mat& rawBgr() const noexcept { return raw_bgr_; }
  /// CV_16UC1: the depth camera's image, z in millimetres, 0 where there is no return.
  const cv::Mat& depthMillimetres() const noexcept { return depth_mm_; }
  /// What each camera's CameraInfo says: the colour camera raw with its distortion and P its rectified model; the
  /// depth camera undistorted.
  const CameraCalibration& colourCalibration() const noexcept { return colour_calibration_; }
  const CameraCalibration& depthCalibration() const noexcept { return depth_calibration_; }
  /// The depth optical frame in the world.
  Eigen::Isometry3d depthPose() const { return config_.colour.pose * config_.colour_from_depth; }
  const RawRgbdSensorConfig& config() const noexcept { return config_; }

 private:
  RawRgbdSensorConfig config_;
  PerspectiveRenderer colour_, depth_;
  CameraCalibration colour_calibration_, depth_calibration_;
  cv::Mat distort_x_, distort_y_;  ///< Raw pixel -> where its ray lands in the rectified image.
  cv::Mat raw_bgr_, depth_mm_;
};

}  // namespace bimanual_skills::vision
