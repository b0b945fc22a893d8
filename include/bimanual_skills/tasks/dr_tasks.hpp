/// \file
/// The episodic tasks of the thesis' dimensionality-reduction experiments (Ch. 7), shared by dr_benchmark and the
/// tests: planar arms of unit links with the Cartesian tracking reward (7.22, Fig. 7.5) and the via-point reward
/// (7.50, Table 7.3), the WAM circle from a noisy, kinesthetic-like demonstration (7.51, Table 7.4), and DR-DMP
/// rollouts with exploration outside the latent space. The thesis does not give the constants of its rewards, its
/// via-points or the demonstrations; ours are stated here. Offline: allocates and throws.
#pragma once

#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/primitives/dr_dmp.hpp"
#include "bimanual_skills/tasks/policy_search_tasks.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <random>
#include <vector>

namespace bimanual_skills::tasks {

/// Tip (x, y) [m] of a planar arm of unit links with relative joint angles q: Σ_i (cos θ_i, sin θ_i),
/// θ_i = Σ_{j ≤ i} q_j. Real-time safe: no allocation, no exceptions.
Eigen::Vector2d planarTip(const Eigen::Ref<const Eigen::VectorXd>& q) noexcept;

/// Joint trajectories (samples × dofs over s ∈ [0, 1]) that follow the same minimum-jerk profile from 0 to
/// `amplitude` on every joint plus, on each joint, Σ_a A_a exp(−(s − c_a)² / w²), A_a ~ N(0, variance) drawn from
/// rng joint by joint (Sec. 7.2.3, Fig. 7.6b). \throws std::invalid_argument for dofs < 1, samples < 2, width ≤ 0 or
/// variance ≤ 0.
Eigen::MatrixXd perturbedMinimumJerk(int dofs, int samples, double amplitude, const std::vector<double>& centres,
                                     double width, double variance, std::mt19937& rng);

/// Central second differences of rows sampled every dt (zero at the first and last row).
Eigen::MatrixXd secondDifferences(const Eigen::MatrixXd& y, double dt);

/// One DR-DMP rollout.
struct DrDmpRollout {
  Eigen::MatrixXd positions;      ///< steps + 1 rows: the start, then after each step.
  Eigen::MatrixXd accelerations;  ///< steps + 1 rows: zero, then the ÿ of each step.
  Eigen::MatrixXd forcing;        ///< steps rows: f of each step (exploration included), the CMU's f_t^k.
};

/// Integrates `dmp` for `steps` steps of dt from its initial state. With exploration σ > 0, every step adds
/// N(0, σ² I) to the d forcing values (exploration outside the latent space, "noise added to the d-dimensional
/// acceleration commands", Sec. 7.2.3), drawn from rng. \throws std::invalid_argument if a step fails.
void rolloutDrDmp(const primitives::DrDmp& dmp, double dt, int steps, double exploration, std::mt19937& rng,
                  DrDmpRollout& out);

/// Table 7.3's task: a d-DoF planar arm of unit links whose joints all move from 0 to 2π/d in 1 s (minimum jerk,
/// 100 steps of 10 ms) must pass two via-points. Ten demonstrations perturb every joint by two bumps (centres 1/3 and
/// 2/3 of the movement, width 0.1, A_a ~ N(0, 1/(4d)), Fig. 7.6b). The via-points lie on the unperturbed movement's tip
/// path ("along the trajectory"), 1 m ahead of where its tip is at 0.3 s and 0.6 s: the arm must run ahead of its
/// schedule, which the joints' common (first principal) direction can do alone. Reward (7.50) with C_x = 0.1 I and, on
/// joint accelerations, C_u = 10⁻⁵ diag(d + 1 − j) / Σ_j (d + 1 − j), which weighs the first joints, which move the
/// whole arm, most.
class PlanarViaPointTask {
 public:
  /// The demonstrations' bumps come from a generator seeded with `seed`. \throws std::invalid_argument for dofs < 2.
  PlanarViaPointTask(int dofs, std::uint32_t seed);

  int dofs() const noexcept { return dofs_; }
  double dt() const noexcept { return kDt; }
  int steps() const noexcept { return kSteps; }
  const std::vector<Eigen::MatrixXd>& demonstrations() const noexcept { return demonstrations_; }
  const std::vector<Eigen::Vector2d>& viaPoints() const noexcept { return via_points_; }
  const std::vector<int>& viaSteps() const noexcept { return via_steps_; }
  /// (7.50): −Σ_v (x_{t_v} − x_v)ᵀ C_x (x_{t_v} − x_v) − Σ_t q̈_tᵀ C_u q̈_t of a rollout (steps + 1 rows each).
  /// \throws std::invalid_argument for wrong sizes.
  double reward(const Eigen::MatrixXd& positions, const Eigen::MatrixXd& accelerations) const;

  static constexpr double kDt = 0.01, kViaWeight = 0.1, kAccelerationWeight = 1e-5;
  /// The via-points lie kViaLead [m] ahead of the mean motion's tip on its path (searched in steps of kViaAngleStep).
  static constexpr double kViaLead = 1.0, kViaAngleStep = 1e-3;
  static constexpr int kSteps = 100, kDemonstrations = 10;

 private:
  int dofs_;
  std::vector<Eigen::MatrixXd> demonstrations_;
  std::vector<Eigen::Vector2d> via_points_;
  std::vector<int> via_steps_;
  Eigen::VectorXd acceleration_weights_;
};

/// Fig. 7.5's task: a d-DoF planar arm of unit links tracks a Cartesian path over 1 s (101 samples). The
/// demonstrations move every joint from 0 to π/d (minimum jerk) with two bumps per joint (as above, variance
/// 1/(4d)); the path to track is the tip path of q_j(s) = π/d · minimumJerk(s) + 0.05 sin(π s). Reward (7.22) with
/// D = I and H = 10⁻⁶ I on accelerations by second differences.
class PlanarTrackingTask {
 public:
  PlanarTrackingTask(int dofs, std::uint32_t seed);

  int dofs() const noexcept { return dofs_; }
  int samples() const noexcept { return kSamples; }
  double dt() const noexcept { return 1.0 / (kSamples - 1); }
  const std::vector<Eigen::MatrixXd>& demonstrations() const noexcept { return demonstrations_; }
  const Eigen::MatrixXd& target() const noexcept { return target_; }  ///< samples × 2
  /// (7.22): −Σ_t (e_tᵀ D e_t + q̈_tᵀ H q̈_t), e_t the tip's error. \throws std::invalid_argument for wrong sizes.
  double reward(const Eigen::MatrixXd& positions) const;

  static constexpr int kSamples = 101, kDemonstrations = 10;
  static constexpr double kTrackingWeight = 1.0, kAccelerationWeight = 1e-6;

 private:
  int dofs_;
  std::vector<Eigen::MatrixXd> demonstrations_;
  Eigen::MatrixXd target_;
};

/// Where the smooth perturbations of WamCircleTask's demonstration act.
enum class CirclePerturbation {
  /// On every joint, three bumps (centres uniform in time, width 0.4 s, amplitudes N(0, 0.03²) rad) added after IK:
  /// independent per joint, so the demonstration's deviations span all seven joint directions.
  Joint,
  /// On the tool, before IK, as a hand guiding the tool deviates from the circle: four bumps (centres uniform in
  /// time, width 1 s, amplitudes N(0, 0.008²) m per axis), faded in over the first second and out over the last
  /// (minimum-jerk ramps), so the tool starts and ends at the nominal point of the circle (the posture may end
  /// elsewhere along the arm's self-motion; the circle the reward fits passes a few millimetres off, the deviations
  /// shift it) and the joint deviations are those of the tool through the arm's kinematics.
  Task,
};

/// The circle WamCircleTask's reward measures distances from.
enum class CircleTarget {
  /// The circle that best fits the demonstrated tool path, as the thesis computes it from its recorded
  /// demonstration (Circle3d::fit); the perturbations shift it off the demonstration's start.
  Fitted,
  /// The circle the demonstration was made from: the teacher's intent, which a real recording does not give. The
  /// tool starts on it with CirclePerturbation::Task (its deviations fade in), not with Joint.
  Nominal,
};

/// Table 7.4's task on the WAM (7 DoF): a "kinesthetic" demonstration of a circle of radius 0.12 m (tilted 30° about
/// the base x axis, around the tool position of q = (0, 0.6, 0, 1.6, 0, 0.4, 0)) drawn once in 8 s with
/// minimum-jerk timing at 25 Hz: the circle through the global IK solver (constant tool orientation, each sample
/// seeded with the previous solution), smooth perturbations on the joints or on the tool (CirclePerturbation), and
/// white noise of 2 mrad on every joint but at the first and last sample. Reward (7.51):
/// R = −(Σ_t r_circle^t + α Σ_t ‖q̈_t‖²), r_circle^t [m] the tool's distance from the circle that best fits the
/// demonstrated tool path (or the nominal one, CircleTarget), α = 2 · 10⁻⁵.
class WamCircleTask {
 public:
  /// \throws std::invalid_argument for a chain without 7 joints or an IK failure along the circle.
  WamCircleTask(const kinematics::ChainModel& model, std::uint32_t seed,
                CirclePerturbation perturbation = CirclePerturbation::Joint,
                CircleTarget target = CircleTarget::Fitted);

  const Eigen::MatrixXd& demonstration() const noexcept { return demonstration_; }  ///< (steps + 1) × 7
  double dt() const noexcept { return kDt; }
  int steps() const noexcept { return static_cast<int>(demonstration_.rows()) - 1; }
  const Circle3d& circle() const noexcept { return circle_; }
  /// (7.51) of a rollout (positions and accelerations, steps + 1 rows each). Uses this task's scratch: one task per
  /// thread. \throws std::invalid_argument for wrong sizes.
  double reward(const Eigen::MatrixXd& positions, const Eigen::MatrixXd& accelerations);
  /// The tool position (rows × 3) at each row of joint positions (rows × 7). Uses this task's scratch.
  /// \throws std::invalid_argument for other than 7 columns or non-finite positions.
  Eigen::MatrixXd toolPath(const Eigen::MatrixXd& positions);

  static constexpr double kDt = 0.04, kDuration = 8.0, kAccelerationWeight = 2e-5;

 private:
  kinematics::ChainModel model_;
  kinematics::ChainData data_;
  Eigen::MatrixXd demonstration_;
  Circle3d circle_;
};

}  // namespace bimanual_skills::tasks
