#include "bimanual_skills/tasks/in_process_control.hpp"

#include <stdexcept>

namespace bimanual_skills::tasks {

control::ArmControllerConfig inProcessControllerConfig(const kinematics::ChainModel& model,
                                                       const control::ComputedTorqueGains& gains,
                                                       bool friction_compensation, double dt,
                                                       const Eigen::VectorXd& velocity_limit, int capacity) {
  if (!(dt > 0.0) || capacity < 2) {
    throw std::invalid_argument("in-process control: the step must be > 0 and the capacity at least 2 waypoints");
  }
  const int n = model.nq();
  control::ArmControllerConfig c;
  c.gains = gains;
  c.friction_compensation = friction_compensation;
  c.observer = control::ObserverGains::diagonal(n, 10.0, 0.0, 100.0, 0.0, 10.0);
  c.observer.rate_hz = 1.0 / dt;
  if (velocity_limit.size() == 0) {
    c.velocity_limit = model.velocityLimits();
  } else if (velocity_limit.size() == 1) {
    c.velocity_limit = Eigen::VectorXd::Constant(n, velocity_limit[0]);
  } else if (velocity_limit.size() == n) {
    c.velocity_limit = velocity_limit;
  } else {
    throw std::invalid_argument("in-process control: a velocity limit of one or " + std::to_string(n) +
                                " entries, got " + std::to_string(velocity_limit.size()));
  }
  if (!(c.velocity_limit.array() > 0.0).all() || !c.velocity_limit.allFinite()) {
    throw std::invalid_argument("in-process control: velocity limits must be finite and > 0");
  }
  c.trajectory_capacity = capacity;
  return c;
}

control::Waypoints plannedWaypoints(const Eigen::MatrixXd& position, const Eigen::MatrixXd& velocity,
                                    const Eigen::MatrixXd& acceleration, int first, double dt) {
  if (velocity.rows() != position.rows() || acceleration.rows() != position.rows() ||
      velocity.cols() != position.cols() || acceleration.cols() != position.cols()) {
    throw std::invalid_argument("planned waypoints: positions, velocities and accelerations of different sizes");
  }
  const Eigen::Index skip = std::max<Eigen::Index>(0, 2 - first);
  const Eigen::Index k = position.cols() - skip;
  if (k <= 0) throw std::invalid_argument("planned waypoints: no period after the controller's start");
  control::Waypoints w;
  w.times.resize(k);
  for (Eigen::Index j = 0; j < k; ++j) w.times[j] = static_cast<double>(first + skip + j - 1) * dt;
  w.positions = position.rightCols(k);
  w.velocities = velocity.rightCols(k);
  w.accelerations = acceleration.rightCols(k);
  return w;
}

std::string controllerStopReason(control::ControllerStatus status, int arm, const Eigen::VectorXd& qd,
                                 const Eigen::VectorXd& velocity_limit) {
  const std::string who = "arm " + std::to_string(arm) + "'s controller";
  switch (status) {
    case control::ControllerStatus::Ok:
    case control::ControllerStatus::Saturated:
      return {};
    case control::ControllerStatus::VelocityLimit: {
      const std::string text = control::velocityLimitText(qd, velocity_limit);
      return who + " stopped the arm: " + (text.empty() ? "a joint moved faster than its velocity limit" : text);
    }
    case control::ControllerStatus::InvalidState:
      return who + " refused the measured state (InvalidState)";
    case control::ControllerStatus::StaleState:
      return who + " found the measured state stale (StaleState)";
  }
  return who + " failed";
}

}  // namespace bimanual_skills::tasks
