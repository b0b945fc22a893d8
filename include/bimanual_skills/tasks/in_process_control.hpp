/// \file
/// The control step of the in-process tasks: the robot path's ArmController (the computed-torque law with friction
/// compensation, thesis eq. 4.17, the disturbance observer of Sec. 4.1, torque saturation, the velocity monitor and
/// the stop rules) on every simulated arm, so that a policy meets the same controller in-process as through ROS,
/// where `ctc_controller` runs it. The task plans its references first and loads them as one trajectory.
#pragma once

#include <string>

#include <Eigen/Core>

#include "bimanual_skills/control/arm_controller.hpp"
#include "bimanual_skills/control/joint_trajectory.hpp"

namespace bimanual_skills::tasks {

/// The ArmController of an in-process task's arm: `gains` (torque limits empty: the model's effort limits), the
/// observer as `ctc_controller` defaults it (diagonal gains 10, 0, 100, 0, σ 10) at the simulation's rate 1/dt,
/// `velocity_limit` (one entry: every joint; empty: the model's velocity limits, `ctc_controller`'s default), room
/// for `capacity` waypoints. \throws std::invalid_argument for a non-positive dt or capacity, a velocity limit of
/// the wrong size or not positive.
control::ArmControllerConfig inProcessControllerConfig(const kinematics::ChainModel& model,
                                                       const control::ComputedTorqueGains& gains,
                                                       bool friction_compensation, double dt,
                                                       const Eigen::VectorXd& velocity_limit, int capacity);

/// Planned references as trajectory waypoints for a controller that started (in hold) at period 0 and is loaded
/// before period 1's update: column j of `position`, `velocity`, `acceleration` is the reference of period
/// `first` + j, at time (first + j − 1)·dt after period 1. Columns of periods before 2 are left out (the
/// controller holds its start there). \throws std::invalid_argument for sizes that differ or no column left.
control::Waypoints plannedWaypoints(const Eigen::MatrixXd& position, const Eigen::MatrixXd& velocity,
                                    const Eigen::MatrixXd& acceleration, int first, double dt);

/// Why the controller of `arm` stopped a rollout (VelocityLimit: the fastest joint against its limit; InvalidState
/// and StaleState by name); "" for Ok and Saturated.
std::string controllerStopReason(control::ControllerStatus status, int arm, const Eigen::VectorXd& qd,
                                 const Eigen::VectorXd& velocity_limit);

}  // namespace bimanual_skills::tasks
