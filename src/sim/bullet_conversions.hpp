/// \file
/// Internal: conversions between Eigen and Bullet (double precision: btScalar is double).
#pragma once

#include <LinearMath/btTransform.h>
#include <Eigen/Geometry>

namespace bimanual_skills::sim {

static_assert(sizeof(btScalar) == sizeof(double), "bimanual_skills_sim needs Bullet's double-precision build");

inline btVector3 toBullet(const Eigen::Ref<const Eigen::Vector3d>& v) {
  return btVector3(v.x(), v.y(), v.z());
}

inline Eigen::Vector3d toEigen(const btVector3& v) {
  return Eigen::Vector3d(v.x(), v.y(), v.z());
}

inline btMatrix3x3 toBulletBasis(const Eigen::Matrix3d& m) {
  return btMatrix3x3(m(0, 0), m(0, 1), m(0, 2), m(1, 0), m(1, 1), m(1, 2), m(2, 0), m(2, 1), m(2, 2));
}

inline Eigen::Matrix3d toEigen(const btMatrix3x3& m) {
  Eigen::Matrix3d out;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out(r, c) = m[r][c];
  }
  return out;
}

inline btTransform toBulletTransform(const Eigen::Isometry3d& pose) {
  return btTransform(toBulletBasis(pose.linear()), toBullet(Eigen::Vector3d(pose.translation())));
}

inline Eigen::Isometry3d toEigen(const btTransform& transform) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = toEigen(transform.getBasis());
  pose.translation() = toEigen(transform.getOrigin());
  return pose;
}

/// Quaternion of a rotation matrix.
inline btQuaternion toBulletQuaternion(const Eigen::Matrix3d& rotation) {
  const Eigen::Quaterniond q(rotation);
  return btQuaternion(q.x(), q.y(), q.z(), q.w());
}

}  // namespace bimanual_skills::sim
