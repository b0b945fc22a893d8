#include "bimanual_skills/control/target_follower.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace bimanual_skills::control {

namespace {

/// Periods ahead of the update that each reference segment ends (TargetFollower::update).
constexpr double kSegmentPeriods = 5.0;

bool finitePositive(double v, double high) {
  return std::isfinite(v) && v > 0.0 && v <= high;
}

}  // namespace

const char* toString(FollowPhase phase) noexcept {
  switch (phase) {
    case FollowPhase::Idle:
      return "idle";
    case FollowPhase::Following:
      return "following";
    case FollowPhase::Holding:
      return "holding";
    case FollowPhase::Approaching:
      return "approaching";
    case FollowPhase::Closing:
      return "closing";
    case FollowPhase::HoldingObject:
      return "holding the object";
  }
  return "unknown";
}

const char* toString(HoldReason reason) noexcept {
  switch (reason) {
    case HoldReason::None:
      return "none";
    case HoldReason::NoTarget:
      return "the target is not tracked";
    case HoldReason::Stale:
      return "the target's estimate is too old";
    case HoldReason::Jumped:
      return "the target jumped";
    case HoldReason::Invalid:
      return "a non-finite target or joint state";
  }
  return "unknown";
}

void TargetFollowerConfig::validate(int joints) const {
  const auto fail = [](const std::string& what) { throw std::invalid_argument("target follower: " + what); };
  if (!base.matrix().allFinite()) fail("base must be finite");
  if (!tool_orientation.allFinite() ||
      !(tool_orientation.transpose() * tool_orientation).isApprox(Eigen::Matrix3d::Identity(), 1e-6) ||
      tool_orientation.determinant() < 0.0) {
    fail("tool_orientation must be a rotation");
  }
  if (!grasp_offset.allFinite() || grasp_offset.norm() > 1.0) fail("grasp_offset must be finite, at most 1 m");
  if (!pregrasp.allFinite() || pregrasp.norm() > 1.0) fail("pregrasp must be finite, at most 1 m");
  if (!finitePositive(period, 1.0)) fail("period must lie in (0, 1] s");
  if (!finitePositive(time_constant, 10.0)) fail("time_constant must lie in (0, 10] s");
  for (const Eigen::VectorXd* v : {&velocity_limit, &acceleration_limit}) {
    if (v->size() != 0 && joints > 0 && v->size() != joints)
      fail("velocity and acceleration limits need one per joint");
    for (Eigen::Index i = 0; i < v->size(); ++i) {
      if (!finitePositive((*v)[i], 1e4)) fail("velocity and acceleration limits must be finite and > 0");
    }
  }
  if (!(limit_margin >= 0.0 && limit_margin <= 1.0)) fail("limit_margin must lie in [0, 1] rad");
  if (!finitePositive(max_age, 60.0)) fail("max_age must lie in (0, 60] s");
  if (!finitePositive(jump, 10.0)) fail("jump must lie in (0, 10] m");
  if (!(settle >= 0.0 && settle <= 60.0)) fail("settle must lie in [0, 60] s");
  if (!(track_time >= 0.0 && track_time <= 3600.0)) fail("track_time must lie in [0, 3600] s");
  if (!finitePositive(grasp_speed, 10.0)) fail("grasp_speed must lie in (0, 10] m/s");
  if (!finitePositive(follow_tolerance, 1.0)) fail("follow_tolerance must lie in (0, 1] m");
  if (!finitePositive(approach_speed, 10.0)) fail("approach_speed must lie in (0, 10] m/s");
  if (!finitePositive(speed_time_constant, 10.0) || !finitePositive(position_time_constant, 10.0)) {
    fail("speed_time_constant and position_time_constant must lie in (0, 10] s");
  }
  if (!finitePositive(grasp_tolerance, 1.0)) fail("grasp_tolerance must lie in (0, 1] m");
  if (clik_iterations < 1 || clik_iterations > 100) fail("clik_iterations must lie in [1, 100]");
  clik.validate();
}

TargetFollower::TargetFollower(const kinematics::ChainModel& model, const TargetFollowerConfig& config)
    : model_(model),
      config_((config.validate(model.nq()), config)),
      clik_(model, config.clik),
      fk_(model),
      orientation_(config.tool_orientation) {
  const int n = model.nq();
  for (Eigen::VectorXd* v :
       {&q_r_, &v_r_, &q_goal_, &q_goal_previous_, &v_goal_, &v_wanted_, &v_segment_, &a_r_, &a_segment_})
    v->setZero(n);
  const Eigen::VectorXd margin = Eigen::VectorXd::Constant(n, config_.limit_margin);
  lower_ = model.lowerLimits() + margin;
  upper_ = model.upperLimits() - margin;
  for (int j = 0; j < n; ++j) {
    if (lower_[j] > upper_[j]) lower_[j] = upper_[j] = 0.5 * (model.lowerLimits()[j] + model.upperLimits()[j]);
  }
  v_max_ = config_.velocity_limit.size() == n ? config_.velocity_limit : 0.5 * model.velocityLimits();
  for (int j = 0; j < n; ++j) {
    if (!std::isfinite(v_max_[j])) v_max_[j] = 1.0;
  }
  a_max_ = config_.acceleration_limit.size() == n ? config_.acceleration_limit : Eigen::VectorXd::Constant(n, 4.0);
  waypoints_.times.setZero(1);
  waypoints_.positions.setZero(n, 1);
  waypoints_.velocities.setZero(n, 1);
  waypoints_.accelerations.setZero(n, 1);
}

void TargetFollower::start(double t, const Eigen::Ref<const Eigen::VectorXd>& q,
                           const Eigen::Ref<const Eigen::VectorXd>& qd, bool grasp) noexcept {
  if (q.size() != q_r_.size() || qd.size() != v_r_.size() || !q.allFinite() || !qd.allFinite()) return;
  t_ = t;
  grasp_ = grasp;
  q_r_ = q.cwiseMax(lower_).cwiseMin(upper_);
  v_r_ = qd;
  q_goal_ = q_r_;
  orientation_ = config_.tool_orientation;
  if (config_.keep_yaw && kinematics::forwardKinematics(model_, fk_, q_r_) == kinematics::KinematicsStatus::Success) {
    // Turned about the vertical so that the axis (x or y) more level in both points, seen from above, as the tool's
    // does now.
    const Eigen::Matrix3d now = config_.base.linear() * fk_.tipPose().linear();
    const auto level = [&](int k) {
      return std::min(now.col(k).head<2>().norm(), orientation_.col(k).head<2>().norm());
    };
    const int k = level(0) >= level(1) ? 0 : 1;
    if (level(k) > 1e-3) {
      const double yaw = std::atan2(now(1, k), now(0, k)) - std::atan2(orientation_(1, k), orientation_(0, k));
      orientation_ = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() * orientation_;
    }
  }
  goal_valid_ = false;
  offset_ = 1.0;
  followed_since_ = t;
  jumped_at_ = -1e300;
  last_stamp_ = used_stamp_ = filtered_stamp_ = std::numeric_limits<double>::quiet_NaN();
  grasp_answered_ = false;
  phase_ = FollowPhase::Holding;
  reason_ = HoldReason::NoTarget;
}

void TargetFollower::hold(HoldReason reason) noexcept {
  if (phase_ != FollowPhase::Holding) goal_valid_ = false;  // no feed-forward from a goal before the hold
  phase_ = FollowPhase::Holding;
  reason_ = reason;
}

bool TargetFollower::solve(const Eigen::Vector3d& position) noexcept {
  Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
  target.linear() = orientation_;
  target.translation() = position;
  const Eigen::Isometry3d in_base = config_.base.inverse(Eigen::Isometry) * target;
  for (int k = 0; k < config_.clik_iterations; ++k) {
    if (kinematics::step(model_, config_.clik, clik_, q_goal_, in_base) != kinematics::IkStatus::StepComputed) {
      return false;
    }
    q_goal_ += clik_.dq;
  }
  q_goal_ = q_goal_.cwiseMax(lower_).cwiseMin(upper_);
  return q_goal_.allFinite();
}

bool TargetFollower::update(double t, const FollowTarget& target,
                            const Eigen::Ref<const Eigen::VectorXd>& q_measured) noexcept {
  if (phase_ == FollowPhase::Idle || q_measured.size() != q_r_.size()) return false;
  const double dt = std::clamp(t - t_, 0.0, 4.0 * config_.period);
  t_ = t;
  const bool measured = q_measured.allFinite() &&
                        kinematics::forwardKinematics(model_, fk_, q_measured) == kinematics::KinematicsStatus::Success;
  if (measured) tool_ = config_.base * fk_.tipPose().translation();

  // The estimate: valid, fresh, and where the last one said it would be.
  const bool finite = std::isfinite(target.stamp) && target.position.allFinite() && target.velocity.allFinite();
  HoldReason why = HoldReason::None;
  if (!measured || (target.tracking && !finite)) {
    why = HoldReason::Invalid;
  } else if (!target.tracking) {
    why = HoldReason::NoTarget;
    // A target found again is not a jump from the lost one, nor filtered with it.
    last_stamp_ = filtered_stamp_ = std::numeric_limits<double>::quiet_NaN();
  } else {
    if (target.stamp != last_stamp_) {
      if (std::isfinite(last_stamp_)) {
        const Eigen::Vector3d predicted = last_position_ + last_velocity_ * (target.stamp - last_stamp_);
        if ((target.position - predicted).norm() > config_.jump) {
          jumped_at_ = t;
          filtered_stamp_ = std::numeric_limits<double>::quiet_NaN();  // the new place is filtered afresh
        }
      }
      last_stamp_ = target.stamp;
      last_position_ = target.position;
      last_velocity_ = target.velocity;
      // The filters take each measured estimate once (a prediction of a hidden object is left out).
      if (!std::isfinite(target.measured) || target.measured >= target.stamp) {
        if (!std::isfinite(filtered_stamp_)) {
          filtered_position_ = target.position;
          filtered_velocity_ = target.velocity;
        } else {
          const double h = std::max(0.0, target.stamp - filtered_stamp_);
          filtered_velocity_ +=
              (1.0 - std::exp(-h / config_.speed_time_constant)) * (target.velocity - filtered_velocity_);
          filtered_position_ +=
              (1.0 - std::exp(-h / config_.position_time_constant)) * (target.position - filtered_position_);
        }
        filtered_stamp_ = target.stamp;
      }
    }
    if (t - target.stamp > config_.max_age) {
      why = HoldReason::Stale;
    } else if (t - jumped_at_ < config_.settle) {
      why = HoldReason::Jumped;
    }
  }

  if (phase_ == FollowPhase::HoldingObject) {
    v_wanted_.setZero();
  } else if (why != HoldReason::None && phase_ != FollowPhase::Closing) {
    hold(why);
    v_wanted_.setZero();
  } else if (why != HoldReason::None) {  // closing: wait for the gripper where the tool is
    v_wanted_.setZero();
  } else {
    if (phase_ == FollowPhase::Holding) {
      phase_ = FollowPhase::Following;
      reason_ = HoldReason::None;
      followed_since_ = t;
    }
    used_stamp_ = target.stamp;
    const double age = std::max(0.0, t - target.stamp);
    const bool filtered = std::isfinite(filtered_stamp_);
    const double speed = filtered ? filtered_velocity_.norm() : target.velocity.norm();
    if (grasp_ && phase_ == FollowPhase::Following && t - followed_since_ >= config_.track_time &&
        speed < config_.grasp_speed && tool_error_ < config_.follow_tolerance) {
      phase_ = FollowPhase::Approaching;  // from wherever the offset stands: slow spells add up
    } else if (phase_ == FollowPhase::Approaching && speed > 2.0 * config_.grasp_speed) {
      phase_ = FollowPhase::Following;  // too fast again: back towards the pre-grasp point, still tracked
    }
    const double length = config_.pregrasp.norm();
    const double share = length > 0.0 ? config_.approach_speed * dt / length : 1.0;
    const bool closer = phase_ == FollowPhase::Approaching || phase_ == FollowPhase::Closing;
    offset_ = std::clamp(offset_ + (closer ? -share : share), 0.0, 1.0);
    // Following, the object's estimate predicted to now; on the approach and the grasp (a slow object), where it was
    // measured, filtered: neither its noise nor the prediction of an object the hand hides moves the tool.
    const Eigen::Vector3d grasp_point =
        (closer && filtered ? filtered_position_ : Eigen::Vector3d(target.position + target.velocity * age)) +
        config_.grasp_offset;
    goal_ = grasp_point + offset_ * config_.pregrasp;
    q_goal_previous_ = q_goal_;
    if (!solve(goal_)) {
      q_goal_ = q_goal_previous_;
      hold(HoldReason::Invalid);
      v_wanted_.setZero();
    } else {
      // Feed-forward: the goal's rate of change, smoothed (the CLIK iterates converge over updates too).
      if (goal_valid_ && dt > 0.0) {
        v_goal_ = 0.7 * v_goal_ + 0.3 * (q_goal_ - q_goal_previous_) / dt;
      } else {
        v_goal_.setZero();
      }
      goal_valid_ = true;
      v_wanted_ = v_goal_ + (q_goal_ - q_r_) / config_.time_constant;
      tool_error_ = measured ? (tool_ - goal_).norm() : tool_error_;
      if (phase_ == FollowPhase::Approaching && offset_ <= 0.0 && tool_error_ < config_.grasp_tolerance) {
        phase_ = FollowPhase::Closing;
        grasp_answered_ = false;
      }
    }
  }

  // The reference: towards the wanted velocity within the acceleration limit, the velocity limit, and a speed from
  // which it can stop before the position limits; positions kept inside them.
  for (Eigen::Index j = 0; j < q_r_.size(); ++j) {
    double wanted = std::clamp(v_wanted_[j], -v_max_[j], v_max_[j]);
    const double room = wanted > 0.0 ? upper_[j] - q_r_[j] : q_r_[j] - lower_[j];
    const double stoppable = std::sqrt(2.0 * a_max_[j] * std::max(0.0, room));
    wanted = std::clamp(wanted, -stoppable, stoppable);
    const double step = a_max_[j] * dt;
    const double change = std::clamp(wanted - v_r_[j], -step, step);
    a_r_[j] = dt > 0.0 ? change / dt : 0.0;
    v_r_[j] += change;
    q_r_[j] += v_r_[j] * dt;
    if (q_r_[j] > upper_[j] || q_r_[j] < lower_[j]) {
      q_r_[j] = std::clamp(q_r_[j], lower_[j], upper_[j]);
      v_r_[j] = a_r_[j] = 0.0;
    }
  }
  // The segment reaches the reference extrapolated kSegmentPeriods periods ahead: states that come late or after a
  // robot's stall (stamps 20-30 ms apart) still sample the segment, not its end held still, whose stop and restart
  // would be acceleration spikes.
  const double h = kSegmentPeriods * config_.period;
  waypoints_.times[0] = h;
  // The reference's own motion, at its last acceleration (within a_max), from its state: the controller starts the
  // segment there (ArmController::setTrajectoryFrom), so q̈_d is the reference's and nothing else. Where a position
  // limit cuts the extrapolation, the joint goes to it at a constant velocity instead.
  for (Eigen::Index j = 0; j < q_r_.size(); ++j) {
    const double end = q_r_[j] + (v_r_[j] + 0.5 * a_r_[j] * h) * h;
    if (end >= lower_[j] && end <= upper_[j]) {
      v_segment_[j] = v_r_[j];
      a_segment_[j] = a_r_[j];
      waypoints_.positions(j, 0) = end;
    } else {
      waypoints_.positions(j, 0) = std::clamp(end, lower_[j], upper_[j]);
      v_segment_[j] = (waypoints_.positions(j, 0) - q_r_[j]) / h;
      a_segment_[j] = 0.0;
    }
    waypoints_.velocities(j, 0) = v_segment_[j] + a_segment_[j] * h;
    waypoints_.accelerations(j, 0) = a_segment_[j];
  }
  return true;
}

void TargetFollower::graspDone(bool held) noexcept {
  if (phase_ != FollowPhase::Closing) return;
  grasp_answered_ = true;
  if (held) {
    phase_ = FollowPhase::HoldingObject;
    return;
  }
  phase_ = FollowPhase::Following;  // back off to the pre-grasp point and try again after track_time
  followed_since_ = t_;
}

}  // namespace bimanual_skills::control
