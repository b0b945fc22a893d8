/// \file
/// The scarf-placing experiment's measures (thesis Sec. 4.3.1): the camera cost of a scarf around a mannequin's neck
/// from a colour image (the thesis' HSV segmentation of scarf and nose mark: the vertical distance d from the nose
/// to the scarf against d_ref, and on which side the scarf hangs), and a ground truth from the scarf's mesh that a
/// learner never sees (wrapped around the neck, hanging on the mannequin's right and not its left).
#pragma once

#include "bimanual_skills/sim/obstacle.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace bimanual_skills::tasks {

/// What the measures need of the mannequin, from a scene's obstacles named "neck", "shoulders" and "nose_mark".
struct Mannequin {
  Eigen::Vector3d neck = Eigen::Vector3d::Zero();  ///< Centre of the neck (a vertical cylinder) [m, world].
  double neck_radius = 0.0, neck_length = 0.0;
  double shoulders_top = 0.0;                         ///< World z of the shoulders' top face.
  Eigen::Vector3d nose = Eigen::Vector3d::Zero();     ///< The nose mark's centre.
  Eigen::Vector3d facing = Eigen::Vector3d::UnitX();  ///< Horizontal unit vector from the neck towards the nose.
  Eigen::Vector3d right = Eigen::Vector3d::UnitY();   ///< The mannequin's right: facing × up.

  /// \throws std::invalid_argument naming the part that is missing or not of the expected shape.
  static Mannequin fromObstacles(const std::vector<sim::Obstacle>& obstacles);
};

/// The ground truth of a scarf's final mesh.
struct ScarfTruth {
  /// Signed angle the scarf's centre line turns about the neck's axis within the neck's height band [rad]:
  /// |winding| ≥ π when it passes behind the neck.
  double winding = 0.0;
  bool wrapped = false;
  /// Points of the centre line (one per node along the length) hanging more than kHangingDrop below the shoulders'
  /// top, away from the neck, on the mannequin's right and left: a wound band resting on the shoulders' edge is not
  /// hanging.
  int hanging_right = 0, hanging_left = 0;
  bool fallen = false;   ///< No node above the shoulders' top: the scarf left the mannequin.
  bool success = false;  ///< Wrapped, hanging on the right and not on the left, not fallen.
};

/// How far below the shoulders' top a node hangs [m].
constexpr double kHangingDrop = 0.05;

/// The ground truth of `vertices` (3 × nodes_x · nodes_y, node (i, j) at column j · nodes_x + i, i along the
/// scarf's length), as sim::Cloth numbers them.
ScarfTruth scarfTruth(const Mannequin& mannequin, const Eigen::Matrix3Xd& vertices, int nodes_x, int nodes_y);

/// The camera cost's settings (thesis Sec. 4.3.1: d_ref = 62 px, α = 1.2, weights 10 and 3).
struct ScarfCameraConfig {
  double d_ref = 62.0;            ///< Reference distance from the nose mark down to the scarf [px], > 0.
  double alpha = 1.2;             ///< Exponent of the distance term, > 0.
  double distance_weight = 10.0;  ///< ≥ 0.
  double hanging_weight = 3.0;    ///< Weight of I_hanging, ≥ 0.
  /// The printed formula 10 max((d − d_ref)/d_ref, 1)^α cannot go below 10, yet the thesis calls a cost under 3
  /// success: by default the distance term is 10 (|d − d_ref| / d_ref)^α (zero at d_ref); `printed` keeps the
  /// formula as printed.
  bool printed = false;
  /// How far below the nose mark scarf pixels count as hanging [px] (the thesis: "the part hanging on the sides up to
  /// a certain level"); 0: 2 d_ref.
  double hanging_level = 0.0;
  /// Half-width of the column band around the nose mark in which the scarf's top is looked for [px].
  int band = 40;
  /// Whether the mannequin's right is the image's left (a camera facing the mannequin) or its right.
  bool right_is_image_left = true;
  /// HSV thresholds (OpenCV ranges: H 0–180, S and V 0–255) of the blue scarf and the red nose mark.
  cv::Scalar scarf_low = cv::Scalar(100, 120, 60), scarf_high = cv::Scalar(135, 255, 255);
  cv::Scalar nose_low = cv::Scalar(0, 150, 80), nose_high = cv::Scalar(8, 255, 255);
  int min_pixels = 10;  ///< Fewer pixels of a colour count as not seen.

  /// \throws std::invalid_argument naming `where` and the entry out of range.
  void validate(const std::string& where) const;
};

/// The camera's view of a rollout's end.
struct ScarfCameraTerms {
  bool nose_seen = false, scarf_seen = false;
  double nose_u = 0.0, nose_v = 0.0;  ///< The nose mark's centroid [px].
  /// Vertical distance from the nose mark down to the scarf's topmost pixel in the band [px]; the image's height
  /// when no scarf is in the band below the nose.
  double d = 0.0;
  int right_pixels = 0, left_pixels = 0;  ///< Scarf pixels below the nose on the mannequin's right and left.
  int hanging = 1;                        ///< I_hanging: 0 when the scarf hangs right and not left, else 1.
  double c_distance = 0.0, c_cam = 0.0;   ///< The distance term and c_cam = it + w_h I_hanging.
};

/// d_ref for `camera`: the image distance [px] from the nose mark's centre down to the front of the neck's top, where
/// a scarf wound round the neck shows its top edge (the thesis' 62 px were its camera's; this is the same place
/// seen by another). \throws std::invalid_argument when the camera does not see both points below one another.
double referenceDistance(const Mannequin& mannequin, const vision::PinholeCamera& camera);

/// The hanging level for `camera`: the image distance [px] from the nose mark's centre down to kHangingDrop below the
/// shoulders' top in front of the neck, as scarfTruth() counts hanging nodes. \throws as referenceDistance().
double hangingLevel(const Mannequin& mannequin, const vision::PinholeCamera& camera);

/// c_cam of a colour image (bgr8): segmentation by HSV thresholds, then d, the hanging side and the cost. An image
/// without the nose mark costs as if the scarf were nowhere near (d = the image's height) and hanging wrong.
/// \throws std::invalid_argument for an empty image or one of another type.
ScarfCameraTerms scarfCameraTerms(const cv::Mat& bgr, const ScarfCameraConfig& config);

}  // namespace bimanual_skills::tasks
