#include "bimanual_skills/vision/cloth_renderer.hpp"

#include "render_support.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace bimanual_skills::vision {

namespace {

[[noreturn]] void fail(const char* where, const std::string& what) {
  throw std::invalid_argument(std::string(where) + ": " + what);
}

bool finite(const Eigen::Vector3d& v) {
  return v.allFinite();
}

}  // namespace

void ClothRendererParameters::validate(const char* where) const {
  camera.validate(where);
  if (!std::isfinite(table.height) || !table.centre.allFinite()) fail(where, "table height and centre must be finite");
  if (!table.size.allFinite() || (table.size.array() <= 0.0).any()) fail(where, "table size must be finite and > 0");
  if (!(table.height < camera.height)) fail(where, "table height must be below the camera height");
  if (!std::isfinite(floor_height) || !(floor_height < table.height)) {
    fail(where, "floor_height must be finite and below the table height");
  }
  for (const Eigen::Vector3d* c : {&cloth_colour, &table_colour, &floor_colour}) {
    if (!c->allFinite() || (c->array() < 0.0).any() || (c->array() > 1.0).any()) {
      fail(where, "colours must be RGB triples in [0, 1]");
    }
  }
  if (!finite(light_direction) || light_direction.norm() <= 0.0) {
    fail(where, "light_direction must be finite and non-zero");
  }
  if (!std::isfinite(ambient) || ambient < 0.0 || ambient > 1.0) fail(where, "ambient must be in [0, 1]");
  for (const SceneSolid& solid : solids) {
    const int used = solid.shape == SceneSolid::Shape::Box ? 3 : solid.shape == SceneSolid::Shape::Cylinder ? 2 : 1;
    if (!solid.pose.matrix().allFinite() || !solid.size.allFinite() || (solid.size.head(used).array() <= 0.0).any()) {
      fail(where, "a solid needs a finite pose and sizes > 0");
    }
    if (!solid.colour.allFinite() || (solid.colour.array() < 0.0).any() || (solid.colour.array() > 1.0).any()) {
      fail(where, "colours must be RGB triples in [0, 1]");
    }
  }
  if (!std::isfinite(noise.depth_stddev) || noise.depth_stddev < 0.0) fail(where, "noise.depth_stddev must be >= 0");
  if (!std::isfinite(noise.colour_stddev) || noise.colour_stddev < 0.0) {
    fail(where, "noise.colour_stddev must be >= 0");
  }
}

ClothRenderer::ClothRenderer(const ClothRendererParameters& parameters)
    : parameters_(parameters), normal_quantiles_(normalQuantiles()) {
  parameters_.validate("ClothRenderer");
  light_ = parameters_.light_direction.normalized();
  const TopDownCamera& camera = parameters_.camera;
  const int rows = camera.rows;
  const int columns = camera.columns;
  background_bgr_.create(rows, columns, CV_8UC3);
  background_depth_.create(rows, columns, CV_32FC1);
  bgr_.create(rows, columns, CV_8UC3);
  depth_.create(rows, columns, CV_32FC1);
  mask_.create(rows, columns, CV_8UC1);

  // Table and floor are horizontal: both shaded with the normal (0, 0, 1).
  const double up_shading = parameters_.ambient + (1.0 - parameters_.ambient) * std::abs(light_.z());
  const cv::Vec3b table_bgr = shade(parameters_.table_colour, up_shading);
  const cv::Vec3b floor_bgr = shade(parameters_.floor_colour, up_shading);
  const float table_depth = static_cast<float>(camera.height - parameters_.table.height);
  const float floor_depth = static_cast<float>(camera.height - parameters_.floor_height);
  const TableTop& table = parameters_.table;
  for (int v = 0; v < rows; ++v) {
    for (int u = 0; u < columns; ++u) {
      const Eigen::Vector2d xy = camera.pixelCentre(u, v);
      const bool on_table = parameters_.has_table && std::abs(xy.x() - table.centre.x()) <= 0.5 * table.size.x() &&
                            std::abs(xy.y() - table.centre.y()) <= 0.5 * table.size.y();
      background_bgr_.at<cv::Vec3b>(v, u) = on_table ? table_bgr : floor_bgr;
      background_depth_.at<float>(v, u) = on_table ? table_depth : floor_depth;
    }
  }
  background_bgr_.copyTo(bgr_);
  background_depth_.copyTo(depth_);
  mask_.setTo(0);
}

VisionStatus ClothRenderer::render(const Eigen::Ref<const Eigen::Matrix3Xd>& vertices,
                                   const Eigen::Ref<const Eigen::Matrix3Xi>& triangles) noexcept {
  // Plain copies of the (continuous) buffers: OpenCV's copyTo/setTo allocate on their first call in a thread.
  std::memcpy(bgr_.data, background_bgr_.data, bgr_.total() * bgr_.elemSize());
  std::memcpy(depth_.data, background_depth_.data, depth_.total() * depth_.elemSize());
  std::memset(mask_.data, 0, mask_.total() * mask_.elemSize());
  cloth_pixels_ = 0;
  if (vertices.cols() == 0 || triangles.cols() == 0) return VisionStatus::EmptyMesh;
  if (!vertices.allFinite()) return VisionStatus::NonFiniteVertex;
  const Eigen::Index n = vertices.cols();
  for (Eigen::Index t = 0; t < triangles.cols(); ++t) {
    for (int k = 0; k < 3; ++k) {
      if (triangles(k, t) < 0 || triangles(k, t) >= n) return VisionStatus::BadTriangle;
    }
  }
  rasterise(vertices, triangles);
  return VisionStatus::Ok;
}

VisionStatus ClothRenderer::render(const Eigen::Ref<const Eigen::Matrix3Xd>& vertices,
                                   const Eigen::Ref<const Eigen::Matrix3Xi>& triangles, std::mt19937& rng) noexcept {
  const VisionStatus status = render(vertices, triangles);
  addNoise(rng);
  return status;
}

void ClothRenderer::rasterise(const Eigen::Ref<const Eigen::Matrix3Xd>& vertices,
                              const Eigen::Ref<const Eigen::Matrix3Xi>& triangles) noexcept {
  const TopDownCamera& camera = parameters_.camera;
  const int rows = camera.rows;
  const int columns = camera.columns;
  constexpr double kNearest = 1e-3;  // Surfaces closer to the camera plane than this [m] are not drawn.
  for (Eigen::Index t = 0; t < triangles.cols(); ++t) {
    const Eigen::Vector3d a = vertices.col(triangles(0, t));
    const Eigen::Vector3d b = vertices.col(triangles(1, t));
    const Eigen::Vector3d c = vertices.col(triangles(2, t));
    const Eigen::Vector3d normal = (b - a).cross(c - a);
    const double normal_norm = normal.norm();
    if (!(normal_norm > 0.0)) continue;  // Degenerate triangle: covers no area.
    const Eigen::Vector2d pa = camera.project(a), pb = camera.project(b), pc = camera.project(c);
    // Twice the signed image area; a triangle seen edge-on covers no pixel centre.
    const double area = (pb.x() - pa.x()) * (pc.y() - pa.y()) - (pb.y() - pa.y()) * (pc.x() - pa.x());
    if (std::abs(area) < 1e-12) continue;
    // Pixel centres (u + ½, v + ½) inside the triangle's bounding box, clamped to the image before conversion.
    const double x_min = std::min({pa.x(), pb.x(), pc.x()}), x_max = std::max({pa.x(), pb.x(), pc.x()});
    const double y_min = std::min({pa.y(), pb.y(), pc.y()}), y_max = std::max({pa.y(), pb.y(), pc.y()});
    const int u0 = static_cast<int>(std::clamp(std::ceil(x_min - 0.5), 0.0, double(columns)));
    const int u1 = static_cast<int>(std::clamp(std::floor(x_max - 0.5), -1.0, double(columns - 1)));
    const int v0 = static_cast<int>(std::clamp(std::ceil(y_min - 0.5), 0.0, double(rows)));
    const int v1 = static_cast<int>(std::clamp(std::floor(y_max - 0.5), -1.0, double(rows - 1)));
    if (u0 > u1 || v0 > v1) continue;

    const double shading =
        parameters_.ambient + (1.0 - parameters_.ambient) * std::abs(normal.dot(light_)) / normal_norm;
    const cv::Vec3b colour = shade(parameters_.cloth_colour, shading);
    const double da = camera.height - a.z(), db = camera.height - b.z(), dc = camera.height - c.z();
    const double inv_area = 1.0 / area;
    for (int v = v0; v <= v1; ++v) {
      const double y = v + 0.5;
      cv::Vec3b* bgr_row = bgr_.ptr<cv::Vec3b>(v);
      float* depth_row = depth_.ptr<float>(v);
      unsigned char* mask_row = mask_.ptr<unsigned char>(v);
      for (int u = u0; u <= u1; ++u) {
        const double x = u + 0.5;
        // Barycentric weights of the pixel centre (edge functions over the signed area).
        const double wa = ((pb.x() - x) * (pc.y() - y) - (pb.y() - y) * (pc.x() - x)) * inv_area;
        const double wb = ((pc.x() - x) * (pa.y() - y) - (pc.y() - y) * (pa.x() - x)) * inv_area;
        const double wc = 1.0 - wa - wb;
        if (wa < 0.0 || wb < 0.0 || wc < 0.0) continue;
        // Orthographic projection: depth is affine in the image, so the barycentric blend is exact.
        const double d = wa * da + wb * db + wc * dc;
        if (d < kNearest || d >= depth_row[u]) continue;
        depth_row[u] = static_cast<float>(d);
        bgr_row[u] = colour;
        if (mask_row[u] == 0) ++cloth_pixels_;
        mask_row[u] = 255;
      }
    }
  }
}

void ClothRenderer::addNoise(std::mt19937& rng) noexcept {
  const std::uint64_t high = rng(), low = rng();
  SplitMix64 generator{(high << 32) | low};
  const float* normal = normal_quantiles_.data();
  const float depth_sigma = static_cast<float>(parameters_.noise.depth_stddev);
  const float colour_sigma = static_cast<float>(parameters_.noise.colour_stddev);
  const int rows = parameters_.camera.rows;
  const int columns = parameters_.camera.columns;
  for (int v = 0; v < rows; ++v) {
    unsigned char* bgr_row = bgr_.ptr<unsigned char>(v);
    float* depth_row = depth_.ptr<float>(v);
    for (int u = 0; u < columns; ++u) {
      // One 64-bit draw per pixel: four 16-bit indices for the depth and the three colour channels.
      const std::uint64_t bits = generator();
      depth_row[u] += depth_sigma * normal[bits & 0xffffu];
      for (int k = 0; k < 3; ++k) {
        unsigned char& channel = bgr_row[3 * u + k];
        const float draw = normal[(bits >> (16 * (k + 1))) & 0xffffu];
        channel = cv::saturate_cast<unsigned char>(float(channel) + colour_sigma * draw);
      }
    }
  }
}

}  // namespace bimanual_skills::vision
