/// \file
/// Parameters of the simulator's "true plant": the joint friction, rotor inertias, torque limits and sensors that
/// the simulated arms have and the controllers do not know exactly, with the YAML loader of `config/plant.yaml`.
///
/// Friction acts on *channels*: a direct-drive joint is one channel with velocity u = q̇_i; a cable differential
/// (the WAM's joints 2–3 and 5–6, thesis Sec. 4.2.2) is two motor channels with u_a = q̇_i + k q̇_j and
/// u_b = q̇_i − k q̇_j (joint-side units), whose friction reaches the joints through the transmission
/// (τ_i = f_a + f_b, τ_j = k (f_a − f_b)). When joint j moves faster than joint i the two motors turn in opposite
/// directions and their friction on joint i cancels: the reduction the thesis models with its modA/modB switching
/// arises here from the mechanism. Each channel obeys the law of FrictionLaw (see ArmPlant for the time stepping).
#pragma once

#include <Eigen/Core>

#include <string>
#include <utility>
#include <vector>

namespace bimanual_skills::sim {

/// Friction law of one channel (position m = gᵀq, velocity u = gᵀq̇, in joint-side units):
///
/// - sticking (u = 0): the channel holds while the torque needed to keep it still stays below
///   F_s ρ(m);
/// - slipping: a torque opposing u of magnitude
///   μ(m, u, σ) = ρ(m, sign u) [F_c (1 + η σ) + (F_s − F_c) exp(−(u / v_s)²)] + b u,
///   where σ = +1 while |u| grows and −1 while it shrinks (the hysteresis of thesis eq. 2.14/4.16: more friction
///   when accelerating than when decelerating at the same speed) and
///   ρ(m, ±) = 1 + r sin(ω m + φ_±) is a position ripple whose phase depends on the direction (as the two Fourier
///   sets of thesis eq. 4.16).
struct FrictionLaw {
  double static_friction = 0.0;        ///< F_s: breakaway torque [N m], ≥ F_c.
  double coulomb = 0.0;                ///< F_c: sliding (Coulomb) torque [N m], ≥ 0.
  double stribeck_velocity = 0.05;     ///< v_s: decay speed from F_s to F_c [rad/s], > 0.
  double viscous = 0.0;                ///< b: viscous coefficient [N m s/rad], ≥ 0.
  double hysteresis = 0.0;             ///< η ∈ [0, 1): relative Coulomb change between speeding up and slowing down.
  double ripple = 0.0;                 ///< r ∈ [0, 1): relative amplitude of the position ripple.
  double ripple_frequency = 0.0;       ///< ω: ripple frequency [rad⁻¹ of channel position], ≥ 0.
  double ripple_phase_positive = 0.0;  ///< φ₊ [rad], used while u > 0.
  double ripple_phase_negative = 0.0;  ///< φ₋ [rad], used while u < 0.

  /// True when every coefficient is zero (the channel has no friction).
  bool isZero() const noexcept;
  /// Throws std::invalid_argument naming `where` and the offending entry.
  void validate(const std::string& where) const;
};

/// How joints are driven: one joint directly, or two through a cable differential.
struct Drive {
  int first = 0;         ///< Joint index (0-based).
  int second = -1;       ///< Second joint of a differential (0-based), −1 for a direct drive.
  double ratio = 1.0;    ///< k of u = q̇_first ± k q̇_second (differentials only), > 0.
  FrictionLaw friction;  ///< Law of the joint (direct) or of each of the two motors (differential).

  bool isDifferential() const noexcept { return second >= 0; }
};

/// The true plant of one arm with n joints.
struct ArmPlantParameters {
  /// Every joint exactly once, in one direct drive or one differential. Empty = no friction at all.
  std::vector<Drive> drives;
  Eigen::VectorXd rotor_inertia;       ///< J_m: reflected rotor inertia per joint [kg m²], ≥ 0 (empty = zeros).
  Eigen::VectorXd encoder_resolution;  ///< Δ: position quantisation per joint [rad], 0 = exact (empty = zeros).
  Eigen::VectorXd velocity_noise;      ///< σ: std. dev. of white velocity noise per joint [rad/s] (empty = zeros).
  bool saturate_torque = true;         ///< Clip commands to the URDF effort limits, as the motor drivers do.

  /// Throws std::invalid_argument naming `where` and the entry that is wrong for an arm of n joints.
  void validate(int n, const std::string& where) const;
  /// A plant without friction, rotor inertia or sensor imperfections (the rigid-body model alone).
  static ArmPlantParameters ideal();
};

/// The true plant of every arm, by arm name.
struct PlantModel {
  std::vector<std::pair<std::string, ArmPlantParameters>> arms;

  /// Loads `config/plant.yaml`'s format:
  /// \code
  /// arms:
  ///   left:
  ///     rotor_inertia: [7 numbers]          # optional, default zeros
  ///     encoder_resolution: [7 numbers]     # optional
  ///     velocity_noise: [7 numbers]         # optional
  ///     saturate_torque: true               # optional
  ///     friction:                           # optional; joints are 1-based
  ///       - {joint: 1, static: 2.4, coulomb: 1.8, stribeck_velocity: 0.04, viscous: 1.27, hysteresis: 0.15,
  ///          ripple: 0.1, ripple_frequency: 3, ripple_phase: [0.0, 1.2]}
  ///       - {differential: [2, 3], ratio: 0.595, static: ..., ...}     # the law of each of the two motors
  /// \endcode
  /// Sizes are checked against the arm when the simulation is built (ArmPlantParameters::validate).
  /// \throws std::invalid_argument naming the file and the entry for unreadable files, unknown keys, missing or
  /// non-numeric values and values out of range.
  static PlantModel fromYamlFile(const std::string& path);

  /// The parameters of arm `name`. \throws std::invalid_argument if the model has no such arm.
  const ArmPlantParameters& arm(const std::string& name) const;
  bool hasArm(const std::string& name) const noexcept;
};

}  // namespace bimanual_skills::sim
