#include "bimanual_skills/kinematics/chain_kinematics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace bimanual_skills::kinematics {
namespace {

/// Singular values of data.jacobian.
const Eigen::VectorXd& jacobianSingularValues(ChainData& data) noexcept {
  static_cast<void>(data.svd.compute(data.jacobian));  // the shape is the data's own; a NaN Jacobian keeps the last
  return data.svd.singularValues();
}

KinematicsStatus checkConfiguration(const ChainModel& model, const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  if (q.size() != model.nq()) return KinematicsStatus::WrongSize;
  if (!q.allFinite()) return KinematicsStatus::NotFinite;
  return KinematicsStatus::Success;
}

}  // namespace

const char* toString(KinematicsStatus status) noexcept {
  switch (status) {
    case KinematicsStatus::Success:
      return "success";
    case KinematicsStatus::WrongSize:
      return "joint vector has the wrong size";
    case KinematicsStatus::NotFinite:
      return "joint vector contains NaN or Inf";
  }
  return "unknown status";
}

ChainData::ChainData(const ChainModel& model)
    : frame_poses(static_cast<std::size_t>(model.nq()) + 1, Eigen::Isometry3d::Identity()),
      jacobian(Matrix6Xd::Zero(6, model.nq())),
      axis_frames(static_cast<std::size_t>(model.nq()), Eigen::Isometry3d::Identity()),
      svd(6, model.nq(), false) {}

KinematicsStatus forwardKinematics(const ChainModel& model, ChainData& data,
                                   const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  if (const KinematicsStatus status = checkConfiguration(model, q); status != KinematicsStatus::Success) {
    return status;
  }
  const auto& steps = model.axisFrames();
  const int n = model.nq();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) {
    const ChainModel::AxisFrame& step = steps[static_cast<std::size_t>(i)];
    p.noalias() += R * step.translation;
    Eigen::Matrix3d R_joint;
    R_joint.noalias() = R * step.rotation;
    if (step.prismatic) {
      p.noalias() += q[i] * R_joint.col(2);
      R = R_joint;
    } else {
      ChainModel::turnAboutZ(R_joint, q[i], R);
    }
    Eigen::Isometry3d& F = data.axis_frames[static_cast<std::size_t>(i)];
    F.linear() = R;
    F.translation() = p;
    Eigen::Isometry3d& L = data.frame_poses[static_cast<std::size_t>(i)];
    L.translation() = p;
    if (step.axis_is_z) {
      L.linear() = R;
    } else {
      L.linear().noalias() = R * step.to_link;
    }
  }
  const Eigen::Isometry3d& tip = model.tipInLastFrame();
  Eigen::Isometry3d& T = data.frame_poses.back();
  T.translation() = p;
  T.translation().noalias() += R * tip.translation();
  T.linear().noalias() = R * tip.linear();
  return KinematicsStatus::Success;
}

KinematicsStatus frameJacobian(const ChainModel& model, const ChainData& data, int frame_index, JacobianFrame frame,
                               Eigen::Ref<Matrix6Xd> J) noexcept {
  const int n = model.nq();
  if (frame_index < 0 || frame_index > n || J.cols() != n) {
    return KinematicsStatus::WrongSize;
  }
  const Eigen::Isometry3d& target = data.frame_poses[static_cast<std::size_t>(frame_index)];
  const Eigen::Vector3d& p_target = target.translation();
  // Joints up to and including the frame's own joint move it (all joints for the tip, index n).
  const int moving = frame_index < n ? frame_index + 1 : n;
  const auto& steps = model.axisFrames();
  for (int i = 0; i < moving; ++i) {
    const Eigen::Isometry3d& F = data.axis_frames[static_cast<std::size_t>(i)];
    const auto z = F.linear().col(2);
    if (steps[static_cast<std::size_t>(i)].prismatic) {
      J.col(i).head<3>() = z;
      J.col(i).tail<3>().setZero();
    } else {
      J.col(i).head<3>() = z.cross(p_target - F.translation());
      J.col(i).tail<3>() = z;
    }
  }
  J.rightCols(n - moving).setZero();
  if (frame == JacobianFrame::Tip) {
    const Eigen::Matrix3d Rt = target.linear().transpose();
    for (int i = 0; i < moving; ++i) {
      const Eigen::Vector3d v = Rt * J.col(i).head<3>();
      const Eigen::Vector3d w = Rt * J.col(i).tail<3>();
      J.col(i) << v, w;
    }
  }
  return KinematicsStatus::Success;
}

KinematicsStatus computeJacobian(const ChainModel& model, ChainData& data, const Eigen::Ref<const Eigen::VectorXd>& q,
                                 JacobianFrame frame) noexcept {
  if (const KinematicsStatus status = forwardKinematics(model, data, q); status != KinematicsStatus::Success) {
    return status;
  }
  return frameJacobian(model, data, model.nq(), frame, data.jacobian);
}

double manipulability(ChainData& data) noexcept {
  return jacobianSingularValues(data).prod();
}

double conditionNumber(ChainData& data) noexcept {
  const Eigen::VectorXd& sigma = jacobianSingularValues(data);
  const double smallest = sigma.minCoeff();
  return smallest > 0.0 ? sigma.maxCoeff() / smallest : std::numeric_limits<double>::infinity();
}

}  // namespace bimanual_skills::kinematics
