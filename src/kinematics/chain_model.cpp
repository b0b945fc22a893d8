#include "bimanual_skills/kinematics/chain_model.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <stdexcept>
#include <utility>

namespace bimanual_skills::kinematics {
namespace {

bool isFinite(const Eigen::Isometry3d& pose) {
  return pose.matrix().allFinite();
}

/// A rotation taking the z axis onto the unit vector `axis` (identity when axis is +z).
Eigen::Matrix3d rotationFromZ(const Eigen::Vector3d& axis) {
  return Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), axis).toRotationMatrix();
}

}  // namespace

ChainModel::ChainModel(std::string base_link, std::string tip_link, std::vector<ChainJoint> joints,
                       const Eigen::Isometry3d& tip_offset)
    : base_link_(std::move(base_link)), tip_link_(std::move(tip_link)), joints_(std::move(joints)) {
  const std::string where = "chain '" + base_link_ + "' -> '" + tip_link_ + "': ";
  if (joints_.empty()) {
    throw std::invalid_argument(where + "no movable joint between the two links");
  }
  if (!isFinite(tip_offset)) {
    throw std::invalid_argument(where + "the tip offset is not finite");
  }
  const auto n = joints_.size();
  lower_.resize(static_cast<Eigen::Index>(n));
  upper_.resize(static_cast<Eigen::Index>(n));
  velocity_.resize(static_cast<Eigen::Index>(n));
  effort_.resize(static_cast<Eigen::Index>(n));
  axis_frames_.resize(n);
  Eigen::Matrix3d previous_alignment = Eigen::Matrix3d::Identity();
  for (std::size_t i = 0; i < n; ++i) {
    ChainJoint& joint = joints_[i];
    const std::string what = where + "joint '" + joint.name + "': ";
    const double axis_norm = joint.axis.norm();
    if (!std::isfinite(axis_norm) || axis_norm < 1e-12) {
      throw std::invalid_argument(what + "the joint axis is zero or not finite");
    }
    joint.axis /= axis_norm;
    if (!isFinite(joint.origin)) {
      throw std::invalid_argument(what + "the joint origin is not finite");
    }
    if (std::isnan(joint.lower) || std::isnan(joint.upper) || joint.lower > joint.upper) {
      throw std::invalid_argument(what + "position limits are NaN or lower > upper");
    }
    if (!(joint.velocity > 0.0) || !(joint.effort > 0.0)) {
      throw std::invalid_argument(what + "velocity and effort limits must be positive");
    }
    const auto k = static_cast<Eigen::Index>(i);
    lower_[k] = joint.lower;
    upper_[k] = joint.upper;
    velocity_[k] = joint.velocity;
    effort_[k] = joint.effort;

    // F_i = F_{i-1} (R_{i-1}^T O_i R_i) R(z, q_i): see the class comment.
    AxisFrame& frame = axis_frames_[i];
    const Eigen::Matrix3d alignment = rotationFromZ(joint.axis);
    frame.axis_is_z = joint.axis == Eigen::Vector3d::UnitZ();
    const Eigen::Matrix3d R_i = frame.axis_is_z ? Eigen::Matrix3d::Identity() : alignment;
    frame.rotation = previous_alignment.transpose() * joint.origin.linear() * R_i;
    frame.translation = previous_alignment.transpose() * joint.origin.translation();
    frame.to_link = R_i.transpose();
    frame.prismatic = joint.type == JointType::Prismatic;
    previous_alignment = R_i;
    frame_names_.push_back(joint.child_link);
  }
  frame_names_.push_back(tip_link_);
  for (std::size_t i = 1; i < n; ++i) reach_bound_ += joints_[i].origin.translation().norm();
  reach_bound_ += tip_offset.translation().norm();
  for (const ChainJoint& joint : joints_) {
    if (joint.type == JointType::Prismatic) reach_bound_ += std::max(std::abs(joint.lower), std::abs(joint.upper));
  }
  tip_in_last_.setIdentity();
  tip_in_last_.linear() = previous_alignment.transpose() * tip_offset.linear();
  tip_in_last_.translation() = previous_alignment.transpose() * tip_offset.translation();
}

std::vector<std::string> ChainModel::jointNames() const {
  std::vector<std::string> names;
  names.reserve(joints_.size());
  for (const auto& joint : joints_) {
    names.push_back(joint.name);
  }
  return names;
}

int ChainModel::frameIndex(const std::string& name) const noexcept {
  for (std::size_t i = 0; i < frame_names_.size(); ++i) {
    if (frame_names_[i] == name) {
      return static_cast<int>(i);
    }
  }
  return -1;
}

bool ChainModel::withinLimits(const Eigen::Ref<const Eigen::VectorXd>& q, double tolerance) const noexcept {
  if (q.size() != nq() || !q.allFinite()) {
    return false;
  }
  return ((q.array() >= lower_.array() - tolerance) && (q.array() <= upper_.array() + tolerance)).all();
}

}  // namespace bimanual_skills::kinematics
