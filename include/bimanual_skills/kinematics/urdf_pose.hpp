/// \file
/// A URDF pose (urdfdom) as an Eigen transform, for the loaders of URDF files (kinematics' chain loader, the
/// simulator's Bullet arms). Public, so that no module includes another's private header; it needs urdfdom's headers
/// (urdf_model/pose.h), which only the loaders have.
#pragma once

#include <urdf_model/pose.h>

#include <Eigen/Geometry>

namespace bimanual_skills::kinematics {

/// The rigid transform of a URDF pose (its quaternion normalised).
inline Eigen::Isometry3d toIsometry(const urdf::Pose& pose) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.translation() << pose.position.x, pose.position.y, pose.position.z;
  out.linear() = Eigen::Quaterniond(pose.rotation.w, pose.rotation.x, pose.rotation.y, pose.rotation.z)
                     .normalized()
                     .toRotationMatrix();
  return out;
}

}  // namespace bimanual_skills::kinematics
