#include "bimanual_skills/control/arm_controller.hpp"

#include "bimanual_skills/signal/acceleration_sign.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace bimanual_skills::control {

namespace {

constexpr const char* kModeNames[] = {"gravity_compensation", "hold", "track"};
/// |q̈_d| below this counts as no acceleration for the friction models' sign(q̈) [rad/s²].
constexpr double kAccelerationDeadBand = 1e-3;

}  // namespace

const char* toString(ControllerMode mode) noexcept {
  return kModeNames[static_cast<int>(mode)];
}

bool modeFromString(const char* name, ControllerMode& mode) noexcept {
  for (int i = 0; i < 3; ++i) {
    if (std::strcmp(name, kModeNames[i]) == 0) {
      mode = static_cast<ControllerMode>(i);
      return true;
    }
  }
  return false;
}

const char* toString(ControllerStatus status) noexcept {
  switch (status) {
    case ControllerStatus::Ok:
      return "Ok";
    case ControllerStatus::Saturated:
      return "Saturated";
    case ControllerStatus::InvalidState:
      return "InvalidState";
    case ControllerStatus::StaleState:
      return "StaleState";
    case ControllerStatus::VelocityLimit:
      return "VelocityLimit";
  }
  return "Unknown";
}

std::string velocityLimitText(const Eigen::VectorXd& qd, const Eigen::VectorXd& velocity_limit) {
  if (qd.size() == 0 || qd.size() != velocity_limit.size()) return {};
  Eigen::Index joint = 0;
  (qd.cwiseAbs().array() / velocity_limit.array()).maxCoeff(&joint);
  return "joint " + std::to_string(joint + 1) + " moved at " + std::to_string(qd[joint]) +
         " rad/s, over its velocity limit " + std::to_string(velocity_limit[joint]) + " rad/s";
}

ArmController::ArmController(const kinematics::ChainModel& model, const dynamics::FrictionModel& friction,
                             ArmControllerConfig config)
    : ctc_(model, friction, config.gains),
      observer_(model, friction, config.observer),
      trajectory_(model.nq(), config.trajectory_capacity, model.lowerLimits(), model.upperLimits()),
      dynamics_(model),
      velocity_limit_(config.velocity_limit.size() == 0 ? model.velocityLimits() : config.velocity_limit),
      torque_limit_(config.gains.torque_limit.size() == 0 ? model.effortLimits() : config.gains.torque_limit),
      timeout_(config.state_timeout),
      stop_deceleration_(config.stop_deceleration),
      min_stop_time_(config.min_stop_time) {
  const int n = model.nq();
  if (velocity_limit_.size() != n || (velocity_limit_.array() <= 0.0).any()) {
    throw std::invalid_argument("ArmController: velocity_limit needs " + std::to_string(n) + " positive entries");
  }
  if (!(timeout_ > 0.0)) throw std::invalid_argument("ArmController: state_timeout must be > 0");
  if (!(stop_deceleration_ > 0.0) || !std::isfinite(stop_deceleration_) || !(min_stop_time_ > 0.0) ||
      !std::isfinite(min_stop_time_)) {
    throw std::invalid_argument("ArmController: stop_deceleration and min_stop_time must be finite and > 0");
  }
  ctc_.setFrictionCompensation(config.friction_compensation);
  q_d_ = qd_d_ = qdd_d_ = error_ = applied_ = accel_sign_ = q_valid_ = start_q_ = start_qd_ = start_qdd_ =
      Eigen::VectorXd::Zero(n);
}

void ArmController::holdAt(double t, const Eigen::Ref<const Eigen::VectorXd>& q) noexcept {
  trajectory_.hold(t, q);
  mode_ = ControllerMode::Hold;
}

void ArmController::stopAt(double t) noexcept {
  const double duration = std::max(min_stop_time_, 2.0 * qd_d_.cwiseAbs().maxCoeff() / stop_deceleration_);
  trajectory_.stop(t, q_d_, qd_d_, qdd_d_, duration);
  mode_ = ControllerMode::Hold;
}

bool ArmController::holdingTorque(Eigen::Ref<Eigen::VectorXd> torque) noexcept {
  if (torque.size() != q_valid_.size()) return false;
  if (!started_ ||
      dynamics::gravityTorques(ctc_.model(), dynamics_, q_valid_, torque) != dynamics::DynamicsStatus::Success) {
    torque.setZero();
    return false;
  }
  torque = torque.cwiseMax(-torque_limit_).cwiseMin(torque_limit_);
  return true;
}

bool ArmController::stale(double now) noexcept {
  if (started_ && now - last_stamp_ > timeout_) was_stale_ = true;
  return was_stale_;
}

void ArmController::setMode(ControllerMode mode) noexcept {
  requested_mode_ = mode;
  mode_request_ = true;
}

TrajectoryStatus ArmController::setTrajectory(const Waypoints& waypoints) noexcept {
  const TrajectoryStatus status = trajectory_.load(waypoints);
  if (status == TrajectoryStatus::Ok) {
    trajectory_request_ = true;
    start_given_ = false;
  }
  return status;
}

TrajectoryStatus ArmController::setTrajectory(const Waypoints& waypoints, double offset) noexcept {
  const TrajectoryStatus status = trajectory_.load(waypoints, offset);
  if (status == TrajectoryStatus::Ok) {
    trajectory_request_ = true;
    start_given_ = false;
  }
  return status;
}

TrajectoryStatus ArmController::setTrajectoryFrom(const Waypoints& waypoints,
                                                  const Eigen::Ref<const Eigen::VectorXd>& q,
                                                  const Eigen::Ref<const Eigen::VectorXd>& qd,
                                                  const Eigen::Ref<const Eigen::VectorXd>& qdd) noexcept {
  if (q.size() != start_q_.size() || qd.size() != start_qd_.size() || qdd.size() != start_qdd_.size()) {
    return TrajectoryStatus::WrongSize;
  }
  if (!q.allFinite() || !qd.allFinite() || !qdd.allFinite()) return TrajectoryStatus::NotFinite;
  const TrajectoryStatus status = trajectory_.load(waypoints);
  if (status == TrajectoryStatus::Ok) {
    trajectory_request_ = true;
    start_given_ = true;
    start_q_ = q;
    start_qd_ = qd;
    start_qdd_ = qdd;
  }
  return status;
}

ControllerStatus ArmController::update(double now, double stamp, const Eigen::Ref<const Eigen::VectorXd>& q,
                                       const Eigen::Ref<const Eigen::VectorXd>& qd,
                                       Eigen::Ref<Eigen::VectorXd> torque) noexcept {
  return update(now, stamp, q, qd, applied_, torque);
}

ControllerStatus ArmController::update(double now, double stamp, const Eigen::Ref<const Eigen::VectorXd>& q,
                                       const Eigen::Ref<const Eigen::VectorXd>& qd,
                                       const Eigen::Ref<const Eigen::VectorXd>& applied,
                                       Eigen::Ref<Eigen::VectorXd> torque) noexcept {
  const Eigen::Index n = q_d_.size();
  if (q.size() != n || qd.size() != n || torque.size() != n || !q.allFinite() || !qd.allFinite() ||
      !std::isfinite(now) || !std::isfinite(stamp)) {
    return ControllerStatus::InvalidState;
  }
  // Time went backwards (a simulation was reset): the clock of `now` and the stamp both went back; start afresh at
  // this state. A stamp earlier than the last one while the clock did not go back is a delayed message: stale.
  if (started_ && stamp < last_stamp_ && now < last_stamp_) {
    started_ = false;
    was_stale_ = false;
  } else if (now - stamp > timeout_ || (started_ && stamp < last_stamp_)) {
    was_stale_ = started_;
    return ControllerStatus::StaleState;
  }
  last_period_ = started_ && !was_stale_ ? stamp - last_stamp_ : 0.0;
  last_stamp_ = stamp;
  q_valid_ = q;
  if (!started_ || was_stale_) {
    observer_.reset(q, qd);  // a start, or states again after a gap: the estimate restarts here
    started_ = true;
    was_stale_ = false;
    trajectory_request_ = false;
    mode_request_ = false;
    holdAt(stamp, q);
    q_d_ = q;
    qd_d_.setZero();
    qdd_d_.setZero();
  }
  // A stop or a new trajectory starts where the reference is at this stamp: the desired state of the last update is
  // one period old, and starting from it would set the reference back by one period's motion. A stop samples the
  // running trajectory; a new trajectory has already replaced its waypoints on loading, so the last desired state is
  // carried over the period instead (to second order).
  if (mode_ != ControllerMode::GravityCompensation && last_period_ > 0.0) {
    if (trajectory_request_) {
      q_d_ += last_period_ * qd_d_ + (0.5 * last_period_ * last_period_) * qdd_d_;
      qd_d_ += last_period_ * qdd_d_;
    } else if (mode_request_) {
      trajectory_.sample(stamp, q_d_, qd_d_, qdd_d_);
    }
  }
  if (mode_request_) {
    mode_request_ = false;
    if (requested_mode_ == ControllerMode::Track && trajectory_request_) {
      // The trajectory request below switches to tracking.
    } else if (requested_mode_ == ControllerMode::GravityCompensation) {
      mode_ = ControllerMode::GravityCompensation;
      trajectory_request_ = false;
    } else {
      if (mode_ == ControllerMode::GravityCompensation) {  // from where the arm is, as it moves
        q_d_ = q;
        qd_d_ = qd;
        qdd_d_.setZero();
      }
      stopAt(stamp);
    }
  }
  if (trajectory_request_) {
    trajectory_request_ = false;
    if (start_given_) {
      start_given_ = false;
      q_d_ = start_q_;
      qd_d_ = start_qd_;
      qdd_d_ = start_qdd_;
    } else if (mode_ == ControllerMode::GravityCompensation) {
      q_d_ = q;
      qd_d_ = qd;
      qdd_d_.setZero();
    }
    if (trajectory_.start(stamp, q_d_, qd_d_, qdd_d_) == TrajectoryStatus::Ok) mode_ = ControllerMode::Track;
  }
  ControllerStatus status = ControllerStatus::Ok;
  if (((qd.array().abs() - velocity_limit_.array()) > 0.0).any()) {
    holdAt(stamp, q);
    status = ControllerStatus::VelocityLimit;
  }
  if (mode_ == ControllerMode::GravityCompensation) {
    q_d_ = q;
    qd_d_ = qd;
    qdd_d_.setZero();
    if (dynamics::gravityTorques(ctc_.model(), dynamics_, q, torque) != dynamics::DynamicsStatus::Success) {
      return ControllerStatus::InvalidState;
    }
    for (Eigen::Index i = 0; i < n; ++i) {
      if (std::abs(torque[i]) > torque_limit_[i]) {
        torque[i] = std::copysign(torque_limit_[i], torque[i]);
        if (status == ControllerStatus::Ok) status = ControllerStatus::Saturated;
      }
    }
  } else {
    trajectory_.sample(stamp, q_d_, qd_d_, qdd_d_);
    const ControlStatus control = ctc_.update(q, qd, q_d_, qd_d_, qdd_d_, torque);
    if (control == ControlStatus::InvalidInput) return ControllerStatus::InvalidState;
    if (control == ControlStatus::Saturated && status == ControllerStatus::Ok) status = ControllerStatus::Saturated;
  }
  error_ = q_d_ - q;
  signal::signWithDeadBand(qdd_d_, kAccelerationDeadBand, accel_sign_);
  // The measured state results from the torque applied over the last period Δt (none at a start: the observer
  // was reset at this state; a repeated stamp: nothing new to integrate).
  if (last_period_ > 0.0) {
    if (applied.size() == n && applied.allFinite()) {
      (void)observer_.update(q, qd, applied, accel_sign_, last_period_);
    } else {
      (void)observer_.update(q, qd, applied_, accel_sign_, last_period_);
    }
  }
  applied_ = torque;
  return status;
}

}  // namespace bimanual_skills::control
