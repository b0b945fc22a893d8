#include "bimanual_skills/kinematics/pose_error.hpp"

namespace bimanual_skills::kinematics {

void poseError(const Eigen::Isometry3d& current, const Eigen::Isometry3d& target, TaskMode mode,
               Eigen::Ref<Eigen::VectorXd> e) noexcept {
  if (mode == TaskMode::PlanarPosition) {
    e.head<2>() = (target.translation() - current.translation()).head<2>();
    return;
  }
  e.head<3>() = target.translation() - current.translation();
  if (mode == TaskMode::Pose) {
    const Eigen::AngleAxisd rotation(Eigen::Matrix3d(target.linear() * current.linear().transpose()));
    e.segment<3>(3) = rotation.angle() * rotation.axis();
  }
}

}  // namespace bimanual_skills::kinematics
