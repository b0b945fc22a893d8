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

BodyInertia BodyInertia::combined(const BodyInertia& other) const {
  BodyInertia out;
  out.mass = mass + other.mass;
  if (out.mass <= 0.0) return out;
  out.com = (mass * com + other.mass * other.com) / out.mass;
  // Parallel-axis theorem: I_c + m (|d|² 1 − d dᵀ) for each body's offset d from the common centre of mass.
  const auto shifted = [&](const BodyInertia& body) -> Eigen::Matrix3d {
    const Eigen::Vector3d d = body.com - out.com;
    return body.inertia + body.mass * (d.squaredNorm() * Eigen::Matrix3d::Identity() - d * d.transpose());
  };
  out.inertia = shifted(*this) + shifted(other);
  return out;
}

BodyInertia BodyInertia::expressedIn(const Eigen::Isometry3d& pose) const {
  BodyInertia out;
  out.mass = mass;
  out.com = pose.inverse() * com;
  out.inertia = pose.linear().transpose() * inertia * pose.linear();
  return out;
}

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
  rotor_.resize(static_cast<Eigen::Index>(n));
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
    if (!std::isfinite(joint.body.mass) || joint.body.mass < 0.0 || !joint.body.com.allFinite() ||
        !joint.body.inertia.allFinite() || !std::isfinite(joint.rotor_inertia) || joint.rotor_inertia < 0.0) {
      throw std::invalid_argument(what + "mass, centre of mass, inertia and rotor inertia must be finite, mass >= 0");
    }
    const auto k = static_cast<Eigen::Index>(i);
    lower_[k] = joint.lower;
    upper_[k] = joint.upper;
    velocity_[k] = joint.velocity;
    effort_[k] = joint.effort;
    rotor_[k] = joint.rotor_inertia;

    // F_i = F_{i-1} (R_{i-1}^T O_i R_i) R(z, q_i): see the class comment.
    AxisFrame& frame = axis_frames_[i];
    const Eigen::Matrix3d alignment = rotationFromZ(joint.axis);
    frame.axis_is_z = joint.axis == Eigen::Vector3d::UnitZ();
    const Eigen::Matrix3d R_i = frame.axis_is_z ? Eigen::Matrix3d::Identity() : alignment;
    frame.rotation = previous_alignment.transpose() * joint.origin.linear() * R_i;
    frame.translation = previous_alignment.transpose() * joint.origin.translation();
    frame.to_link = R_i.transpose();
    frame.prismatic = joint.type == JointType::Prismatic;
    // F_i = L_i R_i: a body given in L_i is expressed in F_i through the pose of F_i in L_i, a pure rotation R_i.
    Eigen::Isometry3d axis_in_link = Eigen::Isometry3d::Identity();
    axis_in_link.linear() = R_i;
    frame.body = joint.body.expressedIn(axis_in_link);
    const Eigen::Vector3d& c = frame.body.com;
    frame.first_moment = frame.body.mass * c;
    frame.origin_inertia =
        frame.body.inertia + frame.body.mass * (c.squaredNorm() * Eigen::Matrix3d::Identity() - c * c.transpose());
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

ChainModel ChainModel::withGravity(const Eigen::Vector3d& gravity) const {
  if (!gravity.allFinite()) throw std::invalid_argument("ChainModel::withGravity: gravity must be finite");
  ChainModel copy = *this;
  copy.gravity_ = gravity;
  return copy;
}

ChainModel ChainModel::withRotorInertia(const Eigen::VectorXd& rotor_inertia) const {
  if (rotor_inertia.size() != nq() || !rotor_inertia.allFinite() || (rotor_inertia.array() < 0.0).any()) {
    throw std::invalid_argument("ChainModel::withRotorInertia: need " + std::to_string(nq()) + " finite values >= 0");
  }
  ChainModel copy = *this;
  copy.rotor_ = rotor_inertia;
  for (int i = 0; i < nq(); ++i) copy.joints_[static_cast<std::size_t>(i)].rotor_inertia = rotor_inertia[i];
  return copy;
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

Eigen::VectorXd randomWithinLimits(const ChainModel& model, std::mt19937& rng) {
  Eigen::VectorXd q(model.nq());
  for (int i = 0; i < model.nq(); ++i) {
    const double lo = std::isfinite(model.lowerLimits()[i]) ? model.lowerLimits()[i] : -M_PI;
    const double hi = std::isfinite(model.upperLimits()[i]) ? model.upperLimits()[i] : M_PI;
    q[i] = std::uniform_real_distribution<double>(lo, hi)(rng);
  }
  return q;
}

Eigen::VectorXd middleOfLimits(const ChainModel& model) {
  Eigen::VectorXd q(model.nq());
  for (int i = 0; i < model.nq(); ++i) {
    const double lo = std::isfinite(model.lowerLimits()[i]) ? model.lowerLimits()[i] : -M_PI;
    const double hi = std::isfinite(model.upperLimits()[i]) ? model.upperLimits()[i] : M_PI;
    q[i] = 0.5 * (lo + hi);
  }
  return q;
}

}  // namespace bimanual_skills::kinematics
