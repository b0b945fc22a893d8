/// \file
/// Cartesian DMP of a pose: a 3-DoF Dmp (thesis 5.14–5.15) for the position and one of two orientation DMPs — the
/// unit-quaternion DMP of Ude et al. (ICRA 2014) or the thesis' 3-D quaternion-vector encoding (Sec. 7.2.3, footnote).
#pragma once

#include "bimanual_skills/primitives/dmp.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <vector>

namespace bimanual_skills::primitives {

/// A pose: position [m] and orientation (unit quaternion), both in the same base frame.
struct Pose {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
};

/// How the orientation is encoded.
enum class OrientationEncoding {
  /// Ude et al. 2014, written with one consistent τ (the movement's duration) as the position DMP:
  ///   τ η̇ = α_z (β_z 2 log(g ∗ q̄) − η) + f(x),   τ q̇ = ½ η ∗ q,   η = τ ω,
  /// ω [rad/s] the angular velocity in the base frame, log the quaternion logarithm (a rotation vector / 2),
  /// integrated with the exponential map q ← exp(dt/(2τ) η) ∗ q, so q stays a unit quaternion. Any rotation, also
  /// more than π from the start. g and −g are the same orientation but not the same attractor: q converges to the
  /// quaternion g itself, so give a new goal the sign nearest the current goal (see nearestSign()).
  UnitQuaternion,
  /// Thesis Sec. 7.2.3, footnote 1: each orientation relative to the start, q_rel = q_s⁻¹ ∗ q (w ≥ 0), is encoded by
  /// its vector part v = u sin(θ/2) as 3 more DMP DoF, and rebuilt as q = q_s ∗ (√(1 − ‖v‖²), v). Limitations: an
  /// orientation more than π from the start is encoded as the equivalent rotation of less than π the other way (the
  /// sign of q_w is lost), so such a movement cannot be reproduced; and when the DMP's v leaves the unit ball
  /// (‖v‖ > 1, possible during overshoots), it is clamped to ‖v‖ = 1 (θ = π) and step() says so.
  QuaternionVector,
};

/// The running state of a CartesianDmp (its "Data"); the goal pose may be changed at any time.
struct CartesianDmpState {
  /// Position part: y [m], ẏ [m/s], ÿ [m/s²], the goal position, and the shared phase x and time t [s].
  DmpState position;
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< q, unit
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();       ///< ω [rad/s], base frame
  Eigen::Vector3d angular_acceleration = Eigen::Vector3d::Zero();   ///< ω̇ [rad/s²], base frame
  Eigen::Quaterniond goal_orientation = Eigen::Quaterniond::Identity();
  /// QuaternionVector: v = vec(q_s⁻¹ ∗ q), its derivatives and goal (kept in step with goal_orientation by step());
  /// UnitQuaternion: unused (empty vectors).
  DmpState orientation_vector;

  Pose pose() const { return Pose{position.y, orientation}; }
  Pose goal() const { return Pose{position.goal, goal_orientation}; }
  void setGoal(const Pose& goal) {
    position.goal = goal.position;
    goal_orientation = goal.orientation;
  }
};

/// Immutable Cartesian DMP: the position is a 3-DoF Dmp, the orientation has its own 3 × kernels weights on the same
/// kernels, duration and phase. Build with fit() or from weights.
class CartesianDmp {
 public:
  /// Weights are 3 × kernels each. For UnitQuaternion the orientation weights shape the forcing term of ω (in the
  /// base frame); for QuaternionVector they are those of the DMP of v.
  /// \throws std::invalid_argument for wrong sizes, non-finite values, non-unit quaternions (|‖q‖ − 1| > 1e-6)
  ///         or a duration ≤ 0.
  CartesianDmp(const DmpParameters& parameters, OrientationEncoding encoding, const Eigen::MatrixXd& position_weights,
               const Eigen::MatrixXd& orientation_weights, const Pose& start, const Pose& goal, double duration);

  /// Least-squares fit to poses sampled every dt: the position as Dmp::fit; the orientation, after making the
  /// quaternions' signs continuous (q_k · q_{k−1} ≥ 0), from ω_{k+½} = 2 log(q_{k+1} ∗ q̄_k) / dt, smoothed with the
  /// same zero-phase low-pass (`smoothing_hz`, 0 = none) and integrated back to orientations, ω_k and ω̇_k by central
  /// differences, then f = τ² ω̇ − α_z (β_z 2 log(g ∗ q̄) − τ ω) (UnitQuaternion), or Dmp::fit of v
  /// (QuaternionVector). With goal_scaled_forcing the orientation forcing is scaled per axis by 2 log(g ∗ q̄_0)
  /// (Ude's D_o) or by v_g − v_0 = v_g.
  /// \throws std::invalid_argument for fewer than 10 poses, dt ≤ 0, non-finite values or non-unit quaternions.
  static CartesianDmp fit(const DmpParameters& parameters, OrientationEncoding encoding,
                          const std::vector<Pose>& demonstration, double dt, double smoothing_hz = 20.0);

  const DmpParameters& parameters() const noexcept { return position_.parameters(); }
  OrientationEncoding encoding() const noexcept { return encoding_; }
  /// The position DMP (3 DoF).
  const Dmp& position() const noexcept { return position_; }
  /// The orientation's 3-DoF DMP: its weights; start 0 and goal 2 log(g ∗ q̄_s) (UnitQuaternion) or vec(q_s⁻¹ ∗ g)
  /// (QuaternionVector). For UnitQuaternion only its weights, kernels and goal − start (for goal scaling) are used.
  const Dmp& orientation() const noexcept { return orientation_; }
  const Eigen::MatrixXd& positionWeights() const noexcept { return position_.weights(); }
  const Eigen::MatrixXd& orientationWeights() const noexcept { return orientation_.weights(); }
  const Pose& start() const noexcept { return start_; }
  const Pose& goal() const noexcept { return goal_; }
  double duration() const noexcept { return position_.duration(); }

  /// A copy with another duration (time scaling) or another goal pose.
  CartesianDmp withDuration(double duration) const;
  CartesianDmp withGoal(const Pose& goal) const;

  /// A state at the start pose, at rest, phase 1, with the model's goal.
  CartesianDmpState initialState() const;

  /// One integration step of dt [s] (semi-implicit Euler; the orientation by the exponential map for UnitQuaternion).
  /// Validates the whole state first and leaves it unchanged on InvalidInput.
  /// Real-time safe: no allocation, no exceptions.
  DmpStatus step(CartesianDmpState& state, double dt) const noexcept;
  /// The same step with the forcing terms given by the caller instead of the weights' (a coordinated DR-DMP's
  /// Ω^t W g(x), 7.24): `forcing` holds the position's 3 values, then the orientation's 3 (of v for
  /// QuaternionVector, of ω for UnitQuaternion), used as given. InvalidInput (state unchanged) also for a forcing of
  /// another size or not finite. Real-time safe: no allocation, no exceptions.
  DmpStatus step(CartesianDmpState& state, double dt, const Eigen::Ref<const Eigen::VectorXd>& forcing) const noexcept;

 private:
  /// step() with the forcing from the weights (forcing == nullptr) or given.
  DmpStatus stepWith(CartesianDmpState& state, double dt,
                     const Eigen::Ref<const Eigen::VectorXd>* forcing) const noexcept;

  OrientationEncoding encoding_;
  Dmp position_, orientation_;
  Pose start_, goal_;
};

/// Quaternion logarithm of a unit quaternion, log(q) = atan2(‖v‖, w) v / ‖v‖ (half a rotation vector; no sign
/// canonicalisation: for w < 0 the angle is more than π). Real-time safe: no allocation, no exceptions.
Eigen::Vector3d quaternionLog(const Eigen::Quaterniond& q) noexcept;
/// Quaternion exponential of r ∈ ℝ³, exp(r) = (cos ‖r‖, sin ‖r‖ r / ‖r‖), a unit quaternion.
/// Real-time safe: no allocation, no exceptions.
Eigen::Quaterniond quaternionExp(const Eigen::Vector3d& r) noexcept;
/// `q` or −q, whichever is nearer `reference` (non-negative dot product): the same orientation, the sign a
/// UnitQuaternion DMP's goal should have. Real-time safe: no allocation, no exceptions.
Eigen::Quaterniond nearestSign(const Eigen::Quaterniond& q, const Eigen::Quaterniond& reference) noexcept;
/// The thesis' orientation coordinates relative to the start (QuaternionVector): vec(q_s⁻¹ ∗ q) with the sign that
/// makes w ≥ 0. Real-time safe: no allocation, no exceptions.
Eigen::Vector3d relativeQuaternionVector(const Eigen::Quaterniond& start, const Eigen::Quaterniond& q) noexcept;

}  // namespace bimanual_skills::primitives
