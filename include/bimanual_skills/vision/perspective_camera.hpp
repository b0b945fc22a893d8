/// \file
/// A perspective RGB-D camera (a Kinect or RealSense: pinhole, 640 × 480) looking at the table from wherever it is
/// mounted, and the step back to what the fold's reward needs: its depth image, with its intrinsics (CameraInfo's K)
/// and its pose (tf), re-projected into the orthographic top-down height map and colour map of a TopDownCamera.
///
/// Conventions are ROS's (REP 103/118, sensor_msgs/CameraInfo): the optical frame has z along the view, x right and
/// y down in the image; the centre of pixel (u, v) is the image point (u, v); a world point p with optical-frame
/// coordinates (x, y, z) = pose⁻¹ p lands at u = f_x x/z + c_x, v = f_y y/z + c_y; a depth image holds z (not the
/// distance along the ray) in metres, NaN where the sensor has no return.
///
/// The sensor model (DepthSensorNoise) follows Khoshelham & Elberink (2012, Sensors 12:1437) for a Kinect: the
/// depth's random error grows with the square of the distance, σ_z = k z² with k = 1.425 × 10⁻³ m⁻¹ (1.4 mm at 1 m,
/// 5.7 mm at 2 m); structured-light sensors lose pixels where the depth jumps (the projector's shadow and mixed
/// pixels at edges), on surfaces seen at grazing angles and outside their range (0.5–4 m).
#pragma once

#include "bimanual_skills/vision/cloth_renderer.hpp"
#include "bimanual_skills/vision/top_down_camera.hpp"
#include "bimanual_skills/vision/vision_status.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <random>
#include <vector>

namespace bimanual_skills::vision {

/// A pinhole camera without distortion (rectified images) and its pose.
struct PinholeCamera {
  int width = 640, height = 480;                           ///< [pixels], ≥ 8.
  double fx = 525.0, fy = 525.0, cx = 319.5, cy = 239.5;   ///< [pixels] (a Kinect's colour camera).
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< The optical frame in the world.
  double min_range = 0.5, max_range = 4.0;                 ///< Depth the sensor returns [m].

  /// The camera at `eye` looking at `target` (world frame), image rows running against `up` (the world's +z by
  /// default). \throws std::invalid_argument when eye and target coincide or the view is along `up`.
  static PinholeCamera lookingAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                                 const Eigen::Vector3d& up = Eigen::Vector3d::UnitZ());

  /// Image point (u, v) and depth z of a world point; false when it lies behind the camera (z ≤ 0).
  bool project(const Eigen::Vector3d& world, Eigen::Vector3d& uvz) const noexcept;
  /// The world point of image point (u, v) at depth z.
  Eigen::Vector3d backProject(double u, double v, double z) const noexcept {
    return pose * Eigen::Vector3d((u - cx) / fx * z, (v - cy) / fy * z, z);
  }

  /// Whether its intrinsics and pose can project: finite focal lengths > 0, a finite principal point, a finite rigid
  /// pose (what a frame's users check in real time; validate() says which member is wrong).
  bool usable() const noexcept;

  /// \throws std::invalid_argument naming `where` and the member that is out of range.
  void validate(const char* where) const;
};

/// A structured-light depth sensor's errors (see the file comment); all zero: a perfect sensor.
struct DepthSensorNoise {
  double axial = 1.425e-3;     ///< k of σ_z = k z² [1/m].
  double dropout = 0.002;      ///< Share of pixels lost at random.
  double edge_jump = 0.02;     ///< A depth step between neighbours beyond this [m] is an edge...
  double edge_dropout = 0.5;   ///< ...whose pixels are lost with this probability.
  double grazing = 0.1;        ///< Surfaces whose |cos| between normal and ray is below this give no return.
  double colour_stddev = 2.0;  ///< Colour noise per channel [levels of 0–255].

  void validate(const char* where) const;
};

/// Renders the scene of a ClothRendererParameters (table as a box, floor, cloth; its top-down camera and noise
/// unused) as a perspective RGB-D camera sees it: colour (Lambert shading by face normal), depth z with the sensor's
/// errors, and the noise-free cloth mask. Every buffer is allocated at construction; render() only writes into them.
class PerspectiveRenderer {
 public:
  /// \throws std::invalid_argument for invalid parameters.
  PerspectiveRenderer(const ClothRendererParameters& scene, const PinholeCamera& camera,
                      const DepthSensorNoise& noise = DepthSensorNoise());

  /// The cloth mesh (3 × N world vertices, 3 × M indices) in the scene, without noise: depth NaN only where nothing
  /// lies within the sensor's range or a surface is seen at a grazing angle. Real-time safe.
  VisionStatus render(const Eigen::Ref<const Eigen::Matrix3Xd>& vertices,
                      const Eigen::Ref<const Eigen::Matrix3Xi>& triangles) noexcept;
  /// As above, then the sensor's errors drawn from `rng` (same seed, same images). Real-time safe.
  VisionStatus render(const Eigen::Ref<const Eigen::Matrix3Xd>& vertices,
                      const Eigen::Ref<const Eigen::Matrix3Xi>& triangles, std::mt19937& rng) noexcept;

  /// A solid that moves (an object carried about the table, thesis Sec. 4.3.2), tessellated here once in its own
  /// frame (`solid.pose` is ignored); setMovingPose() places it. Returns its index. Allocates: set-up only.
  int addMovingSolid(const SceneSolid& solid);
  /// Where moving solid `index` is for the next render()s (its centre; a non-finite pose hides it). Real-time safe;
  /// an unknown index does nothing.
  void setMovingPose(int index, const Eigen::Isometry3d& pose) noexcept;

  const PinholeCamera& camera() const noexcept { return camera_; }
  const ClothRendererParameters& scene() const noexcept { return scene_; }
  /// CV_8UC3, B, G, R ("bgr8"), registered to the depth image (one camera).
  const cv::Mat& bgr() const noexcept { return bgr_; }
  /// CV_32FC1, z along the optical axis [m], NaN for no return ("32FC1", REP 118).
  const cv::Mat& depth() const noexcept { return depth_; }
  /// CV_8UC1, 255 where the visible surface is cloth (noise-free).
  const cv::Mat& clothMask() const noexcept { return mask_; }
  int clothPixelCount() const noexcept { return cloth_pixels_; }
  /// CV_8UC1, 255 where the visible surface is a moving solid (noise-free).
  const cv::Mat& movingMask() const noexcept { return moving_mask_; }

 private:
  struct MovingSolid {
    std::vector<Eigen::Matrix3d> triangles;  ///< In its own frame.
    Eigen::Vector3d colour;
    Eigen::Isometry3d pose;
    bool visible = false;
  };
  void draw(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c, const Eigen::Vector3d& rgb,
            unsigned char kind) noexcept;
  void finish(std::mt19937* rng) noexcept;

  ClothRendererParameters scene_;
  PinholeCamera camera_;
  DepthSensorNoise noise_;
  Eigen::Isometry3d world_to_camera_;
  Eigen::Vector3d light_;
  std::vector<float> normal_quantiles_;
  cv::Mat background_bgr_, background_z_, background_flags_;
  std::vector<MovingSolid> moving_;
  /// z_: noise-free z buffer; flags_: bit 0 cloth, bit 1 no return, bit 2 a moving solid.
  cv::Mat bgr_, z_, flags_, depth_, mask_, moving_mask_;
  int cloth_pixels_ = 0;
};

/// What a re-projection saw.
struct HeightMapCoverage {
  int points = 0;    ///< Depth pixels with a return that fell on the map.
  int observed = 0;  ///< Cells a point fell in.
  int filled = 0;    ///< Cells filled from observed neighbours (gaps between points, small shadows).
  int unseen = 0;    ///< Cells no point reached: given the lowest surface seen, in black.
};

/// Re-projects a perspective camera's depth and colour images into the orthographic top-down images of a
/// TopDownCamera (what ClothRenderer renders and the reward scores): each depth pixel with a return is back-projected
/// into the world and dropped into its cell of the map, the highest point of a cell wins (an orthographic camera
/// above sees the top surface); cells between points are filled from their neighbours for up to `fill_cells` passes,
/// the rest take the lowest surface seen. Buffers allocated at construction; project() does not allocate.
class HeightMapProjector {
 public:
  /// \throws std::invalid_argument for an invalid map or a negative fill.
  explicit HeightMapProjector(const TopDownCamera& map, int fill_cells = 3);

  /// Images of `camera`'s size (bgr8 and 32FC1 metres): WrongImageSize otherwise, BadCameraPose for a non-finite or
  /// non-rigid pose, NoCloth when no depth pixel lands on the map.
  VisionStatus project(const cv::Mat& bgr, const cv::Mat& depth, const PinholeCamera& camera) noexcept;

  const TopDownCamera& map() const noexcept { return map_; }
  /// CV_8UC3 and CV_32FC1 (map.height − z [m]) of the map's size, as ClothRenderer's bgr() and depth().
  const cv::Mat& bgr() const noexcept { return bgr_; }
  const cv::Mat& depth() const noexcept { return depth_; }
  const HeightMapCoverage& coverage() const noexcept { return coverage_; }

 private:
  TopDownCamera map_;
  int fill_cells_;
  cv::Mat bgr_, depth_, next_bgr_, next_depth_;
  HeightMapCoverage coverage_;
};

}  // namespace bimanual_skills::vision
