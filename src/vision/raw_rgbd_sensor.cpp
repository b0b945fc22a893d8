#include "bimanual_skills/vision/raw_rgbd_sensor.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <stdexcept>

namespace bimanual_skills::vision {

namespace {

PinholeCamera depthCamera(const RawRgbdSensorConfig& c) {
  PinholeCamera d = c.colour;
  d.fx = c.depth_fx;
  d.fy = c.depth_fy;
  d.cx = 0.5 * (d.width - 1);
  d.cy = 0.5 * (d.height - 1);
  d.pose = c.colour.pose * c.colour_from_depth;
  return d;
}

DepthSensorNoise colourOnly(const DepthSensorNoise& noise) {
  DepthSensorNoise n;
  n.axial = n.dropout = n.edge_dropout = n.grazing = 0.0;
  n.colour_stddev = noise.colour_stddev;
  return n;
}

CameraCalibration pinholeCalibration(const PinholeCamera& camera) {
  CameraCalibration c;
  c.width = camera.width;
  c.height = camera.height;
  c.K << camera.fx, 0.0, camera.cx, 0.0, camera.fy, camera.cy, 0.0, 0.0, 1.0;
  c.P.leftCols<3>() = c.K;
  return c;
}

}  // namespace

void RawRgbdSensorConfig::validate() const {
  colour.validate("raw RGB-D sensor: the colour camera");
  if (distortion.size() != 5) throw std::invalid_argument("raw RGB-D sensor: the distortion needs 5 coefficients");
  for (const double d : distortion) {
    if (!std::isfinite(d) || std::abs(d) > 2.0)
      throw std::invalid_argument("raw RGB-D sensor: a distortion in [-2, 2]");
  }
  const Eigen::Matrix3d r = colour_from_depth.linear();
  if (!colour_from_depth.matrix().allFinite() ||
      (r * r.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 ||
      colour_from_depth.translation().norm() > 0.5) {
    throw std::invalid_argument("raw RGB-D sensor: colour_from_depth must be rigid, finite and within 0.5 m");
  }
  if (!(depth_fx > 0.0) || !(depth_fy > 0.0) || !std::isfinite(depth_fx) || !std::isfinite(depth_fy)) {
    throw std::invalid_argument("raw RGB-D sensor: the depth camera's focal lengths must be finite and > 0");
  }
  noise.validate("raw RGB-D sensor");
}

RawRgbdSensor::RawRgbdSensor(const ClothRendererParameters& scene, const RawRgbdSensorConfig& config)
    : config_((config.validate(), config)),
      colour_(scene, config.colour, colourOnly(config.noise)),
      depth_(scene, depthCamera(config), config.noise) {
  colour_calibration_ = pinholeCalibration(config.colour);
  colour_calibration_.D = config.distortion;
  depth_calibration_ = pinholeCalibration(depthCamera(config));
  // Each raw pixel sees what the undistorted ray through it sees: its place in the rectified (pinhole) image.
  std::vector<cv::Point2f> raw;
  raw.reserve(static_cast<std::size_t>(config.colour.width * config.colour.height));
  for (int v = 0; v < config.colour.height; ++v) {
    for (int u = 0; u < config.colour.width; ++u) raw.emplace_back(static_cast<float>(u), static_cast<float>(v));
  }
  const cv::Matx33d k(config.colour.fx, 0.0, config.colour.cx, 0.0, config.colour.fy, config.colour.cy, 0.0, 0.0, 1.0);
  std::vector<cv::Point2f> rectified;
  cv::undistortPoints(raw, rectified, k, config.distortion, cv::noArray(), k);
  distort_x_.create(config.colour.height, config.colour.width, CV_32FC1);
  distort_y_.create(config.colour.height, config.colour.width, CV_32FC1);
  for (int v = 0; v < config.colour.height; ++v) {
    for (int u = 0; u < config.colour.width; ++u) {
      const cv::Point2f& p = rectified[static_cast<std::size_t>(v * config.colour.width + u)];
      distort_x_.at<float>(v, u) = p.x;
      distort_y_.at<float>(v, u) = p.y;
    }
  }
  raw_bgr_.create(config.colour.height, config.colour.width, CV_8UC3);
  depth_mm_.create(config.colour.height, config.colour.width, CV_16UC1);
}

int RawRgbdSensor::addMovingSolid(const SceneSolid& solid) {
  const int index = colour_.addMovingSolid(solid);
  depth_.addMovingSolid(solid);
  return index;
}

void RawRgbdSensor::setMovingPose(int index, const Eigen::Isometry3d& pose) noexcept {
  colour_.setMovingPose(index, pose);
  depth_.setMovingPose(index, pose);
}

VisionStatus RawRgbdSensor::render(const Eigen::Ref<const Eigen::Matrix3Xd>& vertices,
                                   const Eigen::Ref<const Eigen::Matrix3Xi>& triangles, std::mt19937& rng) {
  const VisionStatus status = colour_.render(vertices, triangles, rng);
  (void)depth_.render(vertices, triangles, rng);
  cv::remap(colour_.bgr(), raw_bgr_, distort_x_, distort_y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  const cv::Mat& metres = depth_.depth();
  for (int v = 0; v < metres.rows; ++v) {
    const float* in = metres.ptr<float>(v);
    auto* out = depth_mm_.ptr<std::uint16_t>(v);
    for (int u = 0; u < metres.cols; ++u) {
      const float z = in[u];
      out[u] = std::isfinite(z) && z > 0.0f && z < 65.0f ? static_cast<std::uint16_t>(std::lround(1000.0f * z)) : 0;
    }
  }
  return status;
}

}  // namespace bimanual_skills::vision
