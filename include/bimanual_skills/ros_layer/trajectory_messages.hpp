/// \file
/// From trajectory messages to the controller's waypoints and tolerances, with the semantics of ROS's
/// joint_trajectory_controller and control_msgs' FollowJointTrajectory: joints matched by name, header.stamp as the
/// start (0: now), points in the past dropped, tolerances of 0 keeping the defaults and of -1 removing the check.
/// Errors come back as FollowJointTrajectory result codes with a message.
#pragma once

#include "bimanual_skills/JointTolerance.h"
#include "bimanual_skills/control/realtime_arm_controller.hpp"

#include <ros/time.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <string>
#include <vector>

namespace bimanual_skills::ros_layer {

/// A refused trajectory or goal: a FollowJointTrajectoryResult error code and why.
struct TrajectoryError {
  int code = 0;  ///< 0 (SUCCESSFUL) when there is no error.
  std::string message;
  explicit operator bool() const { return code != 0; }
};

/// A trajectory point at `t` [s from the trajectory's start] with positions, velocities and accelerations.
trajectory_msgs::JointTrajectoryPoint trajectoryPoint(const Eigen::VectorXd& q, const Eigen::VectorXd& qd,
                                                      const Eigen::VectorXd& qdd, double t);

/// A path tolerance of `position` [rad] on each of `joints` (a FollowJointTrajectory goal's path_tolerance).
std::vector<bimanual_skills::JointTolerance> pathTolerances(const std::vector<std::string>& joints, double position);

/// Converts `message` for an arm whose joints are `joints` into waypoints with times relative to `start`, the
/// trajectory's own start: header.stamp, or `now` (the clock of the controller's stamps) when that is zero. The
/// points at or before `now` are dropped (a negative time_from_start is such a point). Refuses (before allocating
/// for the points) a trajectory of more than `capacity` points; names that are not exactly the arm's joints
/// (INVALID_JOINTS); points of the wrong size, NaN/Inf values, times that do not increase strictly, a point ahead
/// at a negative time_from_start (before a future start; INVALID_GOAL); a trajectory whose points all lie at or
/// before `now` (OLD_HEADER_TIMESTAMP). A point at time_from_start 0 of a future start is kept (the loop drops it
/// when it begins). An empty trajectory is not an error: `out` gets no waypoints (the caller
/// holds).
TrajectoryError toWaypoints(const trajectory_msgs::JointTrajectory& message, const std::vector<std::string>& joints,
                            const ros::Time& now, int capacity, control::Waypoints& out, ros::Time& start);

/// The tolerances of a goal as control_msgs and joint_trajectory_controller read them: `defaults` for every joint,
/// replaced where `path` or `goal` name one of `joints` with a value > 0, unchecked where it is < 0 (-1), kept at
/// 0; entries for other joints ignored; the goal time tolerance (0: the default's, < 0: none). INVALID_GOAL for NaN.
TrajectoryError resolveTolerances(const std::vector<bimanual_skills::JointTolerance>& path,
                                  const std::vector<bimanual_skills::JointTolerance>& goal,
                                  const ros::Duration& goal_time, const std::vector<std::string>& joints,
                                  const control::TrajectoryTolerances& defaults, control::TrajectoryTolerances& out);

}  // namespace bimanual_skills::ros_layer
