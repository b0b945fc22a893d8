/// \file
/// Offscreen, CPU-only rendering of the cloth on the table as a top-down camera sees it: a colour image (Lambert
/// shading by face normal), a depth image (distance along the optical axis) and the renderer's own cloth mask, with
/// optional sensor-like noise. A small z-buffered rasteriser (docs/ARCHITECTURE.md "Vision" says why and what it
/// costs): every buffer is allocated at construction, render() only writes into them.
#pragma once

#include "bimanual_skills/vision/top_down_camera.hpp"
#include "bimanual_skills/vision/vision_status.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <random>
#include <vector>

namespace bimanual_skills::vision {

/// The table top: an axis-aligned rectangle in the world's xy plane at height `height`.
struct TableTop {
  double height = 0.15;                                 ///< World z of the top face [m].
  Eigen::Vector2d centre = Eigen::Vector2d(0.55, 0.0);  ///< World xy of its centre [m].
  Eigen::Vector2d size = Eigen::Vector2d(0.7, 1.2);     ///< Full extents along world x and y [m], > 0.
};

/// A static solid of the scene besides the table (a mannequin's head, neck, the mark on its nose), as
/// sim::Obstacle describes it: drawn by the perspective camera in its colour.
struct SceneSolid {
  enum class Shape { Box, Sphere, Cylinder };
  Shape shape = Shape::Box;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< Its centre in the world; a cylinder's axis is its z.
  /// Box: full extents; sphere: (radius, 0, 0); cylinder: (radius, length, 0) [m], > 0.
  Eigen::Vector3d size = Eigen::Vector3d::Zero();
  Eigen::Vector3d colour = Eigen::Vector3d::Constant(0.8);  ///< RGB in [0, 1].
};

/// The solid's surface as triangles (world frame, outward winding): a box's 12, a sphere of 24 × 16 facets, a
/// cylinder of 32 sides and its two caps.
std::vector<Eigen::Matrix3d> solidTriangles(const SceneSolid& solid);

/// Sensor noise added by render(vertices, triangles, rng): independent per pixel and channel, zero mean, Gaussian
/// of the given standard deviations. Each draw is one of the 2^16 equiprobable quantiles of N(0, 1) (tails at
/// ±4.3 σ, rescaled to unit variance), picked by 16 bits of a SplitMix64 word; the caller's std::mt19937 seeds that
/// stream (two draws per render), and one 64-bit word serves a pixel's depth and three colours. std::mt19937 with
/// std::normal_distribution costs about 16 times more (vision_bench, docs/RESULTS.md "Vision").
struct RenderNoise {
  double depth_stddev = 0.001;  ///< Depth noise σ_d [m] (a Kinect-class sensor at ~1.5 m: 1–3 mm).
  double colour_stddev = 2.0;   ///< Colour noise per channel [levels of 0–255].
};

struct ClothRendererParameters {
  TopDownCamera camera;
  TableTop table;
  bool has_table = true;  ///< false: a scene without a table (the floor alone around `table`'s centre).
  /// Static solids besides the table; the perspective camera draws them (the top-down map of the fold's reward
  /// shows the table scene only).
  std::vector<SceneSolid> solids;
  double floor_height = 0.0;  ///< World z of the floor seen around the table [m], below table.height.
  /// Colours as RGB in [0, 1]: a blue polo shirt (the thesis segments blue), a light wooden table, a grey floor.
  Eigen::Vector3d cloth_colour = Eigen::Vector3d(0.12, 0.28, 0.85);
  Eigen::Vector3d table_colour = Eigen::Vector3d(0.82, 0.72, 0.56);
  Eigen::Vector3d floor_colour = Eigen::Vector3d(0.30, 0.30, 0.30);
  /// Direction towards a distant light (world frame, any length > 0). Shading of a surface of unit normal n:
  /// colour · (a + (1 − a) |n · l̂|) with the ambient share a; |·| because both sides of the cloth are visible.
  Eigen::Vector3d light_direction = Eigen::Vector3d(0.3, -0.4, 1.0);
  double ambient = 0.35;  ///< Ambient share a in [0, 1].
  RenderNoise noise;

  /// Throws std::invalid_argument naming `where` and the parameter that is out of range.
  void validate(const char* where) const;
};

/// The renderer and its images. Construction allocates and may throw; render() does neither.
class ClothRenderer {
 public:
  /// Allocates the images and renders the background (table and floor) once.
  /// \throws std::invalid_argument for invalid parameters.
  explicit ClothRenderer(const ClothRendererParameters& parameters);

  const ClothRendererParameters& parameters() const noexcept { return parameters_; }

  /// Renders the cloth mesh without noise. `vertices`: 3 × N node positions, world frame [m]; `triangles`: 3 × M
  /// node indices (the shapes of sim::Cloth::vertices() and triangles()). The surface closest to the camera wins
  /// (z-buffer); cloth below the table top is hidden by it. For an empty mesh, a non-finite vertex or an index out
  /// of range the images show the table and floor only and the status says why.
  /// Real-time safe: no allocation (pass Eigen::Matrix3Xd / Matrix3Xi or blocks of them, so that the Eigen::Ref
  /// binds without a copy), no exceptions.
  VisionStatus render(const Eigen::Ref<const Eigen::Matrix3Xd>& vertices,
                      const Eigen::Ref<const Eigen::Matrix3Xi>& triangles) noexcept;
  /// As above, then adds parameters().noise drawn from `rng` to every pixel of the colour and depth images (the
  /// cloth mask stays the noise-free truth). Same seed, same images. Real-time safe.
  VisionStatus render(const Eigen::Ref<const Eigen::Matrix3Xd>& vertices,
                      const Eigen::Ref<const Eigen::Matrix3Xi>& triangles, std::mt19937& rng) noexcept;

  /// Colour image, rows × columns, CV_8UC3 in OpenCV's B, G, R order (sensor_msgs/Image encoding "bgr8").
  const cv::Mat& bgr() const noexcept { return bgr_; }
  /// Depth image, rows × columns, CV_32FC1: distance from the camera plane along the optical axis [m].
  const cv::Mat& depth() const noexcept { return depth_; }
  /// Where the visible surface is cloth: rows × columns, CV_8UC1, 255 on cloth and 0 elsewhere (noise-free).
  const cv::Mat& clothMask() const noexcept { return mask_; }
  /// Number of cloth pixels in clothMask() after the last render.
  int clothPixelCount() const noexcept { return cloth_pixels_; }

 private:
  void rasterise(const Eigen::Ref<const Eigen::Matrix3Xd>& vertices,
                 const Eigen::Ref<const Eigen::Matrix3Xi>& triangles) noexcept;
  void addNoise(std::mt19937& rng) noexcept;

  ClothRendererParameters parameters_;
  std::vector<float> normal_quantiles_;  ///< 2^16 quantiles of N(0, 1): the noise's draws.
  Eigen::Vector3d light_;                ///< Unit light direction.
  cv::Mat background_bgr_, background_depth_;
  cv::Mat bgr_, depth_, mask_;
  int cloth_pixels_ = 0;
};

}  // namespace bimanual_skills::vision
