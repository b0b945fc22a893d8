#include "bimanual_skills/vision/object_locator.hpp"

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace bimanual_skills::vision {

double hueOf(const Eigen::Vector3d& rgb) noexcept {
  const double high = rgb.maxCoeff(), low = rgb.minCoeff(), chroma = high - low;
  if (!(chroma > 0.0)) return 0.0;
  double h;
  if (high == rgb[0]) {
    h = std::fmod((rgb[1] - rgb[2]) / chroma, 6.0);
  } else if (high == rgb[1]) {
    h = (rgb[2] - rgb[0]) / chroma + 2.0;
  } else {
    h = (rgb[0] - rgb[1]) / chroma + 4.0;
  }
  h *= 60.0;
  return h < 0.0 ? h + 360.0 : h;
}

namespace {

[[noreturn]] void fail(const char* where, const std::string& what) {
  throw std::invalid_argument(std::string(where) + ": " + what);
}

}  // namespace

const char* toString(LocateStatus status) noexcept {
  switch (status) {
    case LocateStatus::Ok:
      return "Ok";
    case LocateStatus::WrongImage:
      return "WrongImage";
    case LocateStatus::BadCamera:
      return "BadCamera";
    case LocateStatus::NotSeen:
      return "NotSeen";
    case LocateStatus::AtEdge:
      return "AtEdge";
    case LocateStatus::NoDepth:
      return "NoDepth";
    case LocateStatus::NoFit:
      return "NoFit";
  }
  return "Unknown";
}

void ObjectLocatorConfig::validate(const char* where) const {
  const auto positive = [](double v, double high) { return std::isfinite(v) && v > 0.0 && v <= high; };
  const int dimensions = shape.shape == SceneSolid::Shape::Box ? 3 : shape.shape == SceneSolid::Shape::Cylinder ? 2 : 1;
  for (int i = 0; i < dimensions; ++i) {
    if (!positive(shape.size[i], 10.0)) fail(where, "the object's size must be > 0 and at most 10 m");
  }
  if (!(hue >= 0.0 && hue < 360.0)) fail(where, "hue must lie in [0, 360) degrees");
  if (!(hue_tolerance > 0.0 && hue_tolerance <= 90.0)) fail(where, "hue_tolerance must lie in (0, 90] degrees");
  if (!(min_saturation >= 0.0 && min_saturation <= 1.0)) fail(where, "min_saturation must lie in [0, 1]");
  if (!(min_value >= 0.0 && min_value <= 1.0)) fail(where, "min_value must lie in [0, 1]");
  if (min_pixels < 1 || min_pixels > 1000000) fail(where, "min_pixels must lie in [1, 10^6]");
  if (min_points < 4 || min_points > max_points) fail(where, "min_points must lie in [4, max_points]");
  if (max_points > 100000) fail(where, "max_points must be at most 10^5");
  if (!positive(min_stddev, 1.0)) fail(where, "min_stddev must lie in (0, 1] m");
  if (iterations < 1 || iterations > 100) fail(where, "iterations must lie in [1, 100]");
  if (!positive(outlier_distance, 1.0)) fail(where, "outlier_distance must lie in (0, 1] m");
}

ObjectLocator::ObjectLocator(const ObjectLocatorConfig& config) : config_(config) {
  config_.validate("ObjectLocator");
  kernel_ = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(3, 3));
  points_.reserve(static_cast<std::size_t>(config_.max_points));
  scratch_.reserve(static_cast<std::size_t>(config_.max_points));
}

double ObjectLocator::surfaceDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& centre) const noexcept {
  const Eigen::Vector3d d = p - centre;
  const Eigen::Vector3d& size = config_.shape.size;
  switch (config_.shape.shape) {
    case SceneSolid::Shape::Sphere:
      return d.norm() - size[0];
    case SceneSolid::Shape::Cylinder: {
      const Eigen::Vector2d q(d.head<2>().norm() - size[0], std::abs(d.z()) - 0.5 * size[1]);
      return std::min(q.maxCoeff(), 0.0) + q.cwiseMax(0.0).norm();
    }
    case SceneSolid::Shape::Box:
      break;
  }
  const Eigen::Vector3d q = d.cwiseAbs() - 0.5 * size;
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

LocateStatus ObjectLocator::locate(const cv::Mat& bgr, const cv::Mat& depth, const PinholeCamera& camera,
                                   ObjectMeasurement& measurement, const PinholeCamera* depth_view) {
  measurement = ObjectMeasurement{};
  if (bgr.type() != CV_8UC3 || depth.type() != CV_32FC1 || bgr.rows != camera.height || bgr.cols != camera.width ||
      depth.size() != bgr.size()) {
    return LocateStatus::WrongImage;
  }
  if (!camera.usable() || (depth_view != nullptr && !depth_view->usable())) return LocateStatus::BadCamera;
  // The object's colour in HSV (OpenCV: H in [0, 180), S and V in [0, 255]); a hue range across 0 is two ranges.
  cv::cvtColor(bgr, hsv_, cv::COLOR_BGR2HSV);
  const double h = 0.5 * config_.hue, tolerance = 0.5 * config_.hue_tolerance;
  const double s = 255.0 * config_.min_saturation, v = 255.0 * config_.min_value;
  const auto range = [&](double low, double high, cv::Mat& out) {
    cv::inRange(hsv_, cv::Scalar(low, s, v), cv::Scalar(high, 255.0, 255.0), out);
  };
  range(std::max(0.0, h - tolerance), std::min(179.0, h + tolerance), mask_);
  if (h - tolerance < 0.0 || h + tolerance > 179.0) {
    range(h - tolerance < 0.0 ? 180.0 + h - tolerance : 0.0, h - tolerance < 0.0 ? 179.0 : h + tolerance - 180.0,
          opened_);
    cv::bitwise_or(mask_, opened_, mask_);
  }
  cv::morphologyEx(mask_, opened_, cv::MORPH_OPEN, kernel_);
  opened_.copyTo(mask_);
  const int labels = cv::connectedComponentsWithStats(mask_, labels_, stats_, centroids_, 8, CV_32S);
  int best = 0, area = 0;
  for (int l = 1; l < labels; ++l) {
    if (stats_.at<int>(l, cv::CC_STAT_AREA) > area) best = l, area = stats_.at<int>(l, cv::CC_STAT_AREA);
  }
  component_.create(bgr.size(), CV_8UC1);
  component_.setTo(cv::Scalar::all(0));
  measurement.pixels = area;
  if (best == 0 || area < config_.min_pixels) return LocateStatus::NotSeen;
  cv::compare(labels_, cv::Scalar(best), component_, cv::CMP_EQ);
  measurement.image_centre = Eigen::Vector2d(centroids_.at<double>(best, 0), centroids_.at<double>(best, 1));

  const int x0 = stats_.at<int>(best, cv::CC_STAT_LEFT), y0 = stats_.at<int>(best, cv::CC_STAT_TOP);
  const int x1 = x0 + stats_.at<int>(best, cv::CC_STAT_WIDTH), y1 = y0 + stats_.at<int>(best, cv::CC_STAT_HEIGHT);
  if (x0 == 0 || y0 == 0 || x1 == bgr.cols || y1 == bgr.rows) return LocateStatus::AtEdge;
  // Its depth pixels in the world, evenly subsampled to at most max_points.
  int with_depth = 0;
  float near = std::numeric_limits<float>::infinity(), far = -near;
  for (int row = y0; row < y1; ++row) {
    for (int column = x0; column < x1; ++column) {
      const float z = depth.at<float>(row, column);
      if (component_.at<unsigned char>(row, column) == 0 || !std::isfinite(z)) continue;
      ++with_depth;
      near = std::min(near, z);
      far = std::max(far, z);
    }
  }
  if (with_depth < config_.min_points) return LocateStatus::NoDepth;
  if (depth_view != nullptr) {
    // The box's corners at the nearest and farthest depth on it, as the depth camera sees them.
    for (const float z : {near, far}) {
      for (const int u : {x0, x1 - 1}) {
        for (const int v : {y0, y1 - 1}) {
          Eigen::Vector3d uvz;
          if (!depth_view->project(camera.backProject(u, v, z), uvz) || uvz.x() < 0.0 ||
              uvz.x() > depth_view->width - 1.0 || uvz.y() < 0.0 || uvz.y() > depth_view->height - 1.0) {
            return LocateStatus::AtEdge;
          }
        }
      }
    }
  }
  const double stride = std::max(1.0, static_cast<double>(with_depth) / config_.max_points);
  points_.clear();
  double next = 0.0;
  int k = 0;
  for (int row = y0; row < y1; ++row) {
    for (int column = x0; column < x1; ++column) {
      const float z = depth.at<float>(row, column);
      if (component_.at<unsigned char>(row, column) == 0 || !std::isfinite(z)) continue;
      if (k++ < next || static_cast<int>(points_.size()) >= config_.max_points) continue;
      next += stride;
      points_.push_back(camera.backProject(column, row, z));
    }
  }
  // Points far from the others' median (farther than the object's half diagonal and outlier_distance) are not on it.
  Eigen::Vector3d median;
  for (int a = 0; a < 3; ++a) {
    scratch_.clear();
    for (const Eigen::Vector3d& p : points_) scratch_.push_back(p[a]);
    const auto middle = scratch_.begin() + static_cast<std::ptrdiff_t>(scratch_.size() / 2);
    std::nth_element(scratch_.begin(), middle, scratch_.end());
    median[a] = *middle;
  }
  const Eigen::Vector3d& size = config_.shape.size;
  Eigen::Vector3d extent = size;  // the box's; a cylinder's and a ball's bounding boxes
  if (config_.shape.shape == SceneSolid::Shape::Cylinder)
    extent = Eigen::Vector3d(2.0 * size[0], 2.0 * size[0], size[1]);
  if (config_.shape.shape == SceneSolid::Shape::Sphere) extent = Eigen::Vector3d::Constant(2.0 * size[0]);
  const double reach = 0.5 * extent.norm() + config_.outlier_distance;
  points_.erase(std::remove_if(points_.begin(), points_.end(),
                               [&](const Eigen::Vector3d& p) { return (p - median).norm() > reach; }),
                points_.end());
  if (static_cast<int>(points_.size()) < config_.min_points) return LocateStatus::NoDepth;

  // A start for the fit: the points' centroid moved away from the camera by (π/4) r (the visible near side's
  // offset), its height from the top of the points for an upright cylinder or box.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double top = -1e300;
  for (const Eigen::Vector3d& p : points_) centre += p, top = std::max(top, p.z());
  centre /= static_cast<double>(points_.size());
  const double radius = config_.shape.shape == SceneSolid::Shape::Box ? 0.25 * (size[0] + size[1]) : size[0];
  Eigen::Vector3d away = centre - camera.pose.translation();
  if (config_.shape.shape == SceneSolid::Shape::Sphere) {
    centre += 0.785 * radius * away.normalized();
  } else {
    away.z() = 0.0;
    if (away.norm() > 1e-9) centre += 0.785 * radius * away.normalized();
    centre.z() = top - 0.5 * (config_.shape.shape == SceneSolid::Shape::Box ? size[2] : size[1]);
  }

  Eigen::Matrix3d normal = Eigen::Matrix3d::Identity();
  double sum = 0.0;
  if (!fit(centre, normal, sum)) return LocateStatus::NoFit;
  // Points off the fitted surface (what stands in front of it) out, and the fit again without them.
  const std::size_t before = points_.size();
  points_.erase(std::remove_if(points_.begin(), points_.end(),
                               [&](const Eigen::Vector3d& p) {
                                 return std::abs(surfaceDistance(p, centre)) > config_.outlier_distance;
                               }),
                points_.end());
  if (static_cast<int>(points_.size()) < config_.min_points) return LocateStatus::NoFit;
  if (points_.size() < before && !fit(centre, normal, sum)) return LocateStatus::NoFit;
  const int n = static_cast<int>(points_.size());
  if (!centre.allFinite()) return LocateStatus::NoFit;
  measurement.position = centre;
  measurement.points = n;
  measurement.rms = std::sqrt(sum / n);
  const double sigma = std::max(measurement.rms, config_.min_stddev);
  // The fit's covariance, plus the floor on each axis: the points' errors are not independent (the sensor's noise is
  // spatially correlated and the shape model is not exact), so n points do not shrink it as 1/n.
  const Eigen::Matrix3d inverse = (normal + 1e-9 * Eigen::Matrix3d::Identity()).inverse();
  measurement.covariance =
      sigma * sigma * inverse + config_.min_stddev * config_.min_stddev * Eigen::Matrix3d::Identity();
  measurement.covariance = 0.5 * (measurement.covariance + measurement.covariance.transpose()).eval();
  return LocateStatus::Ok;
}

bool ObjectLocator::fit(Eigen::Vector3d& centre, Eigen::Matrix3d& normal, double& sum) const noexcept {
  for (int iteration = 0; iteration < config_.iterations; ++iteration) {
    normal.setZero();
    Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
    sum = 0.0;
    for (const Eigen::Vector3d& p : points_) {
      const double r = surfaceDistance(p, centre);
      Eigen::Vector3d j;
      for (int a = 0; a < 3; ++a) {
        Eigen::Vector3d step = Eigen::Vector3d::Zero();
        step[a] = 1e-6;
        j[a] = (surfaceDistance(p, centre + step) - surfaceDistance(p, centre - step)) / 2e-6;
      }
      normal.noalias() += j * j.transpose();
      gradient += j * r;
      sum += r * r;
    }
    const Eigen::Vector3d delta = -(normal + 1e-9 * Eigen::Matrix3d::Identity()).ldlt().solve(gradient);
    if (!delta.allFinite()) return false;
    centre += delta;
    if (delta.norm() < 1e-7) break;
  }
  return centre.allFinite();
}

}  // namespace bimanual_skills::vision
