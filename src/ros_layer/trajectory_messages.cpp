#include "bimanual_skills/ros_layer/trajectory_messages.hpp"

#include "bimanual_skills/FollowJointTrajectoryResult.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace bimanual_skills::ros_layer {

namespace {

using Result = bimanual_skills::FollowJointTrajectoryResult;

bool finite(const std::vector<double>& values) {
  return std::all_of(values.begin(), values.end(), [](double v) { return std::isfinite(v); });
}

}  // namespace

TrajectoryError toWaypoints(const trajectory_msgs::JointTrajectory& message, const std::vector<std::string>& joints,
                            const ros::Time& now, int capacity, control::Waypoints& out, ros::Time& start) {
  const std::size_t n = joints.size();
  const std::size_t points = message.points.size();
  out = control::Waypoints{};
  std::vector<int> column(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    const auto it = std::find(message.joint_names.begin(), message.joint_names.end(), joints[i]);
    if (it != message.joint_names.end()) column[i] = static_cast<int>(it - message.joint_names.begin());
  }
  if (message.joint_names.size() != n || std::find(column.begin(), column.end(), -1) != column.end()) {
    std::string expected;
    for (const std::string& j : joints) expected += (expected.empty() ? "" : ", ") + j;
    return {Result::INVALID_JOINTS, "the trajectory must name each of the arm's " + std::to_string(n) +
                                        " joints once (" + expected + "); it names " +
                                        std::to_string(message.joint_names.size())};
  }
  if (points == 0) return {};
  if (points > static_cast<std::size_t>(capacity)) {
    return {Result::INVALID_GOAL, std::to_string(points) + " points exceed the controller's capacity of " +
                                      std::to_string(capacity) + " (trajectory_capacity)"};
  }
  const bool with_velocities = !message.points.front().velocities.empty();
  const bool with_accelerations = !message.points.front().accelerations.empty();
  start = message.header.stamp.isZero() ? now : message.header.stamp;
  double previous = -1.0;
  std::size_t first = points;  // the first point after now
  for (std::size_t p = 0; p < points; ++p) {
    const auto& point = message.points[p];
    if (point.positions.size() != n || point.velocities.size() != (with_velocities ? n : 0) ||
        point.accelerations.size() != (with_accelerations ? n : 0)) {
      return {Result::INVALID_GOAL,
              "point " + std::to_string(p) + " has the wrong number of positions, velocities or accelerations"};
    }
    if (!finite(point.positions) || !finite(point.velocities) || !finite(point.accelerations)) {
      return {Result::INVALID_GOAL, "point " + std::to_string(p) + " contains NaN or Inf"};
    }
    const double t = point.time_from_start.toSec();
    if (p > 0 && !(t > previous)) {
      return {Result::INVALID_GOAL, "time_from_start must increase strictly (point " + std::to_string(p) + ")"};
    }
    previous = t;
    if (first == points && start.toSec() + t > now.toSec()) first = p;
  }
  if (first == points) {
    std::ostringstream s;
    s << "every point lies in the past: the last at " << start.toSec() + message.points.back().time_from_start.toSec()
      << " s, now " << now.toSec() << " s";
    return {Result::OLD_HEADER_TIMESTAMP, s.str()};
  }
  // Past points (a negative time_from_start among them) are dropped. A point still ahead before its start (a start
  // stamped in the future) cannot be reached from where the arm will be then (joint_trajectory_controller refuses
  // it too); one at the start is the start's own, dropped by the loop when it begins (the arm goes on from its
  // desired state there).
  if (message.points[first].time_from_start.toSec() < 0.0) {
    std::ostringstream s;
    s << "point " << first << " lies ahead at time_from_start " << message.points[first].time_from_start.toSec()
      << " s, before its start stamped " << start.toSec() - now.toSec() << " s from now (give it a time >= 0)";
    return {Result::INVALID_GOAL, s.str()};
  }
  const int k = static_cast<int>(points - first);
  out.times.resize(k);
  out.positions.resize(static_cast<Eigen::Index>(n), k);
  if (with_velocities) out.velocities.resize(static_cast<Eigen::Index>(n), k);
  if (with_accelerations) out.accelerations.resize(static_cast<Eigen::Index>(n), k);
  for (int c = 0; c < k; ++c) {
    const auto& point = message.points[first + static_cast<std::size_t>(c)];
    out.times[c] = point.time_from_start.toSec();
    for (std::size_t i = 0; i < n; ++i) {
      const auto j = static_cast<std::size_t>(column[i]);
      const auto r = static_cast<Eigen::Index>(i);
      out.positions(r, c) = point.positions[j];
      if (with_velocities) out.velocities(r, c) = point.velocities[j];
      if (with_accelerations) out.accelerations(r, c) = point.accelerations[j];
    }
  }
  return {};
}

TrajectoryError resolveTolerances(const std::vector<bimanual_skills::JointTolerance>& path,
                                  const std::vector<bimanual_skills::JointTolerance>& goal,
                                  const ros::Duration& goal_time, const std::vector<std::string>& joints,
                                  const control::TrajectoryTolerances& defaults, control::TrajectoryTolerances& out) {
  out = defaults;
  const auto apply = [&joints](const std::vector<bimanual_skills::JointTolerance>& list, Eigen::VectorXd& position,
                               Eigen::VectorXd& velocity, const char* which) -> TrajectoryError {
    for (const auto& t : list) {
      // A joint of another controller (a goal for a whole group): ignored, as joint_trajectory_controller does.
      const auto it = std::find(joints.begin(), joints.end(), t.name);
      if (it == joints.end()) continue;
      const auto i = static_cast<Eigen::Index>(it - joints.begin());
      for (const auto& [value, target] : {std::pair<double, Eigen::VectorXd*>{t.position, &position},
                                          std::pair<double, Eigen::VectorXd*>{t.velocity, &velocity}}) {
        if (std::isnan(value)) {
          return {Result::INVALID_GOAL, std::string(which) + " tolerance of '" + t.name +
                                            "' is NaN (> 0: the tolerance, 0: the default, < 0: unchecked)"};
        }
        if (value != 0.0) (*target)[i] = value > 0.0 ? value : 0.0;
      }
    }
    return {};
  };
  if (TrajectoryError e = apply(path, out.path_position, out.path_velocity, "path")) return e;
  if (TrajectoryError e = apply(goal, out.goal_position, out.goal_velocity, "goal")) return e;
  const double g = goal_time.toSec();
  if (g != 0.0) out.goal_time = std::max(0.0, g);  // < 0: no time after the end (joint_trajectory_controller's 0)
  return {};
}

trajectory_msgs::JointTrajectoryPoint trajectoryPoint(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                                      const Eigen::VectorXd& qdd, double t) {
  trajectory_msgs::JointTrajectoryPoint p;
  p.positions.assign(q.data(), q.data() + q.size());
  p.velocities.assign(qd.data(), qd.data() + qd.size());
  p.accelerations.assign(qdd.data(), qdd.data() + qdd.size());
  p.time_from_start = ros::Duration(t);
  return p;
}

std::vector<bimanual_skills::JointTolerance> pathTolerances(const std::vector<std::string>& joints, double position) {
  std::vector<bimanual_skills::JointTolerance> tolerances(joints.size());
  for (std::size_t j = 0; j < joints.size(); ++j) {
    tolerances[j].name = joints[j];
    tolerances[j].position = position;
  }
  return tolerances;
}

}  // namespace bimanual_skills::ros_layer
