/// \file
/// The true plant of one arm in joint space: rigid-body dynamics, reflected rotor inertia, a payload, external
/// torques and stick-slip friction (plant_model.hpp), advanced by one semi-implicit Euler step. The simulation
/// integrates the result with Bullet's btMultiBody; this class holds no Bullet type and is tested on its own.
#pragma once

#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"
#include "bimanual_skills/sim/plant_model.hpp"
#include "bimanual_skills/sim/sim_status.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <memory>
#include <random>
#include <vector>

namespace bimanual_skills::sim {

/// One arm's true plant. Construction may allocate and throw; step() and measure() are
/// real-time safe (no allocation, no exceptions). The object keeps the friction memory (which channels stick, the
/// hysteresis direction), so use one per simulated arm.
///
/// Time stepping (step length Δt, state (q, q̇) at the start of the step, friction impulses λ on the channels
/// u = G q̇ of plant_model.hpp):
///
///   (M(q) + J_m + Δt D) (q̇⁺ − q̇) = Δt (τ + τ_ext − C(q, q̇) q̇ − G(q) − D q̇) + Gᵀ λ,   D = Σ_k b_k g_k g_kᵀ,
///
/// i.e. the viscous terms are implicit, and for every channel k either the channel sticks (g_kᵀ q̇⁺ = 0 with
/// |λ_k| < Δt μ_k) or it slides against its friction (λ_k = −Δt μ_k sign(g_kᵀ q̇⁺)), with μ_k = ρ F_s for a channel
/// that stuck at the previous step and μ_k = ρ [F_c (1 + η σ) + (F_s − F_c) exp(−(u_k / v_s)²)] for a sliding one.
/// This box-constrained problem (a BLCP in the Delassus matrix W = G A⁻¹ Gᵀ, A = M + J_m + Δt D) is solved exactly
/// for the last step's stick/slip pattern (one c × c linear solve) when that pattern is consistent, else by projected
/// Gauss–Seidel to 1e-12 rad/s. M, C, G (with the payload at the tip) come from the project's
/// `dynamics` functions; J_m enters only here, so in free motion (M + J_m) q̈ + h = τ holds exactly.
class ArmPlant {
 public:
  /// `model`: the arm's rigid-body model without rotor inertia (any rotor inertia it carries is ignored), gravity
  /// in its base frame. `parameters` are validated against model.nq().
  /// \throws std::invalid_argument for invalid parameters (naming the entry).
  ArmPlant(kinematics::ChainModel model, ArmPlantParameters parameters);
  ~ArmPlant();
  ArmPlant(ArmPlant&&) noexcept;
  ArmPlant& operator=(ArmPlant&&) noexcept;

  int nq() const noexcept { return model_.nq(); }
  /// The rigid-body model without rotor inertia (what Bullet's btMultiBody simulates).
  const kinematics::ChainModel& model() const noexcept { return model_; }
  const ArmPlantParameters& parameters() const noexcept { return parameters_; }
  /// J_m per joint (zeros when the parameters give none).
  const Eigen::VectorXd& rotorInertia() const noexcept { return rotor_; }
  /// Number of friction channels (one per direct drive, two per differential).
  int channelCount() const noexcept { return static_cast<int>(laws_.size()); }
  /// Row k of G: the joint-velocity weights of channel k.
  Eigen::VectorXd channelDirection(int k) const { return G_.row(k).transpose(); }

  /// The torque the motors deliver for a command: clipped to ±effort limit when parameters().saturate_torque.
  /// Real-time safe: no allocation, no exceptions. Sizes must be nq() (checked by the caller).
  void applyTorqueLimits(const Eigen::Ref<const Eigen::VectorXd>& command,
                         Eigen::Ref<Eigen::VectorXd> applied) const noexcept;

  /// One step of length `dt` from (q, q̇) under the motor torque τ and the external joint torque τ_ext (e.g. Jᵀ F of
  /// external wrenches), with `payload` at the tip: writes q̈ = (q̇⁺ − q̇)/Δt, updates the friction memory, and writes
  /// `rigid_body_torque` = M_rb(q) q̈ + C_rb(q, q̇) q̇ + G_rb(q), the torque under which the rigid-body model() alone
  /// (no rotor inertia, payload or friction; Bullet's btMultiBody) has the same q̈ (from M and h when there is no
  /// payload, else one more RNEA pass). Real-time safe: no allocation, no exceptions. InvalidArgument (friction
  /// memory unchanged) for wrong sizes, non-finite input or dt ≤ 0.
  [[nodiscard]] SimStatus step(const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& qd,
                               const Eigen::Ref<const Eigen::VectorXd>& tau,
                               const Eigen::Ref<const Eigen::VectorXd>& tau_ext, const dynamics::Payload& payload,
                               double dt, Eigen::Ref<Eigen::VectorXd> qdd,
                               Eigen::Ref<Eigen::VectorXd> rigid_body_torque) noexcept;

  /// Friction torque F_f of the last step in the thesis' convention (M q̈ + h + F_f = τ + τ_ext, without the rotor
  /// term): Δt-averaged Coulomb impulses plus the viscous torque at q̇⁺ [N m].
  const Eigen::VectorXd& frictionTorque() const noexcept { return friction_torque_; }
  /// Whether channel k stuck during the last step.
  bool channelSticks(int k) const noexcept { return stuck_[static_cast<std::size_t>(k)] != 0; }
  /// Projected Gauss–Seidel sweeps of the last step (0: the active-set solve was consistent).
  int lastIterations() const noexcept { return iterations_; }

  /// Forgets the friction memory: channels whose velocity G q̇ is zero stick, the others slide.
  /// Real-time safe: no allocation, no exceptions.
  void resetFriction(const Eigen::Ref<const Eigen::VectorXd>& qd) noexcept;

  /// The sensors: encoder q_m = Δ round(q / Δ) (Δ = 0: exact) and velocity q̇_m = q̇ + σ ε, ε ~ N(0, 1) drawn from
  /// `rng` joint by joint (only for σ > 0). Real-time safe: no allocation, no exceptions.
  void measure(const Eigen::Ref<const Eigen::VectorXd>& q, const Eigen::Ref<const Eigen::VectorXd>& qd,
               std::mt19937& rng, Eigen::Ref<Eigen::VectorXd> q_measured,
               Eigen::Ref<Eigen::VectorXd> qd_measured) noexcept;
  /// Drops the normal distribution's cached draw (call when the generator is replaced).
  void resetNoise() noexcept { normal_.reset(); }

 private:
  /// A friction channel: g = e_a (kb = 0) or e_a + kb e_b.
  struct Channel {
    int a = 0;
    int b = 0;
    double kb = 0.0;
  };
  /// gᵀ x for channel k.
  double channelValue(int k, const Eigen::Ref<const Eigen::VectorXd>& x) const noexcept {
    const Channel& ch = channels_[static_cast<std::size_t>(k)];
    return ch.kb == 0.0 ? x[ch.a] : x[ch.a] + ch.kb * x[ch.b];
  }
  /// Row k of the impulse problem: friction channel k, or a joint-limit row (after the channels).
  Channel rowChannel(int k) const noexcept {
    const int c = channelCount();
    return k < c
               ? channels_[static_cast<std::size_t>(k)]
               : Channel{row_joint_[static_cast<std::size_t>(k - c)], row_joint_[static_cast<std::size_t>(k - c)], 0.0};
  }
  double slidingLevel(int k, double position, double velocity) const noexcept;
  double ripple(int k, double position, double direction) const noexcept;

  kinematics::ChainModel model_;
  ArmPlantParameters parameters_;
  Eigen::VectorXd rotor_, resolution_, noise_;
  std::vector<FrictionLaw> laws_;  ///< One per channel.
  std::vector<Channel> channels_;
  Eigen::MatrixXd G_;  ///< Channel directions (channels × nq).
  Eigen::MatrixXd D_;  ///< Σ b_k g_k g_kᵀ.

  dynamics::DynamicsData data_;
  Eigen::MatrixXd mass_;                 ///< M(q) with the payload, no rotors.
  Eigen::MatrixXd A_, inverse_, Y_, W_;  ///< A = M + J_m + Δt D; A⁻¹; Y = A⁻¹ Gᵀ; W = G Y.
  Eigen::LLT<Eigen::MatrixXd> llt_;
  Eigen::VectorXd mass_times_qdd_, bias_, rhs_, v_free_, qd_next_, friction_torque_, zeros_;
  Eigen::VectorXd u_free_, lambda_, lo_, hi_, target_;  ///< Per row (channels, then limit rows).
  Eigen::VectorXd u_previous_, sigma_, position_;       ///< Per channel.
  Eigen::VectorXd lower_, upper_;                       ///< Joint limits.
  std::vector<int> row_joint_;                          ///< Joint of each limit row.
  Eigen::MatrixXd active_;  ///< Active-set system: rows of W for sticking channels, identity rows for sliding ones.
  Eigen::VectorXd active_rhs_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_;
  std::vector<char> stuck_;
  int iterations_ = 0;
  std::normal_distribution<double> normal_;
};

}  // namespace bimanual_skills::sim
