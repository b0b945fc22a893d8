#include "bimanual_skills/vision/perspective_camera.hpp"

#include "render_support.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

namespace bimanual_skills::vision {

namespace {

[[noreturn]] void fail(const char* where, const std::string& what) {
  throw std::invalid_argument(std::string(where) + ": " + what);
}

constexpr unsigned char kBackground = 0, kCloth = 1, kNoReturn = 2, kMoving = 4;
constexpr double kNear = 0.05;  ///< Triangles with a vertex nearer than this [m] (or behind) are not drawn.
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

bool rigid(const Eigen::Isometry3d& pose) {
  return pose.matrix().allFinite() &&
         (pose.linear().transpose() * pose.linear() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-6 &&
         std::abs(pose.linear().determinant() - 1.0) < 1e-6;
}

}  // namespace

// ---------------------------------------------------------------------------------------------- PinholeCamera

PinholeCamera PinholeCamera::lookingAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                                       const Eigen::Vector3d& up) {
  const Eigen::Vector3d view = target - eye;
  if (!eye.allFinite() || !target.allFinite() || !up.allFinite() || view.norm() < 1e-9) {
    throw std::invalid_argument("PinholeCamera::lookingAt: eye and target must be finite and apart");
  }
  const Eigen::Vector3d z = view.normalized();
  const Eigen::Vector3d down = -(up - up.dot(z) * z);  // image y: against `up`, across the view
  if (down.norm() < 1e-6) throw std::invalid_argument("PinholeCamera::lookingAt: the view is along `up`");
  const Eigen::Vector3d y = down.normalized(), x = y.cross(z);
  PinholeCamera camera;
  camera.pose.linear().col(0) = x;
  camera.pose.linear().col(1) = y;
  camera.pose.linear().col(2) = z;
  camera.pose.translation() = eye;
  return camera;
}

bool PinholeCamera::project(const Eigen::Vector3d& world, Eigen::Vector3d& uvz) const noexcept {
  const Eigen::Vector3d p = pose.inverse(Eigen::Isometry) * world;
  if (!(p.z() > 0.0)) return false;
  uvz = Eigen::Vector3d(fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy, p.z());
  return true;
}

bool PinholeCamera::usable() const noexcept {
  return fx > 0.0 && fy > 0.0 && std::isfinite(fx) && std::isfinite(fy) && std::isfinite(cx) && std::isfinite(cy) &&
         rigid(pose);
}

void PinholeCamera::validate(const char* where) const {
  if (width < 8 || height < 8 || width > 8192 || height > 8192) fail(where, "image size must be 8-8192 pixels");
  if (!(fx > 0.0) || !(fy > 0.0) || !std::isfinite(fx) || !std::isfinite(fy)) {
    fail(where, "focal lengths fx, fy must be finite and > 0");
  }
  if (!std::isfinite(cx) || !std::isfinite(cy)) fail(where, "principal point cx, cy must be finite");
  if (!rigid(pose)) fail(where, "pose must be a finite rigid transform");
  if (!(min_range > 0.0) || !(max_range > min_range) || !std::isfinite(max_range)) {
    fail(where, "range must satisfy 0 < min_range < max_range < inf");
  }
}

void DepthSensorNoise::validate(const char* where) const {
  const auto check = [where](double value, double low, double high, const char* name) {
    if (!std::isfinite(value) || value < low || value > high) {
      fail(where, std::string(name) + " must lie in [" + std::to_string(low) + ", " + std::to_string(high) + "]");
    }
  };
  check(axial, 0.0, 1.0, "noise axial");
  check(dropout, 0.0, 1.0, "noise dropout");
  check(edge_jump, 0.0, 10.0, "noise edge_jump");
  check(edge_dropout, 0.0, 1.0, "noise edge_dropout");
  check(grazing, 0.0, 1.0, "noise grazing");
  check(colour_stddev, 0.0, 255.0, "noise colour_stddev");
}

// ---------------------------------------------------------------------------------------- PerspectiveRenderer

PerspectiveRenderer::PerspectiveRenderer(const ClothRendererParameters& scene, const PinholeCamera& camera,
                                         const DepthSensorNoise& noise)
    : scene_(scene), camera_(camera), noise_(noise), normal_quantiles_(normalQuantiles()) {
  scene_.validate("PerspectiveRenderer");
  camera_.validate("PerspectiveRenderer");
  noise_.validate("PerspectiveRenderer");
  world_to_camera_ = camera_.pose.inverse(Eigen::Isometry);
  light_ = scene_.light_direction.normalized();
  const int rows = camera_.height, columns = camera_.width;
  for (cv::Mat* m : {&background_bgr_, &bgr_}) m->create(rows, columns, CV_8UC3);
  for (cv::Mat* m : {&background_z_, &z_, &depth_}) m->create(rows, columns, CV_32FC1);
  for (cv::Mat* m : {&background_flags_, &flags_, &mask_, &moving_mask_}) m->create(rows, columns, CV_8UC1);
  // The background: nothing (no return) until the floor and the table box are drawn, once.
  bgr_.setTo(cv::Scalar::all(0));
  z_.setTo(cv::Scalar::all(std::numeric_limits<float>::infinity()));
  flags_.setTo(cv::Scalar::all(kNoReturn));
  const TableTop& table = scene_.table;
  const double floor = scene_.floor_height, top = table.height;
  // The floor in 0.5 m tiles over 8 m × 8 m around the table (tiles behind the camera are skipped whole).
  for (int i = -8; i < 8; ++i) {
    for (int j = -8; j < 8; ++j) {
      const Eigen::Vector3d a(table.centre.x() + 0.5 * i, table.centre.y() + 0.5 * j, floor);
      const Eigen::Vector3d b = a + Eigen::Vector3d(0.5, 0.0, 0.0), c = a + Eigen::Vector3d(0.5, 0.5, 0.0),
                            d = a + Eigen::Vector3d(0.0, 0.5, 0.0);
      draw(a, b, c, scene_.floor_colour, kBackground);
      draw(a, c, d, scene_.floor_colour, kBackground);
    }
  }
  // The table (when the scene has one): its top and four sides.
  if (scene_.has_table) {
    const double hx = 0.5 * table.size.x(), hy = 0.5 * table.size.y();
    const auto corner = [&](double sx, double sy, double z) {
      return Eigen::Vector3d(table.centre.x() + sx * hx, table.centre.y() + sy * hy, z);
    };
    draw(corner(-1, -1, top), corner(1, -1, top), corner(1, 1, top), scene_.table_colour, kBackground);
    draw(corner(-1, -1, top), corner(1, 1, top), corner(-1, 1, top), scene_.table_colour, kBackground);
    const double sides[4][4] = {{-1, -1, 1, -1}, {1, -1, 1, 1}, {1, 1, -1, 1}, {-1, 1, -1, -1}};
    for (const auto& s : sides) {
      const Eigen::Vector3d a = corner(s[0], s[1], floor), b = corner(s[2], s[3], floor), c = corner(s[2], s[3], top),
                            d = corner(s[0], s[1], top);
      draw(a, b, c, scene_.table_colour, kBackground);
      draw(a, c, d, scene_.table_colour, kBackground);
    }
  }
  // The solids (a mannequin), static: part of the background too.
  for (const SceneSolid& solid : scene_.solids) {
    for (const Eigen::Matrix3d& t : solidTriangles(solid))
      draw(t.col(0), t.col(1), t.col(2), solid.colour, kBackground);
  }
  bgr_.copyTo(background_bgr_);
  z_.copyTo(background_z_);
  flags_.copyTo(background_flags_);
  depth_.setTo(cv::Scalar::all(kNaN));
  mask_.setTo(cv::Scalar::all(0));
  moving_mask_.setTo(cv::Scalar::all(0));
}

int PerspectiveRenderer::addMovingSolid(const SceneSolid& solid) {
  SceneSolid local = solid;
  local.pose.setIdentity();
  moving_.push_back(MovingSolid{solidTriangles(local), solid.colour, Eigen::Isometry3d::Identity(), false});
  return static_cast<int>(moving_.size()) - 1;
}

void PerspectiveRenderer::setMovingPose(int index, const Eigen::Isometry3d& pose) noexcept {
  if (index < 0 || index >= static_cast<int>(moving_.size())) return;
  MovingSolid& solid = moving_[static_cast<std::size_t>(index)];
  solid.visible = rigid(pose);
  if (solid.visible) solid.pose = pose;
}

/// Draws a triangle into the z buffer: perspective-correct depth (1/z is affine in the image), flat Lambert shading,
/// no return where the surface is seen at a grazing angle.
void PerspectiveRenderer::draw(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                               const Eigen::Vector3d& rgb, unsigned char kind) noexcept {
  const Eigen::Vector3d pa = world_to_camera_ * a, pb = world_to_camera_ * b, pc = world_to_camera_ * c;
  if (pa.z() < kNear || pb.z() < kNear || pc.z() < kNear) return;
  const Eigen::Vector3d normal = (b - a).cross(c - a);
  const double normal_norm = normal.norm();
  if (!(normal_norm > 0.0)) return;
  const double xa = camera_.fx * pa.x() / pa.z() + camera_.cx, ya = camera_.fy * pa.y() / pa.z() + camera_.cy;
  const double xb = camera_.fx * pb.x() / pb.z() + camera_.cx, yb = camera_.fy * pb.y() / pb.z() + camera_.cy;
  const double xc = camera_.fx * pc.x() / pc.z() + camera_.cx, yc = camera_.fy * pc.y() / pc.z() + camera_.cy;
  const double area = (xb - xa) * (yc - ya) - (yb - ya) * (xc - xa);
  if (std::abs(area) < 1e-12) return;
  const int columns = camera_.width, rows = camera_.height;
  const int u0 = static_cast<int>(std::clamp(std::ceil(std::min({xa, xb, xc})), 0.0, double(columns)));
  const int u1 = static_cast<int>(std::clamp(std::floor(std::max({xa, xb, xc})), -1.0, double(columns - 1)));
  const int v0 = static_cast<int>(std::clamp(std::ceil(std::min({ya, yb, yc})), 0.0, double(rows)));
  const int v1 = static_cast<int>(std::clamp(std::floor(std::max({ya, yb, yc})), -1.0, double(rows - 1)));
  if (u0 > u1 || v0 > v1) return;
  const double shading = scene_.ambient + (1.0 - scene_.ambient) * std::abs(normal.dot(light_)) / normal_norm;
  const cv::Vec3b colour = shade(rgb, shading);
  // The ray to the triangle's centroid against its normal: how obliquely the sensor sees it.
  const Eigen::Vector3d ray = (a + b + c) / 3.0 - camera_.pose.translation();
  const bool grazing = std::abs(normal.dot(ray)) < noise_.grazing * normal_norm * ray.norm();
  const unsigned char flags = static_cast<unsigned char>(kind | (grazing ? kNoReturn : 0));
  const double ia = 1.0 / pa.z(), ib = 1.0 / pb.z(), ic = 1.0 / pc.z(), inv_area = 1.0 / area;
  for (int v = v0; v <= v1; ++v) {
    const double y = v;
    cv::Vec3b* bgr_row = bgr_.ptr<cv::Vec3b>(v);
    float* z_row = z_.ptr<float>(v);
    unsigned char* flag_row = flags_.ptr<unsigned char>(v);
    for (int u = u0; u <= u1; ++u) {
      const double x = u;
      const double wa = ((xb - x) * (yc - y) - (yb - y) * (xc - x)) * inv_area;
      const double wb = ((xc - x) * (ya - y) - (yc - y) * (xa - x)) * inv_area;
      const double wc = 1.0 - wa - wb;
      if (wa < 0.0 || wb < 0.0 || wc < 0.0) continue;
      const double z = 1.0 / (wa * ia + wb * ib + wc * ic);
      if (!(z < z_row[u])) continue;
      z_row[u] = static_cast<float>(z);
      bgr_row[u] = colour;
      flag_row[u] = flags;
    }
  }
}

VisionStatus PerspectiveRenderer::render(const Eigen::Ref<const Eigen::Matrix3Xd>& vertices,
                                         const Eigen::Ref<const Eigen::Matrix3Xi>& triangles) noexcept {
  std::memcpy(bgr_.data, background_bgr_.data, bgr_.total() * bgr_.elemSize());
  std::memcpy(z_.data, background_z_.data, z_.total() * z_.elemSize());
  std::memcpy(flags_.data, background_flags_.data, flags_.total() * flags_.elemSize());
  for (const MovingSolid& solid : moving_) {
    if (!solid.visible) continue;
    for (const Eigen::Matrix3d& t : solid.triangles) {
      draw(solid.pose * t.col(0), solid.pose * t.col(1), solid.pose * t.col(2), solid.colour, kMoving);
    }
  }
  VisionStatus status = VisionStatus::Ok;
  if (vertices.cols() == 0 || triangles.cols() == 0) {
    status = VisionStatus::EmptyMesh;
  } else if (!vertices.allFinite()) {
    status = VisionStatus::NonFiniteVertex;
  } else {
    for (Eigen::Index t = 0; t < triangles.cols() && status == VisionStatus::Ok; ++t) {
      for (int k = 0; k < 3; ++k) {
        if (triangles(k, t) < 0 || triangles(k, t) >= vertices.cols()) status = VisionStatus::BadTriangle;
      }
    }
  }
  if (status == VisionStatus::Ok) {
    for (Eigen::Index t = 0; t < triangles.cols(); ++t) {
      draw(vertices.col(triangles(0, t)), vertices.col(triangles(1, t)), vertices.col(triangles(2, t)),
           scene_.cloth_colour, kCloth);
    }
  }
  finish(nullptr);
  return status;
}

VisionStatus PerspectiveRenderer::render(const Eigen::Ref<const Eigen::Matrix3Xd>& vertices,
                                         const Eigen::Ref<const Eigen::Matrix3Xi>& triangles,
                                         std::mt19937& rng) noexcept {
  const VisionStatus status = render(vertices, triangles);
  finish(&rng);
  return status;
}

/// The depth image and the cloth mask from the z buffer; with `rng`, the sensor's errors (lost pixels at random and
/// at depth edges, σ_z = k z², colour noise).
void PerspectiveRenderer::finish(std::mt19937* rng) noexcept {
  const int rows = camera_.height, columns = camera_.width;
  SplitMix64 generator{0};
  if (rng) {
    const std::uint64_t high = (*rng)(), low = (*rng)();
    generator.state = (high << 32) | low;
  }
  const float* normal = normal_quantiles_.data();
  const auto uniform = [](std::uint64_t bits) { return static_cast<double>(bits & 0xffffu) / 65536.0; };
  const auto edge = [&](int v, int u, float z) {
    const float jump = static_cast<float>(noise_.edge_jump);
    const auto far = [&](int vv, int uu) {
      if (vv < 0 || uu < 0 || vv >= rows || uu >= columns) return false;
      const float other = z_.at<float>(vv, uu);
      return !std::isfinite(other) || std::abs(other - z) > jump;
    };
    return far(v, u - 1) || far(v, u + 1) || far(v - 1, u) || far(v + 1, u);
  };
  cloth_pixels_ = 0;
  for (int v = 0; v < rows; ++v) {
    const float* z_row = z_.ptr<float>(v);
    const unsigned char* flag_row = flags_.ptr<unsigned char>(v);
    float* depth_row = depth_.ptr<float>(v);
    unsigned char* mask_row = mask_.ptr<unsigned char>(v);
    unsigned char* moving_row = moving_mask_.ptr<unsigned char>(v);
    unsigned char* bgr_row = bgr_.ptr<unsigned char>(v);
    for (int u = 0; u < columns; ++u) {
      const float z = z_row[u];
      const bool cloth = (flag_row[u] & kCloth) != 0;
      mask_row[u] = cloth ? 255 : 0;
      moving_row[u] = (flag_row[u] & kMoving) != 0 ? 255 : 0;
      cloth_pixels_ += cloth ? 1 : 0;
      bool lost = (flag_row[u] & kNoReturn) != 0 || !(z >= camera_.min_range && z <= camera_.max_range);
      float d = z;
      if (rng) {
        const std::uint64_t bits = generator(), more = generator();
        lost = lost || uniform(more) < noise_.dropout ||
               (noise_.edge_dropout > 0.0 && uniform(more >> 16) < noise_.edge_dropout && edge(v, u, z));
        d += static_cast<float>(noise_.axial * z * z) * normal[bits & 0xffffu];
        for (int k = 0; k < 3; ++k) {
          unsigned char& channel = bgr_row[3 * u + k];
          const float draw = normal[(bits >> (16 * (k + 1))) & 0xffffu];
          channel = cv::saturate_cast<unsigned char>(float(channel) + float(noise_.colour_stddev) * draw);
        }
      }
      depth_row[u] = lost ? kNaN : d;
    }
  }
}

// ---------------------------------------------------------------------------------------- HeightMapProjector

HeightMapProjector::HeightMapProjector(const TopDownCamera& map, int fill_cells) : map_(map), fill_cells_(fill_cells) {
  map_.validate("HeightMapProjector");
  if (fill_cells < 0 || fill_cells > 100) throw std::invalid_argument("HeightMapProjector: fill_cells must be 0-100");
  for (cv::Mat* m : {&bgr_, &next_bgr_}) m->create(map_.rows, map_.columns, CV_8UC3);
  for (cv::Mat* m : {&depth_, &next_depth_}) m->create(map_.rows, map_.columns, CV_32FC1);
}

VisionStatus HeightMapProjector::project(const cv::Mat& bgr, const cv::Mat& depth,
                                         const PinholeCamera& camera) noexcept {
  coverage_ = HeightMapCoverage{};
  const float inf = std::numeric_limits<float>::infinity();
  // +inf: no point yet (depth is the distance down from the map's plane). Plain loops: OpenCV's setTo allocates on
  // its first call in a thread.
  std::fill(depth_.ptr<float>(), depth_.ptr<float>() + depth_.total(), inf);
  std::memset(bgr_.data, 0, bgr_.total() * bgr_.elemSize());
  if (bgr.type() != CV_8UC3 || depth.type() != CV_32FC1 || bgr.rows != camera.height || bgr.cols != camera.width ||
      depth.rows != camera.height || depth.cols != camera.width) {
    return VisionStatus::WrongImageSize;
  }
  if (!camera.usable()) return VisionStatus::BadCameraPose;
  const Eigen::Matrix3d r = camera.pose.linear();
  const Eigen::Vector3d t = camera.pose.translation();
  for (int v = 0; v < depth.rows; ++v) {
    const float* z_row = depth.ptr<float>(v);
    const cv::Vec3b* colour_row = bgr.ptr<cv::Vec3b>(v);
    const double ray_y = (v - camera.cy) / camera.fy;
    for (int u = 0; u < depth.cols; ++u) {
      const double z = z_row[u];
      if (!(z > 0.0) || !std::isfinite(z)) continue;
      const Eigen::Vector3d p = r * Eigen::Vector3d((u - camera.cx) / camera.fx * z, ray_y * z, z) + t;
      const Eigen::Vector2d xy = map_.project(p);
      const int column = static_cast<int>(std::floor(xy.x())), row = static_cast<int>(std::floor(xy.y()));
      if (column < 0 || row < 0 || column >= map_.columns || row >= map_.rows) continue;
      ++coverage_.points;
      float& cell = depth_.at<float>(row, column);
      const float down = static_cast<float>(map_.height - p.z());
      if (down < cell) {
        if (cell == inf) ++coverage_.observed;
        cell = down;
        bgr_.at<cv::Vec3b>(row, column) = colour_row[u];
      }
    }
  }
  if (coverage_.points == 0) return VisionStatus::NoCloth;
  // Gaps between the points and small shadows: a cell without a point takes its highest observed neighbour.
  float lowest = 0.0f;
  for (int v = 0; v < map_.rows; ++v) {
    for (int u = 0; u < map_.columns; ++u) {
      const float d = depth_.at<float>(v, u);
      if (d != inf) lowest = std::max(lowest, d);
    }
  }
  for (int pass = 0; pass < fill_cells_; ++pass) {
    std::memcpy(next_depth_.data, depth_.data, depth_.total() * depth_.elemSize());
    std::memcpy(next_bgr_.data, bgr_.data, bgr_.total() * bgr_.elemSize());
    int filled = 0;
    for (int v = 0; v < map_.rows; ++v) {
      for (int u = 0; u < map_.columns; ++u) {
        if (depth_.at<float>(v, u) != inf) continue;
        float best = inf;
        cv::Vec3b colour;
        for (int dv = -1; dv <= 1; ++dv) {
          for (int du = -1; du <= 1; ++du) {
            const int vv = v + dv, uu = u + du;
            if (vv < 0 || uu < 0 || vv >= map_.rows || uu >= map_.columns) continue;
            const float d = depth_.at<float>(vv, uu);
            if (d < best) {
              best = d;
              colour = bgr_.at<cv::Vec3b>(vv, uu);
            }
          }
        }
        if (best == inf) continue;
        next_depth_.at<float>(v, u) = best;
        next_bgr_.at<cv::Vec3b>(v, u) = colour;
        ++filled;
      }
    }
    std::memcpy(depth_.data, next_depth_.data, depth_.total() * depth_.elemSize());
    std::memcpy(bgr_.data, next_bgr_.data, bgr_.total() * bgr_.elemSize());
    coverage_.filled += filled;
    if (filled == 0) break;
  }
  for (int v = 0; v < map_.rows; ++v) {
    float* row = depth_.ptr<float>(v);
    for (int u = 0; u < map_.columns; ++u) {
      if (row[u] != inf) continue;
      row[u] = lowest;
      ++coverage_.unseen;
    }
  }
  return VisionStatus::Ok;
}

}  // namespace bimanual_skills::vision
