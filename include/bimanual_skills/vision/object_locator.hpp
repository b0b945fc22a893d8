/// \file
/// Finds a known object in a registered RGB-D frame and measures where its centre is in the world (the tracking
/// experiment's perception, thesis Sec. 4.3.2): its colour picked out in HSV (OpenCV: cvtColor, inRange, an opening
/// against speckle, the largest connected component), the component's depth pixels back-projected through the
/// camera's intrinsics and pose (tf), and the object's known shape, upright, fitted to those points by Gauss–Newton
/// on their distances to its surface. A camera sees only the near side of an object: the centroid of the visible
/// points lies ≈ (π/4) r towards the camera from a cylinder's axis, which the shape fit removes. The measurement's
/// covariance is the fit's, σ² (JᵀJ)⁻¹ with σ the points' rms distance to the fitted surface (at least
/// `min_stddev`), for the Kalman filter that tracks it (signal/target_tracker.hpp).
#pragma once

#include "bimanual_skills/vision/cloth_renderer.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <vector>

namespace bimanual_skills::vision {

struct ObjectLocatorConfig {
  SceneSolid shape;   ///< The object's shape and size, upright, axes along the world's (pose and colour unused).
  double hue = 24.0;  ///< Its colour's hue [degrees, 0-360)...
  double hue_tolerance = 12.0;  ///< ...give or take this [degrees].
  double min_saturation = 0.5;  ///< HSV saturation at least [0, 1] (the table and the floor are greyer).
  double min_value = 0.15;      ///< HSV value at least [0, 1] (its shaded side still counts).
  int min_pixels = 30;          ///< Fewer pixels of its colour: not seen.
  int min_points = 20;          ///< Fewer depth points on it: not measured.
  int max_points = 600;         ///< The fit uses at most this many points (evenly subsampled).
  double min_stddev = 0.002;    ///< Floor of the measurement's standard deviation per axis [m].
  int iterations = 10;          ///< Gauss–Newton iterations at most.
  /// [m] Points not the object's are dropped: farther than the object's half diagonal and this from the points'
  /// median before the fit, and farther than this from the fitted surface after it (then fitted again). Such points
  /// come from what stands in front of it (an arm: its depth registered onto the object's pixels at the edges).
  double outlier_distance = 0.01;

  /// \throws std::invalid_argument naming `where` and the entry out of range.
  void validate(const char* where) const;
};

/// The hue [degrees, 0-360) of an RGB colour (components in [0, 1]), as OpenCV's HSV measures it (0 for a grey).
double hueOf(const Eigen::Vector3d& rgb) noexcept;

/// What a frame gave.
enum class LocateStatus {
  Ok,
  WrongImage,  ///< Not bgr8 and 32FC1 of the camera's size.
  BadCamera,   ///< Non-finite or non-rigid pose, bad intrinsics.
  NotSeen,     ///< Too few pixels of the object's colour.
  AtEdge,      ///< Cut by the image's (or the depth camera's) edge: part of it is out of view, its fit biased.
  NoDepth,     ///< Seen, but too few of its pixels have a depth.
  NoFit,       ///< The shape fit did not converge to a finite centre.
};
const char* toString(LocateStatus status) noexcept;

struct ObjectMeasurement {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();        ///< The object's centre in the world [m].
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();  ///< [m²], symmetric positive definite.
  int pixels = 0;                                            ///< Pixels of the component taken as the object.
  int points = 0;                                            ///< Of them, with a depth, used in the fit.
  double rms = 0.0;                                          ///< Rms distance of the points to the fitted surface [m].
  Eigen::Vector2d image_centre = Eigen::Vector2d::Zero();    ///< The component's centroid (u, v) [pixels].
};

/// Buffers are allocated on the first frame of a size; later frames of that size reuse them.
class ObjectLocator {
 public:
  /// \throws std::invalid_argument for an invalid config.
  explicit ObjectLocator(const ObjectLocatorConfig& config);

  /// The object in this frame (colour bgr8 and registered depth 32FC1 in metres, NaN: no return) seen by `camera`.
  /// `depth_view`: the depth camera (its pose in the world) when the depth was registered from a camera of its own:
  /// an object whose box, at its depths, reaches beyond that camera's image is AtEdge (only part of it has depth,
  /// and what the depth camera sees past its edge lands on its pixels), as one cut by the colour image's edge.
  LocateStatus locate(const cv::Mat& bgr, const cv::Mat& depth, const PinholeCamera& camera,
                      ObjectMeasurement& measurement, const PinholeCamera* depth_view = nullptr);

  /// The last frame's mask of the object's colour (after the opening) and of the component taken (255).
  const cv::Mat& colourMask() const noexcept { return mask_; }
  const cv::Mat& objectMask() const noexcept { return component_; }
  const ObjectLocatorConfig& config() const noexcept { return config_; }

  /// Signed distance of world point `p` to the surface of the object centred at `centre` (negative inside).
  double surfaceDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& centre) const noexcept;

 private:
  /// Gauss–Newton on the points' distances to the surface from `centre`: the normal matrix and the sum of squared
  /// distances at the last iterate. False for a non-finite step.
  bool fit(Eigen::Vector3d& centre, Eigen::Matrix3d& normal, double& sum) const noexcept;

  ObjectLocatorConfig config_;
  cv::Mat hsv_, mask_, opened_, labels_, stats_, centroids_, component_, kernel_;
  std::vector<Eigen::Vector3d> points_;
  std::vector<double> scratch_;
};

}  // namespace bimanual_skills::vision
