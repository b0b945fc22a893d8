/// \file
/// The ROS side of a hosting::ControlLoop, as any robot's driver needs it: an arm's controller with its ROS
/// interface hosted in the loop (hostArmController), and the loop on /diagnostics (LoopDiagnostics: its level and
/// message, periods, real-time factor, allocations per cycle, outside commands rejected or late, lockstep timeouts).
#pragma once

#include "bimanual_skills/hosting/control_loop.hpp"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/ros_layer/arm_controller_interface.hpp"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/sim/robot_file.hpp"

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <ros/ros.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace bimanual_skills::ros_layer {

/// The controller defaults the robot file gives arm `arm` (its chain, gains and friction model); none without a
/// file. \throws std::invalid_argument when the file has no such arm.
inline ControllerDefaults controllerDefaults(const sim::RobotFile* robot, const std::string& arm) {
  if (!robot) return {};
  const sim::RobotArm* a = robot->arm(arm);
  if (!a) throw std::invalid_argument("the robot file " + robot->path + " has no arm '" + arm + "'");
  return {a->base_link, a->tip_link, a->friction_file, robot->kp, robot->kv};
}

/// Arm `arm` (index `index` of the loop's robot, joints `joints`) driven in `loop` by a computed-torque controller
/// whose parameters are ARM/ctc_controller/* and whose topics, action and services are ARM/...
/// (ArmControllerInterface); its goals are aborted with the reason when the loop stops. `owner` prefixes the log lines.
/// Warns when the observer's rate differs from the loop's by more than 20 %. \throws std::invalid_argument for a bad
/// parameter or a controller of other joints.
inline std::unique_ptr<ArmControllerInterface> hostArmController(hosting::ControlLoop& loop, int index,
                                                                 ros::NodeHandle& node, const std::string& arm,
                                                                 const std::vector<std::string>& joints,
                                                                 const std::string& description,
                                                                 const std::string& owner,
                                                                 const ControllerDefaults& defaults = {}) {
  ros::NodeHandle arm_node(node, arm);
  ParameterReader parameters(ros::NodeHandle(arm_node, "ctc_controller"), owner + ": " + arm + " controller");
  auto controller = std::make_unique<ArmControllerInterface>(arm_node, parameters, arm, description,
                                                             owner + ": " + arm + " controller", defaults);
  parameters.warnUnknown();
  if (controller->jointNames() != joints) {
    throw std::invalid_argument("the controller of '" + arm +
                                "' does not drive the robot arm's joints (check base_link and tip_link)");
  }
  const double rate = controller->settings().config.observer.rate_hz, period = loop.settings().period;
  if (std::abs(rate * period - 1.0) > 0.2) {
    ROS_WARN(
        "%s: %s: the observer's rate (%.0f Hz, %s) differs from the loop's (%.0f Hz); it integrates the measured "
        "step, but its FIR cut-off was designed for %.0f Hz",
        owner.c_str(), arm.c_str(), rate,
        ros::NodeHandle(arm_node, "ctc_controller").resolveName("observer/rate").c_str(), 1.0 / period, rate);
  }
  ArmControllerInterface* interface = controller.get();
  loop.host(index, controller->realtime(), [interface](const std::string& why) { interface->loopStopped(why); });
  return controller;
}

/// Builds a loop's diagnostic status, keeping what it needs to measure the real-time factor between two calls.
class LoopDiagnostics {
 public:
  /// The status named `name`: ERROR with the robot's reason when the loop stopped, else OK saying how it runs.
  diagnostic_msgs::DiagnosticStatus status(const hosting::ControlLoop& loop, const std::string& name) {
    diagnostic_msgs::DiagnosticStatus status;
    status.name = status.hardware_id = name;
    const double now = realtime::monotonicSeconds(), t = loop.time();
    const double factor = last_wall_ > 0.0 ? (t - last_time_) / (now - last_wall_) : 0.0;
    last_wall_ = now;
    last_time_ = t;
    if (loop.stopped()) {
      status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
      status.message = std::string("stopped at t = ") + std::to_string(loop.stopTime()) + " s: " + loop.stopReason();
    } else {
      status.level = diagnostic_msgs::DiagnosticStatus::OK;
      status.message = std::string(loop.paused()              ? "paused"
                                   : loop.settings().lockstep ? "lockstep"
                                                              : "free-running") +
                       ", t = " + std::to_string(t) + " s";
    }
    std::vector<double> periods;
    loop.periods(periods);
    const std::size_t recent = std::min<std::size_t>(periods.size(), 1000);
    std::vector<double> last(periods.end() - static_cast<std::ptrdiff_t>(recent), periods.end());
    const realtime::PeriodSummary summary = realtime::summarize(last);
    const hosting::LoopCounts counts = loop.counts();
    add(status, "simulated_time_s", std::to_string(t));
    add(status, "realtime_factor_target", std::to_string(loop.settings().realtime_factor));
    add(status, "realtime_factor_last_second", std::to_string(factor));
    add(status, "loop_period_median_s", std::to_string(summary.median));
    add(status, "loop_period_p99_s", std::to_string(summary.p99));
    add(status, "loop_period_max_s", std::to_string(summary.max));
    add(status, "loop_schedule_restarts", std::to_string(counts.schedule_restarts));
    add(status, "cycles", std::to_string(counts.cycles));
    add(status, "control_allocations", std::to_string(counts.control_allocations));
    add(status, "control_cycles_that_allocated", std::to_string(counts.control_cycles_that_allocated));
    add(status, "physics_steps_that_allocated", std::to_string(counts.robot_steps_that_allocated));
    add(status, "rejected_external_commands", std::to_string(counts.rejected_commands));
    add(status, "late_external_commands", std::to_string(counts.late_commands));
    add(status, "lockstep_timeouts", std::to_string(counts.lockstep_timeouts));
    add(status, "faulted_states", std::to_string(counts.faulted_states));
    add(status, "unusable_states", std::to_string(counts.unusable_states));
    // Since the last status: arms held because their states could not be used.
    const long unread = counts.faulted_states - last_faulted_, unusable = counts.unusable_states - last_unusable_;
    last_faulted_ = counts.faulted_states;
    last_unusable_ = counts.unusable_states;
    if (status.level == diagnostic_msgs::DiagnosticStatus::OK && unread + unusable > 0) {
      status.level = diagnostic_msgs::DiagnosticStatus::WARN;
      status.message +=
          "; arms held on states that could not be used since the last status: " + std::to_string(unread) +
          " unread, " + std::to_string(unusable) + " stale or not finite";
    }
    return status;
  }

  static void add(diagnostic_msgs::DiagnosticStatus& status, const std::string& key, const std::string& value) {
    diagnostic_msgs::KeyValue kv;
    kv.key = key;
    kv.value = value;
    status.values.push_back(kv);
  }

 private:
  double last_wall_ = 0.0, last_time_ = 0.0;
  long last_faulted_ = 0, last_unusable_ = 0;
};

}  // namespace bimanual_skills::ros_layer
