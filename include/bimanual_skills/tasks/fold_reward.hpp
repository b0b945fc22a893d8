/// \file
/// The cloth-folding reward of thesis eq. 7.52 on a simulated rollout, with an optional goal term:
///
///   R = −R_acceleration − R_color − R_depth − R_goal                                      (7.52 when w_g = 0)
///
///   R = −R_acceleration − R_color − R_depth − R_goal − R_fold                      (7.52 when w_g = w_f = 0)
///
/// R_acceleration = w_a ∫ ‖q̈_ref‖² dt over both arms (FoldRollout::acceleration_cost); R_color, R_depth, R_goal and
/// R_fold are the image terms of vision::ImageReward on the final cloth rendered by a top-down camera over the table
/// (vision::ClothRenderer, with sensor noise). R_fold compares the final images with the flat cloth as the same
/// camera sees it after the reset (the rollout's cloth at rest, rendered with noise): what a camera over a real
/// table gives. R_goal compares them with a goal image that only a simulation has: the ideal fold (tasks::idealFold)
/// rendered once, without noise. Three named settings (rewardSetting()): "fold", the default (w_a = 0.001, w_f = 1,
/// the others 0), "thesis" (7.52 with w_a = 0.01, w_c = w_d = 1) and "goal" (w_a = 0.002, w_g = 1). A rollout that
/// failed (IK, controller, divergence, invalid policy) gets `failure_reward`, below any reward a finished fold can
/// reach with the default weights. Target bimanual_skills_tasks. Runs once per rollout, off the control loop: allocates
/// (OpenCV), never throws after construction.
#pragma once

#include "bimanual_skills/tasks/cloth_fold.hpp"
#include "bimanual_skills/vision/cloth_renderer.hpp"
#include "bimanual_skills/vision/image_reward.hpp"
#include "bimanual_skills/vision/perspective_camera.hpp"

#include <random>
#include <string>

namespace bimanual_skills::tasks {

struct FoldRewardConfig {
  std::string setting = "thesis";            ///< The named setting the weights started from (for the records).
  vision::ClothRendererParameters renderer;  ///< Camera, table and noise (see rendererFor()).
  vision::ImageRewardParameters image;       ///< Segmentation, w_c, w_d, w_g and the goal's height scales.
  double acceleration_weight = 0.01;         ///< w_a ≥ 0 [s³/rad²].
  double failure_reward = -3.0;              ///< Reward of a failed rollout, finite.

  /// Throws std::invalid_argument naming `where` and the parameter that is out of range.
  void validate(const char* where) const;
};

/// `config` with the weights of the named setting "fold", "thesis" or "goal" (see the file's comment); the other
/// entries kept. \throws std::invalid_argument naming `where` for another name.
FoldRewardConfig rewardSetting(FoldRewardConfig config, const std::string& name, const std::string& where);

/// The camera and scene of a simulation: the table top of `sim` (height, centre, extent; none without a table), its
/// obstacles as solids (the perspective camera draws them), and a 320 × 240 camera
/// 1.5 m above it centred on the cloth, covering 1 m of table across (3.125 mm pixels).
vision::ClothRendererParameters rendererFor(const sim::SimConfig& sim);

/// A simulated rigid body (an obstacle, the moving object) as the cameras draw it.
vision::SceneSolid sceneSolid(const sim::Obstacle& body);

/// The perspective RGB-D camera of the scene of `sim` (bullet_sim's rgbd/... by default): a Kinect (640 × 480,
/// f = 525 px) 1.3 m above and 0.65 m beyond the table top's centre on its +x side, looking at that centre (27° off
/// the vertical, 1.45 m away).
vision::PinholeCamera rgbdCameraFor(const sim::SimConfig& sim);

/// The reward's terms of one rollout.
struct FoldRewardTerms {
  FoldOutcome outcome = FoldOutcome::Ok;
  vision::VisionStatus vision = vision::VisionStatus::NoCloth;
  double r_acceleration = 0.0;  ///< w_a ∫ ‖q̈_ref‖² dt
  double r_color = 0.0;         ///< w_c (1 − ρ)
  double r_depth = 0.0;         ///< w_d ḡ
  double r_goal = 0.0;          ///< w_g · goal_mismatch
  double r_fold = 0.0;          ///< w_f · fold_mismatch
  double fill_ratio = 0.0;      ///< ρ
  double mean_gradient = 0.0;   ///< ḡ [m/m]
  double area_ratio = 0.0;      ///< Visible cloth area over the flat cloth's (½ when folded in half).
  double aspect = 0.0;          ///< Long over short side of the cloth's minimum-area rectangle.
  double goal_iou = 0.0;        ///< IoU of the seen cloth with the goal image's (vision::GoalTerm).
  double goal_mismatch = 1.0;   ///< The goal term's mismatch in [0, 1] (vision::GoalTerm).
  /// The fold term (vision::FoldTerm): E / E_flat (0 the ideal fold, 1 the flat cloth) and its widths [m].
  double fold_mismatch = 1.0, fold_edge = 0.0, fold_single = 0.0, fold_length = 0.0, fold_heap = 0.0;
  double reward = 0.0;  ///< (7.52) with R_goal, or failure_reward.
  /// The fold's ground truth from the cloth mesh (not part of the reward; fold_quality.hpp): q, its distance and
  /// displacement terms [m].
  double fold_quality = 0.0, fold_distance = 0.0, fold_displacement = 0.0;
};

/// Renders and scores rollouts. One object per thread (it holds the images).
class FoldReward {
 public:
  /// `flat_area` [m²] (> 0): the flat cloth's area, for the area ratio. `goal_vertices` and `triangles` (world
  /// frame; ClothFoldTask::idealFoldVertices() and clothTriangles()): the mesh the goal image is rendered from.
  /// \throws std::invalid_argument, also for a goal mesh the camera does not see.
  FoldReward(const FoldRewardConfig& config, double flat_area, const Eigen::Matrix3Xd& goal_vertices,
             const Eigen::Matrix3Xi& triangles);

  /// Renders the rollout's final cloth with noise drawn from `rng`, then its cloth at rest (the flat cloth after the
  /// reset, observeFlat()) with the next draws, and evaluates the reward. A rollout without a cloth mesh renders the
  /// empty table and has no flat cloth.
  FoldRewardTerms evaluate(const FoldRollout& rollout, std::mt19937& rng);
  /// The flat cloth after the reset, as a camera took it (colour bgr8, depth 32FC1 [m], of config().renderer.camera's
  /// size): the fold term's reference until the next call. \throws std::invalid_argument when the images do not show
  /// a flat cloth on a table (vision::ImageReward::setFlat); the fold term is then unknown until a good one.
  void observeFlat(const cv::Mat& bgr, const cv::Mat& depth);
  /// The reward on images a camera took (colour bgr8 and depth 32FC1 in metres, of config().renderer.camera's size;
  /// other images give the vision status of vision::ImageReward and a failed image term) for a rollout that ended
  /// with `outcome` and ∫ ‖q̈_ref‖² dt = `acceleration_cost`, the fold term against the last observeFlat(). The fold
  /// quality terms stay 0.
  FoldRewardTerms evaluateImages(FoldOutcome outcome, double acceleration_cost, const cv::Mat& bgr,
                                 const cv::Mat& depth);

  const FoldRewardConfig& config() const noexcept { return config_; }
  /// The images of the last evaluate(): colour (bgr8) and depth (32FC1, metres).
  const cv::Mat& bgr() const noexcept { return renderer_.bgr(); }
  const cv::Mat& depth() const noexcept { return renderer_.depth(); }

 private:
  FoldRewardConfig config_;
  double flat_area_;
  vision::ClothRenderer renderer_, flat_renderer_;
  vision::ImageReward image_;
};

}  // namespace bimanual_skills::tasks
