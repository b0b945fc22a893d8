#include "bimanual_skills/vision/camera_calibration.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace bimanual_skills::vision {

namespace {

bool anyDistortion(const std::vector<double>& d) {
  for (const double v : d) {
    if (v != 0.0) return true;
  }
  return false;
}

}  // namespace

std::string CameraCalibration::problem() const {
  std::ostringstream why;
  if (width < 8 || height < 8 || width > 8192 || height > 8192) {
    why << "its images are " << width << " x " << height << " (8 to 8192 pixels a side are used)";
    return why.str();
  }
  if (!K.allFinite() || !R.allFinite() || !P.allFinite()) return "its K, R or P is not finite";
  if (!(K(0, 0) > 0.0) || !(K(1, 1) > 0.0) || K(0, 1) != 0.0 || K(1, 0) != 0.0 || K(2, 0) != 0.0 || K(2, 1) != 0.0 ||
      K(2, 2) != 1.0) {
    return "its K is not a pinhole's [fx 0 cx; 0 fy cy; 0 0 1] with fx, fy > 0";
  }
  if (!(P(0, 0) > 0.0) || !(P(1, 1) > 0.0) || P(2, 0) != 0.0 || P(2, 1) != 0.0 || P(2, 2) != 1.0 || P(2, 3) != 0.0) {
    return "its P is not a pinhole's projection [fx' 0 cx' Tx; 0 fy' cy' Ty; 0 0 1 0] with fx', fy' > 0";
  }
  if (P(0, 3) != 0.0 || P(1, 3) != 0.0) {
    return "it is the second camera of a stereo pair (P has Tx, Ty): give the first's";
  }
  if ((R * R.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 || R.determinant() < 0.0) {
    return "its R is not a rotation";
  }
  for (const double d : D) {
    if (!std::isfinite(d)) return "its D is not finite";
  }
  if (!anyDistortion(D)) return "";
  if (distortion_model == "plumb_bob" || distortion_model == "rational_polynomial") {
    if (D.size() != 4 && D.size() != 5 && D.size() != 8 && D.size() != 12 && D.size() != 14) {
      why << "its " << distortion_model << " D has " << D.size() << " coefficients (4, 5, 8, 12 or 14 are used)";
      return why.str();
    }
    return "";
  }
  if (distortion_model == "equidistant") {
    if (D.size() != 4) {
      why << "its equidistant D has " << D.size() << " coefficients (4 are used)";
      return why.str();
    }
    return "";
  }
  return "its distortion model '" + distortion_model +
         "' is not handled (plumb_bob, rational_polynomial, equidistant): give rectified images (image_proc's "
         "image_rect) with a camera_info whose D is zero";
}

bool CameraCalibration::rectified() const {
  return !anyDistortion(D) && R.isIdentity(1e-12) && (K - P.leftCols<3>()).cwiseAbs().maxCoeff() <= 1e-9;
}

PinholeCamera CameraCalibration::rectifiedCamera(const Eigen::Isometry3d& pose) const {
  PinholeCamera camera;
  camera.width = width;
  camera.height = height;
  camera.fx = P(0, 0);
  camera.fy = P(1, 1);
  camera.cx = P(0, 2);
  camera.cy = P(1, 2);
  camera.pose = pose;
  return camera;
}

Rectifier::Rectifier(const CameraCalibration& calibration) : calibration_(calibration) {
  if (const std::string problem = calibration.problem(); !problem.empty()) {
    throw std::invalid_argument("camera calibration: " + problem);
  }
  identity_ = calibration.rectified();
  if (identity_) return;
  cv::Mat k, r, p;
  cv::eigen2cv(calibration.K, k);
  cv::eigen2cv(calibration.R, r);
  const Eigen::Matrix3d new_k = calibration.P.leftCols<3>();
  cv::eigen2cv(new_k, p);
  const cv::Mat d = calibration.D.empty() ? cv::Mat() : cv::Mat(calibration.D, true);
  const cv::Size size(calibration.width, calibration.height);
  if (calibration.distortion_model == "equidistant") {
    cv::fisheye::initUndistortRectifyMap(k, d, r, p, size, CV_32FC1, map_x_, map_y_);
  } else {
    cv::initUndistortRectifyMap(k, d, r, p, size, CV_32FC1, map_x_, map_y_);
  }
}

bool Rectifier::rectifyColour(const cv::Mat& raw, cv::Mat& out) const {
  if (raw.cols != calibration_.width || raw.rows != calibration_.height) return false;
  if (identity_) {
    raw.copyTo(out);
  } else {
    cv::remap(raw, out, map_x_, map_y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  }
  return true;
}

bool Rectifier::rectifyDepth(const cv::Mat& raw, cv::Mat& out) const {
  if (raw.cols != calibration_.width || raw.rows != calibration_.height || raw.type() != CV_32FC1) return false;
  if (identity_) {
    raw.copyTo(out);
  } else {
    cv::remap(raw, out, map_x_, map_y_, cv::INTER_NEAREST, cv::BORDER_CONSTANT,
              cv::Scalar::all(std::numeric_limits<double>::quiet_NaN()));
  }
  return true;
}

bool depthToMetres(const cv::Mat& depth, bool millimetres, cv::Mat& out) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  if (millimetres) {
    if (depth.type() != CV_16UC1) return false;
    out.create(depth.size(), CV_32FC1);
    for (int r = 0; r < depth.rows; ++r) {
      const auto* in = depth.ptr<std::uint16_t>(r);
      auto* m = out.ptr<float>(r);
      for (int c = 0; c < depth.cols; ++c) m[c] = in[c] == 0 ? nan : 1e-3f * static_cast<float>(in[c]);
    }
    return true;
  }
  if (depth.type() != CV_32FC1) return false;
  depth.copyTo(out);
  for (int r = 0; r < out.rows; ++r) {
    auto* m = out.ptr<float>(r);
    for (int c = 0; c < out.cols; ++c) {
      if (!(m[c] > 0.0f) || !std::isfinite(m[c])) m[c] = nan;
    }
  }
  return true;
}

}  // namespace bimanual_skills::vision
