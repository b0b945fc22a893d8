#include "bimanual_skills/ros_layer/rgbd_reader.hpp"

#include <cv_bridge/cv_bridge.h>

#include <sstream>
#include <stdexcept>

namespace bimanual_skills::ros_layer {

namespace {

bool sameInfo(const sensor_msgs::CameraInfo& a, const sensor_msgs::CameraInfo& b) {
  return a.header.frame_id == b.header.frame_id && a.width == b.width && a.height == b.height && a.K == b.K &&
         a.P == b.P && a.R == b.R && a.D == b.D && a.distortion_model == b.distortion_model;
}

std::string size(int width, int height) {
  return std::to_string(width) + " x " + std::to_string(height);
}

}  // namespace

vision::CameraCalibration calibrationOf(const sensor_msgs::CameraInfo& info) {
  vision::CameraCalibration c;
  c.width = static_cast<int>(info.width);
  c.height = static_cast<int>(info.height);
  c.distortion_model = info.distortion_model;
  c.D = info.D;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      c.K(i, j) = info.K[static_cast<std::size_t>(3 * i + j)];
      c.R(i, j) = info.R[static_cast<std::size_t>(3 * i + j)];
    }
    for (int j = 0; j < 4; ++j) c.P(i, j) = info.P[static_cast<std::size_t>(4 * i + j)];
  }
  return c;
}

bool affine(const sensor_msgs::CameraInfo& info) {
  return info.P[8] == 0.0 && info.P[9] == 0.0 && info.P[10] == 0.0 && info.P[11] == 1.0;
}

struct RgbdReader::Impl {
  sensor_msgs::CameraInfo colour_info, depth_info;
  bool with_depth = false, orthographic = false;
  vision::CameraCalibration colour;
  std::unique_ptr<vision::Rectifier> colour_rectifier, depth_rectifier;
  std::unique_ptr<vision::DepthRegistration> registration;  ///< Null: the depth is on the colour camera's pixels.
  /// With registration from another frame: the rectified depth camera, its optical frame in the colour camera's.
  std::optional<vision::PinholeCamera> depth_camera;
};

RgbdReader::RgbdReader(const sensor_msgs::CameraInfo& colour) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.colour_info = colour;
  if (colour.header.frame_id.empty()) {
    throw std::invalid_argument("the colour camera_info names no frame (header.frame_id)");
  }
  m.orthographic = affine(colour);
  std::ostringstream said;
  said << size(static_cast<int>(colour.width), static_cast<int>(colour.height)) << " colour on "
       << colour.header.frame_id;
  if (m.orthographic) {
    said << " (orthographic)";
  } else {
    m.colour = calibrationOf(colour);
    if (const std::string problem = m.colour.problem(); !problem.empty()) {
      throw std::invalid_argument("the colour camera: " + problem);
    }
    m.colour_rectifier = std::make_unique<vision::Rectifier>(m.colour);
    if (m.colour_rectifier->remaps()) said << ", rectified from " << colour.distortion_model;
  }
  description_ = said.str();
}

RgbdReader::RgbdReader(const sensor_msgs::CameraInfo& colour, const sensor_msgs::CameraInfo& depth,
                       const std::optional<Eigen::Isometry3d>& colour_from_depth, bool register_depth)
    : RgbdReader(colour) {
  Impl& m = *impl_;
  m.with_depth = true;
  m.depth_info = depth;
  const std::string& frame = depth.header.frame_id;
  if (frame.empty()) throw std::invalid_argument("the depth camera_info names no frame (header.frame_id)");
  std::ostringstream said;
  said << "; " << size(static_cast<int>(depth.width), static_cast<int>(depth.height)) << " depth on " << frame;
  if (m.orthographic) {
    if (!sameInfo(colour, depth)) {
      throw std::invalid_argument("an orthographic camera's depth must have the colour's camera_info (frame " +
                                  colour.header.frame_id + ", " +
                                  size(static_cast<int>(colour.width), static_cast<int>(colour.height)) +
                                  "); its depth camera_info is of " + frame);
    }
    description_ += said.str();
    return;
  }
  if (affine(depth)) throw std::invalid_argument("the depth camera is orthographic, the colour camera perspective");
  const vision::CameraCalibration calibration = calibrationOf(depth);
  if (const std::string problem = calibration.problem(); !problem.empty()) {
    throw std::invalid_argument("the depth camera: " + problem);
  }
  m.depth_rectifier = std::make_unique<vision::Rectifier>(calibration);
  if (m.depth_rectifier->remaps()) said << ", rectified from " << depth.distortion_model;
  const bool same_frame = frame == colour.header.frame_id;
  if (!same_frame && !register_depth) {
    throw std::invalid_argument(
        "the depth images are on " + frame + ", the colour images on " + colour.header.frame_id +
        ": unregistered depth would be read through the wrong camera. Give registered depth (openni2's "
        "depth_registered/ with depth_registration:=true, realsense2's aligned_depth_to_color/ with "
        "align_depth:=true, or depth_image_proc/register) or let it be registered here from tf (register_depth)");
  }
  if (!same_frame && !colour_from_depth) {
    throw std::invalid_argument("no transform from the depth camera's frame " + frame + " to the colour camera's " +
                                colour.header.frame_id + " on tf to register its depth");
  }
  const vision::PinholeCamera depth_camera = calibration.rectifiedCamera(), colour_camera = m.colour.rectifiedCamera();
  const bool same_pixels = same_frame && depth_camera.width == colour_camera.width &&
                           depth_camera.height == colour_camera.height && depth_camera.fx == colour_camera.fx &&
                           depth_camera.fy == colour_camera.fy && depth_camera.cx == colour_camera.cx &&
                           depth_camera.cy == colour_camera.cy;
  if (!same_pixels) {
    // Another frame, or the same one at another resolution: each depth pixel goes where the colour camera sees it.
    m.registration = std::make_unique<vision::DepthRegistration>(
        depth_camera, colour_camera, same_frame ? Eigen::Isometry3d::Identity() : *colour_from_depth);
    said << (same_frame ? ", resampled to the colour's pixels" : ", registered here into the colour camera");
    if (!same_frame) {
      m.depth_camera = depth_camera;
      m.depth_camera->pose = *colour_from_depth;
    }
  }
  description_ += said.str();
}

RgbdReader::~RgbdReader() = default;
RgbdReader::RgbdReader(RgbdReader&&) noexcept = default;
RgbdReader& RgbdReader::operator=(RgbdReader&&) noexcept = default;

bool RgbdReader::madeFor(const sensor_msgs::CameraInfo& colour, const sensor_msgs::CameraInfo* depth) const {
  return sameInfo(colour, impl_->colour_info) && (!impl_->with_depth || !depth || sameInfo(*depth, impl_->depth_info));
}

std::string RgbdReader::readColour(const sensor_msgs::Image& colour, cv::Mat& bgr) const {
  const Impl& m = *impl_;
  if (colour.width != m.colour_info.width || colour.height != m.colour_info.height) {
    return "the colour image is " + size(static_cast<int>(colour.width), static_cast<int>(colour.height)) +
           ", its camera_info " + size(static_cast<int>(m.colour_info.width), static_cast<int>(m.colour_info.height));
  }
  cv::Mat raw;
  try {
    raw = cv_bridge::toCvCopy(colour, "bgr8")->image;
  } catch (const cv_bridge::Exception& e) {
    return "the colour image's encoding " + colour.encoding + " cannot be read as bgr8: " + e.what();
  }
  if (!m.colour_rectifier) {
    bgr = raw;
  } else {
    m.colour_rectifier->rectifyColour(raw, bgr);
  }
  return "";
}

std::string RgbdReader::read(const sensor_msgs::Image& colour, const sensor_msgs::Image& depth, cv::Mat& bgr,
                             cv::Mat& metres) const {
  const Impl& m = *impl_;
  if (!m.with_depth) return "this reader was made for the colour camera only";
  if (std::string problem = readColour(colour, bgr); !problem.empty()) return problem;
  if (depth.header.frame_id != m.depth_info.header.frame_id) {
    return "the depth image is on " + depth.header.frame_id + ", its camera_info on " + m.depth_info.header.frame_id;
  }
  if (depth.width != m.depth_info.width || depth.height != m.depth_info.height) {
    return "the depth image is " + size(static_cast<int>(depth.width), static_cast<int>(depth.height)) +
           ", its camera_info " + size(static_cast<int>(m.depth_info.width), static_cast<int>(m.depth_info.height));
  }
  const bool millimetres = depth.encoding == "16UC1" || depth.encoding == "mono16";
  if (!millimetres && depth.encoding != "32FC1") {
    return "the depth image's encoding is " + depth.encoding + ": 32FC1 metres or 16UC1 millimetres are read (REP 118)";
  }
  cv::Mat raw, decoded;
  try {
    raw = cv_bridge::toCvShare(depth, nullptr)->image;
  } catch (const cv_bridge::Exception& e) {
    return std::string("the depth image cannot be read: ") + e.what();
  }
  if (!vision::depthToMetres(raw, millimetres, decoded)) return "the depth image's data is not " + depth.encoding;
  if (m.orthographic) {
    metres = decoded;
    return "";
  }
  cv::Mat rectified;
  m.depth_rectifier->rectifyDepth(decoded, rectified);
  if (!m.registration) {
    metres = rectified;
    return "";
  }
  m.registration->registerDepth(rectified, metres);
  return "";
}

vision::PinholeCamera RgbdReader::camera(const Eigen::Isometry3d& pose) const {
  return impl_->colour.rectifiedCamera(pose);
}

std::optional<vision::PinholeCamera> RgbdReader::depthCamera(const Eigen::Isometry3d& colour_pose) const {
  if (!impl_->depth_camera) return std::nullopt;
  vision::PinholeCamera placed = *impl_->depth_camera;
  placed.pose = colour_pose * impl_->depth_camera->pose;
  return placed;
}

}  // namespace bimanual_skills::ros_layer
