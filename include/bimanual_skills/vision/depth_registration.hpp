/// \file
/// Depth registration: a depth camera's rectified depth image seen from the colour camera beside it (a Kinect's or
/// a RealSense's IR camera sits 2.5–5 cm from its colour camera), what openni2's depth_registered/ and
/// depth_image_proc/register give. Each depth pixel with a return is back-projected through the depth camera's
/// intrinsics, moved into the colour camera's optical frame and projected there; its footprint (the projections of
/// its four corners) is filled with its z where nothing nearer lies (a z-buffer), so that a colour image finer than
/// the depth image has no holes between the points. Pixels no point reaches are NaN. The corners' rays, turned into
/// the colour camera, are computed once (a 3-vector per corner of the depth image), so that a pixel costs its four
/// corners' scaling and projection.
#pragma once

#include "bimanual_skills/vision/perspective_camera.hpp"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

namespace bimanual_skills::vision {

class DepthRegistration {
 public:
  /// From the rectified depth camera `depth` to the rectified colour camera `colour`; `colour_from_depth` is the
  /// depth optical frame in the colour optical frame (the cameras' poses are not used). \throws
  /// std::invalid_argument for unusable cameras or a transform that is not rigid and finite.
  DepthRegistration(const PinholeCamera& depth, const PinholeCamera& colour,
                    const Eigen::Isometry3d& colour_from_depth);

  /// `depth` (CV_32FC1 [m], the depth camera's size; NaN: no return) into `out` (CV_32FC1, the colour camera's
  /// size). False for an image of another size or type.
  bool registerDepth(const cv::Mat& depth, cv::Mat& out) const;

 private:
  PinholeCamera depth_, colour_;
  Eigen::Isometry3d colour_from_depth_;
  /// Column (v · (width + 1) + u): the ray through the depth image's pixel corner (u − ½, v − ½) at unit depth,
  /// in the colour camera's axes (R [(u − ½ − cx)/fx, (v − ½ − cy)/fy, 1]ᵀ).
  Eigen::Matrix3Xd corner_rays_;
};

}  // namespace bimanual_skills::vision
