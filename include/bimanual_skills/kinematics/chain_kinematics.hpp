/// \file
/// Forward kinematics, geometric Jacobian, manipulability and condition number of a serial chain.
#pragma once

#include "bimanual_skills/kinematics/chain_model.hpp"
#include "bimanual_skills/kinematics/thin_svd.hpp"

#include <vector>

namespace bimanual_skills::kinematics {

/// Outcome of a real-time kinematics call. Bad input is reported here, never by a crash.
enum class KinematicsStatus { Success, WrongSize, NotFinite };

/// Human-readable name of a status, for logs outside the real-time path.
const char* toString(KinematicsStatus status) noexcept;

/// Frame in which a Jacobian is expressed. The reference point is always the origin of the frame the Jacobian is
/// computed for (the tip by default), so J q̇ is the twist [v; ω] of that frame.
enum class JacobianFrame {
  Base,  ///< Expressed in the chain's base frame (KDL's ChainJntToJacSolver convention).
  Tip,   ///< Expressed in the frame itself (the "body" Jacobian).
};

using Matrix6Xd = Eigen::Matrix<double, 6, Eigen::Dynamic>;

/// Scratch and output buffers of the kinematics functions, sized once from a model.
struct ChainData {
  explicit ChainData(const ChainModel& model);

  /// Pose in the base frame of every frame in model.frameNames(): link of joint 1..n, then the tip.
  std::vector<Eigen::Isometry3d> frame_poses;
  /// Geometric Jacobian of the tip (6 x n, rows v then ω), written by computeJacobian().
  Matrix6Xd jacobian;

  /// Internal joint frames F_i in the base frame (see ChainModel); frame_poses is derived from them.
  std::vector<Eigen::Isometry3d> axis_frames;
  /// Singular values of the Jacobian (ThinSvd: allocation-free for the wide Jacobians of redundant arms).
  ThinSvd svd;

  const Eigen::Isometry3d& tipPose() const noexcept { return frame_poses.back(); }
};

/// Forward kinematics of every frame: data.frame_poses[i] = ^base T_i(q), a product of the joint origins and
/// rotations R(axis_i, q_i) (or translations for prismatic joints) from base to tip.
/// Real-time safe: no allocation, no exceptions.
[[nodiscard]] KinematicsStatus forwardKinematics(const ChainModel& model, ChainData& data,
                                                 const Eigen::Ref<const Eigen::VectorXd>& q) noexcept;

/// Forward kinematics, then the tip's geometric Jacobian into data.jacobian. Column i is
/// [z_i × (p_tip − p_i); z_i] for a revolute joint and [z_i; 0] for a prismatic one, z_i the joint axis and p_i the
/// joint frame origin in the base frame; for JacobianFrame::Tip both halves are then rotated by R_tip^T.
/// Real-time safe: no allocation, no exceptions.
[[nodiscard]] KinematicsStatus computeJacobian(const ChainModel& model, ChainData& data,
                                               const Eigen::Ref<const Eigen::VectorXd>& q,
                                               JacobianFrame frame = JacobianFrame::Base) noexcept;

/// Jacobian of frame `frame_index` of model.frameNames() (its origin is the reference point) from the poses left in
/// data by the last forwardKinematics(); columns of joints after that frame are zero. J must be 6 x n.
/// Real-time safe: no allocation, no exceptions. Returns WrongSize for a bad index or a J of the wrong size.
[[nodiscard]] KinematicsStatus frameJacobian(const ChainModel& model, const ChainData& data, int frame_index,
                                             JacobianFrame frame, Eigen::Ref<Matrix6Xd> J) noexcept;

/// Yoshikawa manipulability w = sqrt(det(J Jᵀ)) = ∏ σ_i of data.jacobian (product over min(6, n) singular values).
/// Call after computeJacobian(). Real-time safe: no allocation, no exceptions.
double manipulability(ChainData& data) noexcept;

/// Condition number κ = σ_max / σ_min of data.jacobian (infinity at a singularity).
/// Call after computeJacobian(). Real-time safe: no allocation, no exceptions.
double conditionNumber(ChainData& data) noexcept;

}  // namespace bimanual_skills::kinematics
