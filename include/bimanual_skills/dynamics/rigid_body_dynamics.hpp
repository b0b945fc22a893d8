/// \file
/// Rigid-body dynamics of a serial chain (thesis Sec. 2.3, eq. 4.1: M(q) q̈ + C(q, q̇) q̇ + G(q) = τ): recursive
/// Newton–Euler inverse dynamics, mass matrix, Coriolis/centripetal and gravity vectors, forward dynamics.
#pragma once

#include "bimanual_skills/dynamics/dynamics_status.hpp"
#include "bimanual_skills/kinematics/chain_model.hpp"

#include <Eigen/Cholesky>

#include <vector>

namespace bimanual_skills::dynamics {

using kinematics::ChainModel;

/// Point mass carried by the tip (a grasped object), switchable at run time.
struct Payload {
  double mass = 0.0;                              ///< [kg], 0 = none.
  Eigen::Vector3d com = Eigen::Vector3d::Zero();  ///< Centre of mass in the tip frame [m].
};

/// Scratch buffers of the dynamics functions, sized once from a model.
struct DynamicsData {
  explicit DynamicsData(const ChainModel& model);

  Eigen::MatrixXd mass_matrix;  ///< M(q), written by massMatrix() and forwardDynamics().
  Eigen::VectorXd bias;         ///< C(q, q̇) q̇ + G(q), written by forwardDynamics().

  // Internal: per-joint frames and Newton–Euler quantities (in each joint's own frame).
  std::vector<Eigen::Matrix3d> rotation;     ///< F_{i−1} → F_i
  std::vector<Eigen::Vector3d> translation;  ///< origin of F_i in F_{i−1}
  std::vector<Eigen::Vector3d> omega, alpha, accel;
  // Internal: composite bodies of the CRBA (in each joint's own frame).
  std::vector<double> composite_mass;
  std::vector<Eigen::Vector3d> composite_moment;   ///< h = m c
  std::vector<Eigen::Matrix3d> composite_inertia;  ///< about the frame's origin
  Eigen::VectorXd zeros;
  Eigen::LLT<Eigen::MatrixXd> llt;
};

/// Inverse dynamics τ = M(q) q̈ + C(q, q̇) q̇ + G(q) (+ J_m q̈ with rotor inertias, + the payload's load) by the
/// recursive Newton–Euler algorithm. Real-time safe: no allocation, no exceptions.
[[nodiscard]] DynamicsStatus inverseDynamics(const ChainModel& model, DynamicsData& data,
                                             const Eigen::Ref<const Eigen::VectorXd>& q,
                                             const Eigen::Ref<const Eigen::VectorXd>& qd,
                                             const Eigen::Ref<const Eigen::VectorXd>& qdd,
                                             Eigen::Ref<Eigen::VectorXd> tau, const Payload& payload = {}) noexcept;

/// Joint-space mass matrix M(q) (symmetric positive definite; rotor inertias on the diagonal) into
/// data.mass_matrix by the composite-rigid-body algorithm (Featherstone, Rigid Body Dynamics Algorithms, Sec. 6.2):
/// the composite inertia of the bodies beyond each joint (mass m, first moment h = m c and rotational inertia I_o
/// about the joint frame's origin, accumulated from the tip inwards), the spatial force F_i = I^c_i S_i of unit
/// motion of joint i, M_ii = S_iᵀ F_i (+ the rotor inertia), and M_ji = S_jᵀ F_i with F_i carried to each joint
/// j < i. Equals the RNEA columns of q̈ = e_j without velocity and gravity. Real-time safe: no allocation, no
/// exceptions.
[[nodiscard]] DynamicsStatus massMatrix(const ChainModel& model, DynamicsData& data,
                                        const Eigen::Ref<const Eigen::VectorXd>& q,
                                        const Payload& payload = {}) noexcept;

/// Coriolis and centripetal torques C(q, q̇) q̇. Real-time safe: no allocation, no exceptions.
[[nodiscard]] DynamicsStatus coriolisTorques(const ChainModel& model, DynamicsData& data,
                                             const Eigen::Ref<const Eigen::VectorXd>& q,
                                             const Eigen::Ref<const Eigen::VectorXd>& qd, Eigen::Ref<Eigen::VectorXd> c,
                                             const Payload& payload = {}) noexcept;

/// Gravity torques G(q) for model.gravity(). Real-time safe: no allocation, no exceptions.
[[nodiscard]] DynamicsStatus gravityTorques(const ChainModel& model, DynamicsData& data,
                                            const Eigen::Ref<const Eigen::VectorXd>& q, Eigen::Ref<Eigen::VectorXd> g,
                                            const Payload& payload = {}) noexcept;

/// Forward dynamics q̈ = M(q)⁻¹ (τ − C(q, q̇) q̇ − G(q)) by a Cholesky factorisation held in data.
/// Real-time safe: no allocation, no exceptions.
[[nodiscard]] DynamicsStatus forwardDynamics(const ChainModel& model, DynamicsData& data,
                                             const Eigen::Ref<const Eigen::VectorXd>& q,
                                             const Eigen::Ref<const Eigen::VectorXd>& qd,
                                             const Eigen::Ref<const Eigen::VectorXd>& tau,
                                             Eigen::Ref<Eigen::VectorXd> qdd, const Payload& payload = {}) noexcept;

}  // namespace bimanual_skills::dynamics
