#include "bimanual_skills/ros_layer/camera_contract.hpp"

#include "bimanual_skills/ros_layer/camera_messages.hpp"
#include "bimanual_skills/ros_layer/rgbd_reader.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace bimanual_skills::ros_layer {

namespace {

/// What any camera's info must have: a frame, finite K and P.
std::string framedAndFinite(const sensor_msgs::CameraInfo& info) {
  if (info.header.frame_id.empty()) return "its camera_info names no frame (header.frame_id)";
  for (double v : info.K) {
    if (!std::isfinite(v)) return "its K is not finite";
  }
  for (double v : info.P) {
    if (!std::isfinite(v)) return "its P is not finite";
  }
  return "";
}

}  // namespace

CameraModel cameraModel(const std::string& name) {
  if (name == "orthographic") return CameraModel::Orthographic;
  if (name == "perspective") return CameraModel::Perspective;
  throw std::invalid_argument("camera model '" + name + "' is neither orthographic nor perspective");
}

std::string cameraInfoProblem(const sensor_msgs::CameraInfo& info, CameraModel model,
                              const vision::TopDownCamera& map) {
  std::ostringstream why;
  if (std::string problem = framedAndFinite(info); !problem.empty()) return problem;
  const auto& k = info.K;
  const auto& p = info.P;
  const bool affine = p[8] == 0.0 && p[9] == 0.0 && p[10] == 0.0 && p[11] == 1.0;
  if (model == CameraModel::Orthographic) {
    if (!affine) {
      return "it is a perspective camera (P's third row is not [0 0 0 1]): its images are not the reward's "
             "orthographic map; set the camera model to perspective to re-project them";
    }
    const sensor_msgs::CameraInfo expected = cameraInfo(map, info.header);
    if (info.width != expected.width || info.height != expected.height) {
      why << "its images are " << info.width << " x " << info.height << ", the reward's map " << expected.width << " x "
          << expected.height;
      return why.str();
    }
    for (int i = 0; i < 9; ++i) {
      if (std::abs(k[i] - expected.K[i]) > 1e-6 * std::abs(expected.K[i]) + 1e-9) {
        why << "its scale K = [" << k[0] << ", " << k[2] << ", " << k[4] << ", " << k[5]
            << "] is not the reward's map [" << expected.K[0] << ", " << expected.K[2] << ", " << expected.K[4] << ", "
            << expected.K[5] << "]";
        return why.str();
      }
    }
    return "";
  }
  if (affine) return "it is an orthographic camera (P's third row is [0 0 0 1]): set the camera model to orthographic";
  return perspectiveInfoProblem(info);
}

std::string perspectiveInfoProblem(const sensor_msgs::CameraInfo& info) {
  if (std::string problem = framedAndFinite(info); !problem.empty()) return problem;
  if (affine(info)) return "it is an orthographic camera (P's third row is [0 0 0 1]), not a perspective one";
  // Raw images with their distortion are rectified by RgbdReader into P's pinhole.
  return calibrationOf(info).problem();
}

std::string orthographicPoseProblem(const Eigen::Isometry3d& pose, const vision::TopDownCamera& map) {
  // The reward's map camera: above the image centre at the camera height, rotated by π about x (cameraTransform).
  const Eigen::Vector3d expected(map.centre.x(), map.centre.y(), map.height);
  const Eigen::Matrix3d down = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  const double offset = (pose.translation() - expected).norm();
  const double angle = Eigen::AngleAxisd(Eigen::Matrix3d(down.transpose() * pose.linear())).angle();
  if (!pose.matrix().allFinite() || offset > 1e-3 || angle > 1e-3) {
    std::ostringstream why;
    why << "its frame lies " << offset << " m and " << angle << " rad from the reward's map camera (above ("
        << expected.x() << ", " << expected.y() << ") at " << expected.z() << " m, looking down)";
    return why.str();
  }
  return "";
}

vision::PinholeCamera pinholeCamera(const sensor_msgs::CameraInfo& info, const Eigen::Isometry3d& pose) {
  return calibrationOf(info).rectifiedCamera(pose);
}

}  // namespace bimanual_skills::ros_layer
