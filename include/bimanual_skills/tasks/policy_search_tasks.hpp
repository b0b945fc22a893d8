/// \file
/// The episodic tasks of the thesis' policy-search experiments (Ch. 5–6), shared by the benchmark programs and the
/// tests: the multimodal reward (6.16), DMP rollouts of a parameter vector, the planar bottle task (6.17, 6.18), the
/// WAM circle task (Fig. 6.14) and the classic PI2 via-point task. Offline: allocates and throws.
#pragma once

#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/primitives/dmp.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace bimanual_skills::tasks {

/// Minimum-jerk profile 10 s³ − 15 s⁴ + 6 s⁵ from 0 to 1 over s ∈ [0, 1].
double minimumJerk(double s) noexcept;

/// (6.16): r(θ) = 10 ‖c − θ‖ − Σ_i 5 ‖ψ_i − θ‖ over the first d entries of θ (d the optima's dimension), with optima
/// ψ_i around their centroid c, the origin, which is the worst point: in 2-D (2, 1), (−2, 1) and (0, −2).
struct MultimodalReward {
  std::vector<Eigen::VectorXd> optima = {(Eigen::VectorXd(2) << 2.0, 1.0).finished(),
                                         (Eigen::VectorXd(2) << -2.0, 1.0).finished(),
                                         (Eigen::VectorXd(2) << 0.0, -2.0).finished()};

  /// The same problem in d dimensions (DREPS at scale, thesis Sec. 6.1.3 and Appendix B.5, which give no more): each
  /// 2-D optimum repeated over the d/2 coordinate pairs and scaled by √(2/d), so that the optima's distances to each
  /// other and to the centroid are the 2-D ones; d = 2 gives the 2-D reward. \throws std::invalid_argument unless d
  /// is even and ≥ 2.
  static MultimodalReward inDimension(int d);
  int dimension() const { return static_cast<int>(optima.front().size()); }
  Eigen::VectorXd centroid() const;
  /// \throws std::invalid_argument for a θ with fewer entries than the optima.
  double operator()(const Eigen::VectorXd& theta) const;
};

/// A DMP fitted to a demonstration, whose weights (DoF-major, one block of kernels per DoF) are the policy
/// parameters θ; a rollout integrates the DMP with θ over the demonstration's duration.
struct DmpRollout {
  primitives::Dmp dmp;
  double dt;
  int steps;

  /// Fits a DMP with `kernels` kernels per DoF to `demonstration` (samples × DoF, one row every dt).
  static DmpRollout fit(const Eigen::MatrixXd& demonstration, double dt, int kernels);

  /// The fitted weights as θ.
  Eigen::VectorXd parameters() const;
  /// Positions (steps + 1 × DoF, the start first) and accelerations of the DMP with weights θ.
  /// \throws std::invalid_argument for a θ of the wrong size or a step that fails (non-finite θ).
  void rollout(const Eigen::VectorXd& theta, Eigen::MatrixXd& y, Eigen::MatrixXd& ydd) const;
  /// The basis g(x_t) at every step of a rollout (steps × kernels), for PI2's projection (5.8).
  Eigen::MatrixXd stepBasis() const;
};

/// The planar bottle task (Figs. 6.8–6.12): a path from (0, 0) to (1, 0) between two bottles.
struct BottleTask {
  std::vector<Eigen::Vector2d> centres = {{0.3, 0.0}, {0.7, 0.0}};
  double radius = 0.08;  ///< 4 cm bottle radius widened by a 4 cm tool.
  bool crossing_term = true;

  /// The initial policy: a DMP with 10 kernels per DoF fitted to the straight line (minimum-jerk timing, 1 s at
  /// 100 Hz).
  static DmpRollout initialPolicy();
  /// What initialPolicy() is fitted to: the straight line's minimum-jerk path, 101 samples × (x, y) over 1 s.
  static Eigen::MatrixXd demonstration();
  static constexpr double kDemonstrationStep = 0.01;  ///< [s] between its samples.

  /// (6.18), or (6.17) without the crossing term, of a planar path (rows = samples): −2 per bottle knocked down,
  /// −0.15 × length, −4 unless the path passes the bottles on opposite sides. `satisfactory`: between the bottles,
  /// none down.
  double reward(const Eigen::MatrixXd& y, bool* satisfactory = nullptr) const;
};

/// A circle in space.
struct Circle3d {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< Unit normal of its plane.
  double radius = 0.0;

  /// Best fit of points (rows, ≥ 3): plane by SVD, circle in the plane by the algebraic (Kåsa) fit.
  /// \throws std::invalid_argument for fewer than 3 points or not 3 columns.
  static Circle3d fit(const Eigen::MatrixXd& points);
  /// Shortest distance from p to the circle.
  double distance(const Eigen::Vector3d& p) const noexcept;
};

/// A unimodal 7-DoF task with the WAM's kinematics (Fig. 6.14): an inaccurate "kinesthetic" joint-space ellipse
/// with noise is demonstrated; the tool must trace the circle that best fits the demonstrated tool path.
class CircleTask {
 public:
  /// The demonstration's noise comes from a generator seeded with `seed`. \throws std::invalid_argument if the
  /// chain does not have 7 joints.
  CircleTask(const kinematics::ChainModel& model, std::uint32_t seed);

  const DmpRollout& policy() const noexcept { return policy_; }
  double radius() const noexcept { return circle_.radius; }
  /// −(mean distance of the tool from the circle [mm] + 10⁻³ · mean squared joint acceleration).
  double reward(const Eigen::VectorXd& theta);

 private:
  CircleTask(const kinematics::ChainModel& model, const Eigen::MatrixXd& demonstration);

  kinematics::ChainModel model_;
  kinematics::ChainData data_;
  DmpRollout policy_;
  Circle3d circle_;
  Eigen::MatrixXd y_, ydd_;
};

/// Stulp's classic via-point task: a 1-D DMP (10 kernels) from 0 to 1 in 1 s at 100 Hz, minimum-jerk
/// demonstration, through y = 0.5 at t = 0.3 s. Immediate cost 10⁻⁶ ÿ² per step and 10⁴ (y − 0.5)² at the
/// via-point's step.
class ViaPointTask {
 public:
  ViaPointTask();

  const DmpRollout& policy() const noexcept { return policy_; }
  /// PI2's basis per step (steps × kernels).
  const Eigen::MatrixXd& basis() const noexcept { return basis_; }
  /// The immediate costs of θ (one per step); `via_error` (optional) gets viaPointError(θ) of the same rollout.
  Eigen::VectorXd stepCosts(const Eigen::VectorXd& theta, double* via_error = nullptr);
  /// |y(t_via) − y_via| of θ.
  double viaPointError(const Eigen::VectorXd& theta);

  static constexpr double kViaTime = 0.3, kViaPosition = 0.5;

 private:
  DmpRollout policy_;
  Eigen::MatrixXd basis_, y_, ydd_;
  int via_step_;
};

}  // namespace bimanual_skills::tasks
