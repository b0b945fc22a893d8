#include "bimanual_skills/tasks/scarf.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <stdexcept>

namespace bimanual_skills::tasks {

namespace {

const sim::Obstacle& part(const std::vector<sim::Obstacle>& obstacles, const std::string& name,
                          sim::Obstacle::Shape shape) {
  for (const sim::Obstacle& o : obstacles) {
    if (o.name != name) continue;
    if (o.shape != shape) {
      throw std::invalid_argument("mannequin: its '" + name + "' must be a " + sim::toString(shape));
    }
    return o;
  }
  throw std::invalid_argument("mannequin: the scene has no obstacle named '" + name + "'");
}

/// Angle wrapped into (−π, π].
double wrapAngle(double a) {
  return std::remainder(a, 2.0 * M_PI);
}

}  // namespace

Mannequin Mannequin::fromObstacles(const std::vector<sim::Obstacle>& obstacles) {
  const sim::Obstacle& neck = part(obstacles, "neck", sim::Obstacle::Shape::Cylinder);
  const sim::Obstacle& shoulders = part(obstacles, "shoulders", sim::Obstacle::Shape::Box);
  const sim::Obstacle& nose = part(obstacles, "nose_mark", sim::Obstacle::Shape::Sphere);
  if (std::abs(neck.pose.linear().col(2).z()) < 1.0 - 1e-6) {
    throw std::invalid_argument("mannequin: its 'neck' must stand upright (its cylinder's axis along world z)");
  }
  Mannequin m;
  m.neck = neck.pose.translation();
  m.neck_radius = neck.size[0];
  m.neck_length = neck.size[1];
  m.shoulders_top = shoulders.pose.translation().z() + 0.5 * shoulders.size.z();
  m.nose = nose.pose.translation();
  Eigen::Vector3d facing = m.nose - m.neck;
  facing.z() = 0.0;
  if (facing.norm() < 1e-6) throw std::invalid_argument("mannequin: its 'nose_mark' must be in front of its neck");
  m.facing = facing.normalized();
  m.right = m.facing.cross(Eigen::Vector3d::UnitZ());
  return m;
}

ScarfTruth scarfTruth(const Mannequin& m, const Eigen::Matrix3Xd& vertices, int nodes_x, int nodes_y) {
  if (nodes_x < 2 || nodes_y < 1 || vertices.cols() != static_cast<Eigen::Index>(nodes_x) * nodes_y ||
      !vertices.allFinite()) {
    throw std::invalid_argument("scarf truth: the mesh needs nodes_x · nodes_y finite vertices");
  }
  ScarfTruth t;
  // The centre line: the mean across the width of each column along the length.
  Eigen::Matrix3Xd line = Eigen::Matrix3Xd::Zero(3, nodes_x);
  for (int j = 0; j < nodes_y; ++j) line += vertices.middleCols(static_cast<Eigen::Index>(j) * nodes_x, nodes_x);
  line /= static_cast<double>(nodes_y);
  // Its turning about the neck's axis over the segments close to the neck (within 0.12 m of its surface, in its
  // height band extended by 5 cm).
  const double reach = m.neck_radius + 0.12, low = m.neck.z() - 0.5 * m.neck_length - 0.05,
               high = m.neck.z() + 0.5 * m.neck_length + 0.05;
  const auto near = [&](const Eigen::Vector3d& p) {
    return (p - m.neck).head<2>().norm() < reach && p.z() > low && p.z() < high;
  };
  for (int i = 0; i + 1 < nodes_x; ++i) {
    const Eigen::Vector3d a = line.col(i), b = line.col(i + 1);
    if (!near(a) || !near(b)) continue;
    const double angle_a = std::atan2(a.y() - m.neck.y(), a.x() - m.neck.x());
    const double angle_b = std::atan2(b.y() - m.neck.y(), b.x() - m.neck.x());
    t.winding += wrapAngle(angle_b - angle_a);
  }
  t.wrapped = std::abs(t.winding) >= M_PI;
  // Hanging: the centre line's points below the shoulders' top and off the neck's column, on the mannequin's right
  // or left (the centre line, not the edges: a 15 cm wide end hanging in front of the chest reaches both sides of
  // a 9 cm neck with its edges).
  for (int i = 0; i < nodes_x; ++i) {
    const Eigen::Vector3d p = line.col(i);
    if (p.z() >= m.shoulders_top - kHangingDrop) continue;
    const double side = (p - m.neck).dot(m.right);
    if (side > m.neck_radius) ++t.hanging_right;
    if (side < -m.neck_radius) ++t.hanging_left;
  }
  t.fallen = (vertices.row(2).array() <= m.shoulders_top).all();
  t.success = t.wrapped && t.hanging_right > 0 && t.hanging_left == 0 && !t.fallen;
  return t;
}

namespace {

/// Image rows from the nose mark's centre down to `point` [px].
double belowTheNose(const Mannequin& m, const vision::PinholeCamera& camera, const Eigen::Vector3d& point) {
  Eigen::Vector3d nose, at;
  if (!camera.project(m.nose, nose) || !camera.project(point, at) || !(at.y() > nose.y())) {
    throw std::invalid_argument("scarf camera: the camera does not see the neck below the nose mark");
  }
  return at.y() - nose.y();
}

}  // namespace

double referenceDistance(const Mannequin& m, const vision::PinholeCamera& camera) {
  return belowTheNose(m, camera, m.neck + m.facing * m.neck_radius + Eigen::Vector3d(0.0, 0.0, 0.5 * m.neck_length));
}

double hangingLevel(const Mannequin& m, const vision::PinholeCamera& camera) {
  Eigen::Vector3d point = m.neck + m.facing * m.neck_radius;
  point.z() = m.shoulders_top - kHangingDrop;
  return belowTheNose(m, camera, point);
}

void ScarfCameraConfig::validate(const std::string& where) const {
  if (!(d_ref > 0.0) || !std::isfinite(d_ref)) throw std::invalid_argument(where + ": d_ref must be > 0 px");
  if (!(alpha > 0.0) || !std::isfinite(alpha)) throw std::invalid_argument(where + ": alpha must be > 0");
  if (!(distance_weight >= 0.0) || !(hanging_weight >= 0.0) || !std::isfinite(distance_weight) ||
      !std::isfinite(hanging_weight)) {
    throw std::invalid_argument(where + ": the weights must be finite and >= 0");
  }
  if (!(hanging_level >= 0.0) || !std::isfinite(hanging_level)) {
    throw std::invalid_argument(where + ": hanging_level must be >= 0 px");
  }
  if (band < 1) throw std::invalid_argument(where + ": band must be >= 1 px");
  if (min_pixels < 1) throw std::invalid_argument(where + ": min_pixels must be >= 1");
}

ScarfCameraTerms scarfCameraTerms(const cv::Mat& bgr, const ScarfCameraConfig& config) {
  config.validate("scarf camera cost");
  if (bgr.empty() || bgr.type() != CV_8UC3) throw std::invalid_argument("scarf camera cost: needs a bgr8 image");
  cv::Mat hsv, scarf, nose;
  cv::cvtColor(bgr, hsv, cv::COLOR_BGR2HSV);
  cv::inRange(hsv, config.scarf_low, config.scarf_high, scarf);
  cv::inRange(hsv, config.nose_low, config.nose_high, nose);
  ScarfCameraTerms t;
  const cv::Moments nose_moments = cv::moments(nose, true);
  t.nose_seen = nose_moments.m00 >= config.min_pixels;
  t.scarf_seen = cv::countNonZero(scarf) >= config.min_pixels;
  t.d = static_cast<double>(bgr.rows);
  if (t.nose_seen) {
    t.nose_u = nose_moments.m10 / nose_moments.m00;
    t.nose_v = nose_moments.m01 / nose_moments.m00;
    const int u0 = std::max(0, static_cast<int>(t.nose_u) - config.band);
    const int u1 = std::min(bgr.cols - 1, static_cast<int>(t.nose_u) + config.band);
    const int v_start = std::max(0, static_cast<int>(std::ceil(t.nose_v)));
    for (int v = v_start; v < bgr.rows && t.d == bgr.rows; ++v) {
      const unsigned char* row = scarf.ptr<unsigned char>(v);
      for (int u = u0; u <= u1; ++u) {
        if (row[u] != 0) {
          t.d = v - t.nose_v;
          break;
        }
      }
    }
    // Hanging: the scarf well below the neck (hanging_level under the nose), off the nose's column band.
    const int hang_from =
        static_cast<int>(t.nose_v + (config.hanging_level > 0.0 ? config.hanging_level : 2.0 * config.d_ref));
    for (int v = std::max(0, hang_from); v < bgr.rows; ++v) {
      const unsigned char* row = scarf.ptr<unsigned char>(v);
      for (int u = 0; u < bgr.cols; ++u) {
        if (row[u] == 0) continue;
        const bool image_left = u<t.nose_u - config.band, image_right = u> t.nose_u + config.band;
        if (image_left) (config.right_is_image_left ? t.right_pixels : t.left_pixels)++;
        if (image_right) (config.right_is_image_left ? t.left_pixels : t.right_pixels)++;
      }
    }
  }
  t.hanging = t.right_pixels >= config.min_pixels && t.left_pixels < config.min_pixels ? 0 : 1;
  const double ratio = (t.d - config.d_ref) / config.d_ref;
  const double base = config.printed ? std::max(ratio, 1.0) : std::abs(ratio);
  t.c_distance = config.distance_weight * std::pow(base, config.alpha);
  t.c_cam = t.c_distance + config.hanging_weight * t.hanging;
  return t;
}

}  // namespace bimanual_skills::tasks
