/// \file
/// The image terms of the cloth-folding reward (thesis Sec. 7.2.3, eq. 7.52, Fig. 7.9a–b) on a top-down colour and
/// depth image, with OpenCV:
///
///   R = −R_acceleration − R_color − R_depth                                                        (7.52)
///
///   ρ       = (cloth pixels) / (area of the cloth's minimum-area rectangle)    in [0, 1], 1 for a rectangle
///   R_color = w_c (1 − ρ)
///   ḡ       = mean over the cloth of ‖∇d‖, d the depth [m], ∇ per metre of table (Sobel)    [m/m]
///   R_depth = w_d ḡ
///
/// and, beyond the thesis, a goal term comparing the images with a goal image (the ideal fold rendered without
/// noise, set with setGoal()): over the union of the seen cloth mask M and the goal's G, with Δ = d_G − d the
/// height of the seen surface above the goal's,
///
///   e(pixel) = 1 where only one of M, G has cloth,   min(max(−Δ / τ_missing, Δ / τ_excess), 1) where both have,
///   R_goal   = w_g · mean of e over M ∪ G         in [0, w_g], 0 for the goal itself,
///
/// which is 1 − IoU(M, G) with the shared pixels weighed by how far their height is from the goal's: cloth missing
/// below it (τ_missing, the goal's own height above the table by default, so that a shared pixel one layer low
/// counts ½ where two belong), or heaped above it (τ_excess: a crumpled lump, air under a layer). w_g = 0 by
/// default: (7.52) as the thesis has it.
///
/// And a fold term that needs nothing but the camera: the flat cloth as the camera sees it after the reset
/// (setFlat()) gives the table's depth d_T, the cloth's thickness h_0, its near and far edges u_0, u_1 along the
/// image's u axis (the fold axis: the half at larger u is folded onto the half at smaller u) and the fold line
/// u_c = (u_0 + u_1)/2. Along each image row the flat cloth covers, with a, b the first and last cloth column of the
/// final image and s the pixel size,
///   edge   = |a − u_0| s                               (the staying half dragged: its near edge moved)
///   single = s · #{u_0 ≤ u < u_c: cloth of height < θ h_0 above the table}    (one layer where two belong)
///   length = |(b − a) − (u_c − u_0)| s                  (the folded cloth longer or shorter than half the flat one)
///   heap   = s · #{u_0 ≤ u < u_0 + κ (u_c − u_0): cloth higher than θ_h h_0}   (cloth piled on the near part of the
///            staying half, away from the crease's roll: the far edge heaped on the near one)
///   E      = mean over the rows of w_e edge + w_s single + w_l length + w_h heap  [m]  (a row bare: 2 E_flat)
///   R_fold = w_f · E / E_flat,   E_flat = w_s (u_c − u_0) s + w_l (u_1 − u_c) s   (the flat cloth's E)
/// so R_fold = 0 for the ideal fold and w_f for the cloth left flat. The weights are a linear model of 1 − q (the
/// fold quality of tasks/fold_quality.hpp) fitted by non-negative least squares on scripted folds of many kinds;
/// docs/RESULTS.md ("A camera reward that ranks folds") has the fit and the test on folds it was not fitted to.
///
/// The thesis defines ρ (Fig. 7.9a: blue pixels over the pixels of the smallest rectangle containing them) and ḡ
/// (Fig. 7.9b: the mean depth gradient as wrinkledness) but prints no weights, and (7.52) subtracts R_color while
/// the text calls it a term that is large and negative for a non-rectangular result. We read both vision terms as
/// penalties that vanish for a flat, perfectly rectangular cloth: R_color = w_c (1 − ρ) and R_depth = w_d ḡ, with
/// w_c = w_d = 1 by default. The values the thesis reports for its initial fold, R_color = 0.799 ± 0.088 and
/// R_depth = 0.473 ± 0.029, are most plausibly ρ itself and ḡ in the Kinect's units; compare ρ, not R_color, with
/// the former.
///
/// Not real-time code: it runs once per rollout, outside any control loop. Its scratch images are allocated at
/// construction, but OpenCV's own calls (cvtColor, morphology, Sobel, minAreaRect) may allocate internally.
#pragma once

#include "bimanual_skills/vision/top_down_camera.hpp"
#include "bimanual_skills/vision/vision_status.hpp"

#include <opencv2/core.hpp>

#include <vector>

namespace bimanual_skills::vision {

/// Colour segmentation of the cloth as an HSV box (OpenCV's ranges: hue in [0, 180), saturation and value in
/// [0, 255]). The defaults keep ClothRendererParameters' blue cloth (hue ≈ 113) and reject its table (hue ≈ 18,
/// saturation ≈ 80) and grey floor, at every shading the renderer produces.
struct ClothSegmentation {
  int hue_min = 100;
  int hue_max = 130;
  int saturation_min = 120;
  int value_min = 40;
  /// Morphological opening (3 × 3) of the mask, which removes isolated misclassified pixels before the rectangle is
  /// fitted (one stray pixel would otherwise inflate the minimum-area rectangle).
  bool remove_speckles = true;
};

struct ImageRewardParameters {
  ClothSegmentation segmentation;
  double colour_weight = 1.0;  ///< w_c ≥ 0 in R_color = w_c (1 − ρ).
  double depth_weight = 1.0;   ///< w_d ≥ 0 in R_depth = w_d ḡ.
  /// Pixels removed from the border of the cloth mask (3 × 3 erosions) before ḡ is averaged, so that the step from
  /// the table to the cloth's edge (its thickness) is not counted as a wrinkle. ≥ 0.
  int border_erosion = 1;
  /// Standard deviation [m of table] of a Gaussian smoothing of the depth before the Sobel filter, against sensor
  /// noise; 0 for none, ≥ 0. It averages cloth pixels only (normalised convolution: blur(d·m) / blur(m) for the
  /// cloth mask m), so the table does not bleed into the cloth's edge. Without it, white depth noise of σ_d alone
  /// gives ḡ ≈ 1.25 · √12 σ_d / (8 s): 0.35 for σ_d = 1 mm at s = 1.56 mm, more than a crease.
  double depth_smoothing = 0.005;
  /// ḡ [m/m] used for R_depth when no cloth is visible (the worst case the reward can see). ≥ 0.
  double no_cloth_gradient = 1.0;
  double goal_weight = 0.0;            ///< w_g ≥ 0 in R_goal = w_g · mismatch.
  double goal_missing_height = 0.008;  ///< τ_missing [m] > 0 (two 4 mm layers).
  double goal_excess_height = 0.05;    ///< τ_excess [m] > 0.
  double fold_weight = 0.0;            ///< w_f ≥ 0 in R_fold = w_f · E / E_flat.
  double fold_edge_weight = 5.5;       ///< w_e ≥ 0.
  double fold_single_weight = 1.4;     ///< w_s ≥ 0 (w_s + w_l > 0).
  double fold_length_weight = 4.5;     ///< w_l ≥ 0.
  double layer_threshold = 1.5;        ///< θ > 1: cloth thinner than θ h_0 above the table is one layer.
  /// σ [m of table] of the Gaussian smoothing of the height map against sensor noise before θ is applied; ≥ 0.
  double fold_smoothing = 0.003;
  double fold_heap_weight = 0.0;  ///< w_h ≥ 0 (0: heap measured, not weighed).
  /// θ_h > θ: cloth higher than θ_h h_0 above the table is heaped (two layers lie about 3 h_0 high: the upper one's
  /// rendered thickness and the air between them).
  double heap_threshold = 8.0;
  double heap_reach = 0.1;  ///< κ in (0, 1]: the share of the staying half, from the near edge, searched.

  /// Throws std::invalid_argument naming `where` and the parameter that is out of range.
  void validate(const char* where) const;
};

/// The colour term's facts.
struct ColourTerm {
  VisionStatus status = VisionStatus::NoCloth;
  int cloth_pixels = 0;
  double fill_ratio = 0.0;    ///< ρ: cloth pixels over the rectangle's area in pixels, in [0, 1].
  cv::RotatedRect rectangle;  ///< Minimum-area rectangle of the cloth pixels' centres (image coordinates).
};

/// The depth term's facts.
struct DepthTerm {
  VisionStatus status = VisionStatus::NoCloth;
  int pixels = 0;              ///< Cloth pixels the mean was taken over (after erosion, finite depth).
  double mean_gradient = 0.0;  ///< ḡ [m/m].
};

/// The goal term's facts.
struct GoalTerm {
  VisionStatus status = VisionStatus::NoCloth;  ///< NoCloth also when no goal is set.
  double iou = 0.0;                             ///< |M ∩ G| / |M ∪ G| of the cloth mask M and the goal's mask G.
  double mismatch = 1.0;                        ///< Mean of e over M ∪ G, in [0, 1].
};

/// The flat cloth as setFlat() measured it.
struct FlatCloth {
  double table_depth = 0.0;         ///< d_T [m]: median depth of the table in a band 1–4 cm around the cloth.
  double thickness = 0.0;           ///< h_0 [m]: median height of the cloth above the table.
  int near_column = 0;              ///< u_0: the cloth's first column.
  int far_column = 0;               ///< u_1: one past its last column.
  int first_row = 0, last_row = 0;  ///< The rows the cloth covers (inclusive).
  double fold_column() const noexcept { return 0.5 * (near_column + far_column); }  ///< u_c
};

/// The fold term's facts (widths are means over the flat cloth's rows).
struct FoldTerm {
  VisionStatus status = VisionStatus::NoCloth;  ///< NoCloth also when no flat cloth is set.
  double edge = 0.0;                            ///< [m]
  double single = 0.0;                          ///< [m]
  double length = 0.0;                          ///< [m]
  double heap = 0.0;                            ///< [m]
  double error = 0.0;                           ///< E [m]
  double mismatch = 1.0;                        ///< E / E_flat: 0 the ideal fold, 1 the flat cloth.
};

/// How folded the cloth looks: what the folding demo reports.
struct FoldFacts {
  VisionStatus status = VisionStatus::NoCloth;
  int cloth_pixels = 0;
  double cloth_area = 0.0;        ///< Visible cloth area [m²] (pixels × pixel area).
  double area_ratio = 0.0;        ///< cloth_area over the flat cloth's area: 1 flat, ½ folded in half.
  double rectangle_length = 0.0;  ///< Long side of the minimum-area rectangle [m].
  double rectangle_width = 0.0;   ///< Short side [m].
  double aspect = 0.0;            ///< rectangle_length / rectangle_width (≥ 1).
  double fill_ratio = 0.0;        ///< ρ as in ColourTerm.
};

/// Both vision terms of (7.52).
struct ImageRewardTerms {
  VisionStatus status = VisionStatus::NoCloth;
  ColourTerm colour;
  DepthTerm depth;
  GoalTerm goal;
  FoldTerm fold;
  double r_color = 0.0;  ///< R_color = w_c (1 − ρ); w_c when no cloth is visible.
  double r_depth = 0.0;  ///< R_depth = w_d ḡ; w_d · no_cloth_gradient when no cloth is visible.
  double r_goal = 0.0;   ///< R_goal = w_g · mismatch; w_g when no cloth is visible or no goal is set.
  double r_fold = 0.0;   ///< R_fold = w_f · E / E_flat; 2 w_f when no cloth is visible, w_f without a flat cloth.
  /// The vision part of the reward: −R_color − R_depth − R_goal − R_fold (add −R_acceleration for the whole reward).
  double reward() const noexcept { return -r_color - r_depth - r_goal - r_fold; }
};

/// Evaluates the image terms for one camera's images (size and pixel size fixed at construction).
class ImageReward {
 public:
  /// \throws std::invalid_argument for an invalid camera or parameters.
  ImageReward(const TopDownCamera& camera, const ImageRewardParameters& parameters);

  const TopDownCamera& camera() const noexcept { return camera_; }
  const ImageRewardParameters& parameters() const noexcept { return parameters_; }

  /// Segments the cloth in a CV_8UC3 BGR image of the camera's size into mask() (CV_8UC1, 255 on cloth).
  /// WrongImageSize for another size or type (mask() is then all zero).
  VisionStatus segment(const cv::Mat& bgr);
  const cv::Mat& mask() const noexcept { return mask_; }

  /// ρ of a CV_8UC1 mask of the camera's size (non-zero = cloth). The rectangle's area counts the pixels' extent:
  /// (w + 1)(h + 1) for the sides w, h of the rectangle through the pixel centres, so a filled axis-aligned
  /// rectangle of pixels gives exactly 1.
  ColourTerm colourTerm(const cv::Mat& mask);
  /// ḡ of a CV_32FC1 depth image [m] over the non-zero pixels of `mask` (both of the camera's size): the depth
  /// smoothed over the cloth (parameters().depth_smoothing), Sobel 3 × 3
  /// derivatives scaled by 1 / (8 s) to metres of depth per metre of table, ‖∇d‖ averaged over the eroded mask
  /// (the whole mask if erosion leaves nothing), pixels whose depth or gradient is not finite skipped.
  DepthTerm depthTerm(const cv::Mat& depth, const cv::Mat& mask);
  /// Sets the goal: a CV_8UC1 mask (non-zero = cloth) and a CV_32FC1 depth image [m] of the camera's size, e.g.
  /// the renderer's noise-free clothMask() and depth() of the ideal fold. Copies them.
  /// \throws std::invalid_argument for another size or type, a mask without cloth or a non-finite goal depth on it.
  void setGoal(const cv::Mat& mask, const cv::Mat& depth);
  bool hasGoal() const noexcept { return has_goal_; }
  /// The goal term of a depth image (CV_32FC1 [m]) and its cloth mask (CV_8UC1) against the goal; a pixel of
  /// non-finite depth counts as a mismatch. NoCloth without a goal or without cloth in `mask`.
  GoalTerm goalTerm(const cv::Mat& depth, const cv::Mat& mask) const;
  /// Measures the flat cloth (FlatCloth) from a colour (CV_8UC3) and a depth image (CV_32FC1 [m]) of the camera's
  /// size taken after the reset: the fold term's reference. \throws std::invalid_argument for images of another
  /// size or type, no cloth, no table around it, or a cloth that is not above the table.
  void setFlat(const cv::Mat& bgr, const cv::Mat& depth);
  bool hasFlat() const noexcept { return has_flat_; }
  /// Forgets the flat cloth: the fold term is unknown until the next setFlat().
  void clearFlat() noexcept { has_flat_ = false; }
  const FlatCloth& flat() const noexcept { return flat_; }
  /// The fold term of a depth image (CV_32FC1 [m]) and its cloth mask (CV_8UC1) against the flat cloth; a pixel of
  /// non-finite depth counts as one layer. NoCloth without a flat cloth or without cloth in `mask` (mismatch 2).
  FoldTerm foldTerm(const cv::Mat& depth, const cv::Mat& mask);
  /// Fold facts of a mask, `flat_area` [m²] (> 0) being the flat cloth's area (e.g. 0.5 × 0.6).
  FoldFacts foldFacts(const cv::Mat& mask, double flat_area);

  /// segment(), then colourTerm(), depthTerm(), goalTerm() and foldTerm() on the segmented mask, and the weighted
  /// terms.
  ImageRewardTerms evaluate(const cv::Mat& bgr, const cv::Mat& depth);

 private:
  bool fits(const cv::Mat& image, int type) const noexcept;

  TopDownCamera camera_;
  ImageRewardParameters parameters_;
  cv::Mat hsv_, mask_, opened_, eroded_, weights_, weighted_, smoothed_, gx_, gy_;
  cv::Mat goal_mask_, goal_depth_;
  bool has_goal_ = false;
  cv::Mat height_, smoothed_height_;
  FlatCloth flat_;
  bool has_flat_ = false;
  std::vector<std::vector<cv::Point>> contours_;
  std::vector<cv::Point> points_;
};

}  // namespace bimanual_skills::vision
