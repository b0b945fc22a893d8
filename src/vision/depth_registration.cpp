#include "bimanual_skills/vision/depth_registration.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace bimanual_skills::vision {

DepthRegistration::DepthRegistration(const PinholeCamera& depth, const PinholeCamera& colour,
                                     const Eigen::Isometry3d& colour_from_depth)
    : depth_(depth), colour_(colour), colour_from_depth_(colour_from_depth) {
  PinholeCamera d = depth, c = colour;
  d.pose = c.pose = Eigen::Isometry3d::Identity();
  d.validate("depth registration: the depth camera");
  c.validate("depth registration: the colour camera");
  const Eigen::Matrix3d r = colour_from_depth.linear();
  if (!colour_from_depth.matrix().allFinite() ||
      (r * r.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 || r.determinant() < 0.0) {
    throw std::invalid_argument("depth registration: the transform between the cameras is not rigid and finite");
  }
  const int corners_x = depth.width + 1;
  corner_rays_.resize(3, static_cast<Eigen::Index>(corners_x) * (depth.height + 1));
  for (int v = 0; v <= depth.height; ++v) {
    for (int u = 0; u < corners_x; ++u) {
      corner_rays_.col(static_cast<Eigen::Index>(v) * corners_x + u) =
          r * Eigen::Vector3d((u - 0.5 - depth.cx) / depth.fx, (v - 0.5 - depth.cy) / depth.fy, 1.0);
    }
  }
}

bool DepthRegistration::registerDepth(const cv::Mat& depth, cv::Mat& out) const {
  if (depth.type() != CV_32FC1 || depth.cols != depth_.width || depth.rows != depth_.height) return false;
  const float far = std::numeric_limits<float>::infinity();
  out.create(colour_.height, colour_.width, CV_32FC1);
  out.setTo(far);
  const Eigen::Vector3d t = colour_from_depth_.translation();
  const Eigen::Index corners_x = depth.cols + 1;
  for (int v = 0; v < depth.rows; ++v) {
    const float* row = depth.ptr<float>(v);
    for (int u = 0; u < depth.cols; ++u) {
      const double z = row[u];
      if (!(z > 0.0) || !std::isfinite(z)) continue;
      // The pixel's four corners at its depth, in the colour camera: the footprint it covers there.
      double u_lo = std::numeric_limits<double>::infinity(), u_hi = -u_lo, v_lo = u_lo, v_hi = -u_lo, zc = 0.0;
      bool in_front = true;
      for (const Eigen::Index du : {0, 1}) {
        for (const Eigen::Index dv : {0, 1}) {
          const Eigen::Vector3d p = z * corner_rays_.col((v + dv) * corners_x + u + du) + t;
          if (!(p.z() > 0.0)) {
            in_front = false;
            break;
          }
          const double uc = colour_.fx * p.x() / p.z() + colour_.cx, vc = colour_.fy * p.y() / p.z() + colour_.cy;
          u_lo = std::min(u_lo, uc);
          u_hi = std::max(u_hi, uc);
          v_lo = std::min(v_lo, vc);
          v_hi = std::max(v_hi, vc);
          zc += 0.25 * p.z();
        }
        if (!in_front) break;
      }
      if (!in_front) continue;
      // Pixel centres inside the footprint (at least the one nearest its centre).
      const int c0 = std::max(0, static_cast<int>(std::ceil(u_lo - 1e-9))),
                c1 = std::min(colour_.width - 1, static_cast<int>(std::floor(u_hi + 1e-9)));
      const int r0 = std::max(0, static_cast<int>(std::ceil(v_lo - 1e-9))),
                r1 = std::min(colour_.height - 1, static_cast<int>(std::floor(v_hi + 1e-9)));
      const auto depth_value = static_cast<float>(zc);
      if (c0 > c1 || r0 > r1) {
        const long cu = std::lround(0.5 * (u_lo + u_hi)), cv = std::lround(0.5 * (v_lo + v_hi));
        if (cu < 0 || cv < 0 || cu >= colour_.width || cv >= colour_.height) continue;
        float& cell = out.at<float>(static_cast<int>(cv), static_cast<int>(cu));
        cell = std::min(cell, depth_value);
        continue;
      }
      for (int rr = r0; rr <= r1; ++rr) {
        float* cells = out.ptr<float>(rr);
        for (int cc = c0; cc <= c1; ++cc) cells[cc] = std::min(cells[cc], depth_value);
      }
    }
  }
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int v = 0; v < out.rows; ++v) {
    float* row = out.ptr<float>(v);
    for (int u = 0; u < out.cols; ++u) {
      if (row[u] == far) row[u] = nan;
    }
  }
  return true;
}

}  // namespace bimanual_skills::vision
