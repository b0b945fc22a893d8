/// \file
/// Joint friction models of the thesis with hysteresis (Sec. 2.3.2, 4.2.2), written as F = bᵀ φ(q, q̇, sign q̈):
/// linear in the coefficients b once the nonlinear parameters (s, z, h) are fixed, which is how they are identified.
#pragma once

#include "bimanual_skills/dynamics/dynamics_status.hpp"

#include <Eigen/Core>

#include <array>
#include <string>
#include <vector>

namespace bimanual_skills::dynamics {

/// The friction model of a joint.
enum class FrictionModelType {
  Viscous,  ///< F = b1 q̇.
  Initial,  ///< (2.13) F = b1 atan(s q̇) + b2 q̇.
  Basic,    ///< (2.14) F = b1 atan(s q̇ + z sign(q̈)) + b2 q̇.
  Advanced,  ///< (4.16) F = b1 q + b2 q̇ + b3 atan(s q̇ + z sign q̈) + ½(1 + sign q̇) Σ b_{3+j} f_j + ½(1 − sign q̇) Σ
             ///< b_{8+j} f_j, f_j = 4 sin((2j − 1) h q) / (π (2j − 1)), j = 1..5.
};

/// "viscous", "initial", "basic", "advanced".
const char* toString(FrictionModelType type) noexcept;
/// Parses toString()'s names; false if unknown.
bool parseFrictionModelType(const std::string& name, FrictionModelType& type) noexcept;
/// Number of linear coefficients b of a model (1, 2, 2, 13).
int linearParameterCount(FrictionModelType type) noexcept;

/// Parameters of one joint's friction model.
struct JointFriction {
  FrictionModelType type = FrictionModelType::Viscous;
  Eigen::VectorXd b = Eigen::VectorXd::Zero(1);  ///< linearParameterCount(type) coefficients.
  double s = 1.0;                                ///< atan slope [s/rad].
  double z = 0.0;                                ///< Hysteresis offset inside the atan.
  double h = 1.0;                                ///< Fourier base frequency [1/rad].

  /// Throws std::invalid_argument if b has the wrong size or any value is not finite.
  void validate() const;
};

/// Regressor φ of a model at (q, q̇, σ), σ = sign of the joint acceleration (−1, 0 or +1): F = bᵀ φ. φ must have
/// linearParameterCount(type) entries. Real-time safe: no allocation, no exceptions.
void frictionRegressor(const JointFriction& joint, double q, double qd, double accel_sign,
                       Eigen::Ref<Eigen::VectorXd> phi) noexcept;

/// Friction torque of one joint, bᵀ φ. Real-time safe: no allocation, no exceptions.
double frictionTorque(const JointFriction& joint, double q, double qd, double accel_sign) noexcept;

/// A cable-coupled joint pair (the WAM's 2–3 and 5–6, Sec. 4.2.2): each joint has its full model (modA, in the
/// chain's JointFriction) and a reduced one (modB), used while the other joint of the pair moves faster:
/// mod_i = A if |q̇_i| ≥ |q̇_j| + ε, B if |q̇_j| ≥ |q̇_i| + ε, else unchanged (the dead band ε prevents chattering).
struct CoupledPair {
  int first = 0;  ///< Joint indices (0-based) of the pair.
  int second = 1;
  JointFriction reduced_first;   ///< modB of `first`.
  JointFriction reduced_second;  ///< modB of `second`.
  double epsilon = 0.05;         ///< Dead band [rad/s].
};

/// Friction of a whole chain: one model per joint plus optional coupled pairs.
struct FrictionModel {
  std::vector<JointFriction> joints;
  std::vector<CoupledPair> pairs;

  int size() const noexcept { return static_cast<int>(joints.size()); }
  /// Throws std::invalid_argument naming the joint or pair that is invalid (sizes, indices, ε < 0, non-finite).
  void validate() const;
};

/// Which model (A = full, B = reduced) each joint of a coupled pair uses; kept between calls (the hysteresis of the
/// switching). All joints start in A.
struct FrictionState {
  explicit FrictionState(const FrictionModel& model);
  std::vector<char> reduced;  ///< 1 while joint i uses its modB.
};

/// Updates the A/B mode of every joint of a coupled pair from the joint velocities (the switching rule of
/// CoupledPair). Real-time safe: no allocation, no exceptions; q̇ must have model.size() finite entries.
void updatePairModes(const FrictionModel& model, FrictionState& state,
                     const Eigen::Ref<const Eigen::VectorXd>& qd) noexcept;

/// The model a joint uses in the given state: its own, or its pair's reduced one while in mode B.
const JointFriction& activeJointModel(const FrictionModel& model, const FrictionState& state, int joint) noexcept;

/// Friction torques of every joint at (q, q̇) with acceleration signs σ (see signal::AccelerationSign), updating the
/// pair modes in `state`. WrongSize or NotFinite on bad input (then `tau` and `state` are left unchanged).
/// Real-time safe: no allocation, no exceptions.
[[nodiscard]] DynamicsStatus frictionTorques(const FrictionModel& model, FrictionState& state,
                                             const Eigen::Ref<const Eigen::VectorXd>& q,
                                             const Eigen::Ref<const Eigen::VectorXd>& qd,
                                             const Eigen::Ref<const Eigen::VectorXd>& accel_sign,
                                             Eigen::Ref<Eigen::VectorXd> tau) noexcept;

}  // namespace bimanual_skills::dynamics
