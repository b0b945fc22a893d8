/// \file
/// The table of the simulated scene: a static box the arms and the cloth collide with.
#pragma once

#include <Eigen/Geometry>

namespace bimanual_skills::sim {

struct Table {
  /// Pose of the box's centre in the world frame (its top face is at +size.z/2 along the pose's z axis).
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  Eigen::Vector3d size = Eigen::Vector3d(0.7, 1.2, 0.3);  ///< Full extents along the pose's axes [m], > 0.
  double friction = 0.5;                                  ///< Bullet friction coefficient of the table surface, ≥ 0.

  /// World position of the centre of the top face.
  Eigen::Vector3d topCentre() const { return pose * Eigen::Vector3d(0.0, 0.0, 0.5 * size.z()); }
  /// Throws std::invalid_argument (naming `where`) for a non-finite pose, non-positive size or negative friction.
  void validate(const char* where) const;
};

}  // namespace bimanual_skills::sim
