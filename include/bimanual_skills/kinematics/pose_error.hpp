/// \file
/// Task-space error between a current and a target pose, for inverse kinematics.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace bimanual_skills::kinematics {

/// Which part of the pose an IK task constrains.
enum class TaskMode {
  Pose,            ///< 6-D: position and orientation (rows v then ω).
  Position,        ///< 3-D: position only.
  PlanarPosition,  ///< 2-D: x and y of the position (planar arms, as the thesis' 4R examples).
};

/// Number of task rows of a mode (6, 3 or 2).
constexpr int taskDimension(TaskMode mode) noexcept {
  return mode == TaskMode::Pose ? 6 : mode == TaskMode::Position ? 3 : 2;
}

/// Error twist e = [p_d − p; θ u] in the base frame, θ u the rotation vector of R_d Rᵀ (the twist that KDL::diff
/// gives); the first taskDimension(mode) entries of `e` are written. Real-time safe: no allocation, no exceptions.
void poseError(const Eigen::Isometry3d& current, const Eigen::Isometry3d& target, TaskMode mode,
               Eigen::Ref<Eigen::VectorXd> e) noexcept;

}  // namespace bimanual_skills::kinematics
