/// \file
/// Time alignment of several demonstrations by gradient descent (thesis Sec. 6.2, Fig. 6.9: the human-guided
/// trajectories' common parts are aligned in time before their reward-weighted average is taken).
///
/// A curve is a matrix whose rows are samples equally spaced in its phase s ∈ [0, 1] (columns: dimensions), read
/// between samples by linear interpolation. A warp is the monotone map u(s) = s + Σ_{k=1..K} a_k sin(kπ s) of [0, 1]
/// onto itself (u(0) = 0, u(1) = 1 for any a; monotone while du/ds > 0). Aligning a curve c to a reference r finds
/// the a minimising the mean squared distance C(a) = 1/N Σ_i ‖c(u(s_i)) − r(s_i)‖² over N phases s_i, by gradient
/// descent with a backtracking (Armijo) line search that keeps du/ds ≥ `min_slope` everywhere:
///   ∂C/∂a_k = 2/N Σ_i (c(u_i) − r_i) · c'(u_i) sin(kπ s_i).
/// Offline: allocates and throws std::invalid_argument. Target bimanual_skills_learning.
#pragma once

#include <Eigen/Core>

#include <vector>

namespace bimanual_skills::learning {

/// u(s) = s + Σ_k a_k sin(kπ s); no coefficients: the identity.
struct TimeWarp {
  Eigen::VectorXd a;

  double operator()(double s) const noexcept;
  double slope(double s) const noexcept;  ///< du/ds
  /// The least du/ds over `samples` phases equally spaced in [0, 1].
  double minSlope(int samples = 201) const noexcept;
};

/// The curve at phase u ∈ [0, 1] (clamped), by linear interpolation between its rows.
/// \throws std::invalid_argument for a curve of fewer than two rows.
Eigen::RowVectorXd samplePhase(const Eigen::MatrixXd& curve, double u);
/// The curve read at u(s_i), s_i = i / (samples − 1): `samples` rows.
/// \throws std::invalid_argument for fewer than two rows or samples.
Eigen::MatrixXd warpCurve(const Eigen::MatrixXd& curve, const TimeWarp& warp, int samples);

struct TimeAlignmentOptions {
  int harmonics = 4;         ///< K, the warp's coefficients.
  int samples = 100;         ///< N, the phases compared and the rows of the aligned curves.
  int iterations = 200;      ///< Gradient steps per curve and pass at most.
  int passes = 5;            ///< Of alignCurves(): align every curve to the mean, take the mean again.
  double min_slope = 0.2;    ///< Every warp keeps du/ds ≥ this (in (0, 1]).
  double tolerance = 1e-12;  ///< A step that lowers C by less than this (relative) ends the descent.
  /// \throws std::invalid_argument naming the entry out of range.
  void validate() const;
};

/// C(a) of the file's comment: the mean squared distance of the warped curve to the reference, both read at
/// `samples` phases. \throws std::invalid_argument for curves of different widths or fewer than two rows.
double alignmentCost(const Eigen::MatrixXd& curve, const Eigen::MatrixXd& reference, const TimeWarp& warp, int samples);
/// ∂C/∂a of the file's comment (the derivative of alignmentCost() where the warp meets no sample of the curve).
/// \throws std::invalid_argument as alignmentCost().
Eigen::VectorXd alignmentGradient(const Eigen::MatrixXd& curve, const Eigen::MatrixXd& reference, const TimeWarp& warp,
                                  int samples);

/// The warp (options.harmonics coefficients) aligning `curve` to `reference`, by gradient descent from `initial`
/// (none: the identity; it must keep min_slope). \throws std::invalid_argument for bad options, curves or a
/// non-finite sample.
TimeWarp alignToReference(const Eigen::MatrixXd& curve, const Eigen::MatrixXd& reference,
                          const TimeAlignmentOptions& options, const TimeWarp& initial = {});

struct TimeAlignment {
  std::vector<TimeWarp> warps;           ///< Of each curve.
  std::vector<Eigen::MatrixXd> aligned;  ///< Each curve read at its warp (samples rows).
  Eigen::MatrixXd mean;                  ///< Of the aligned curves.
  double cost_before = 0.0;              ///< Mean over the curves of C to their mean, each read in its own linear time.
  double cost_after = 0.0;               ///< The same, aligned.
};

/// Aligns the curves to each other: the reference starts as their mean in linear time; each pass aligns every curve
/// to it (warm-started from the last pass), re-centres the warps on their average (subtracting the coefficients'
/// mean, where the result keeps min_slope, so that the mean keeps the curves' average timing) and takes the mean
/// of the aligned curves as the next reference. \throws std::invalid_argument for no curves, curves of different
/// widths, bad options or non-finite samples.
TimeAlignment alignCurves(const std::vector<Eigen::MatrixXd>& curves, const TimeAlignmentOptions& options);

/// The weights of a reward-weighted average: w_k ∝ exp(h (R_k − max R) / (max R − min R)), summing to 1 (equal
/// when all the rewards are). \throws std::invalid_argument for no rewards, a non-finite one or h < 0.
Eigen::VectorXd rewardWeights(const Eigen::VectorXd& rewards, double h);

}  // namespace bimanual_skills::learning
