// ctc_controller: one arm's computed-torque controller (control::ArmController) as a ROS node. A thin shell: the
// control step is ArmController::update (no allocation, no locks); this file moves messages in and out of it.
#include "bimanual_skills/SetControlMode.h"
#include "bimanual_skills/control/arm_controller.hpp"
#include "bimanual_skills/dynamics/friction_yaml.hpp"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "node_cli.hpp"
#include "scene_markers.hpp"

#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/WrenchStamped.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <std_msgs/Float64MultiArray.h>
#include <trajectory_msgs/JointTrajectory.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <deque>
#include <memory>
#include <string>
#include <vector>

namespace bs = bimanual_skills;
namespace bc = bimanual_skills::control;

namespace {

const char* const kUsage =
    "usage: rosrun bimanual_skills ctc_controller __ns:=ARM [_param:=value ...]\n"
    "\n"
    "Computed-torque controller of one arm (thesis eq. 4.17) with the identified friction model and the\n"
    "disturbance observer (Sec. 4.1) estimating the external wrench at the tool. Runs one control step per\n"
    "/joint_states message.\n"
    "\n"
    "Parameters (private; config/ctc_controller.yaml holds the defaults):\n"
    "  ~arm                 arm name (default: the namespace), ~base_link, ~tip_link (default ARM_wam_base/_tool)\n"
    "  ~kp, ~kv             gains per joint; ~torque_limit, ~velocity_limit (default: the URDF's limits)\n"
    "  ~friction_file       friction model YAML (fit_friction's output); empty: no friction compensation\n"
    "  ~observer/{k11,k12,k21,k22,sigma,rate,fir_taps,fir_cutoff}  observer gains (diagonal) and rate [Hz]\n"
    "  ~state_timeout       joint states older than this [s] are stale: no torque, hold on recovery (0.05)\n"
    "  ~initial_mode        gravity_compensation | hold (default hold)\n"
    "  ~publish_rate        rate of the wrench, tracking-error and diagnostics topics [Hz] (default 100)\n"
    "Reads robot_description. Topics (relative to the namespace): subscribes /joint_states and command\n"
    "(trajectory_msgs/JointTrajectory: all the arm's joints, times from now; an empty trajectory holds);\n"
    "publishes effort_command (std_msgs/Float64MultiArray), estimated_wrench (geometry_msgs/WrenchStamped, base\n"
    "frame), tracking_error (sensor_msgs/JointState: position and velocity errors q_d - q), tool_paths\n"
    "(visualization_msgs/MarkerArray: the last 10 s of actual and commanded tool positions), /diagnostics.\n"
    "Service: set_mode (bimanual_skills/SetControlMode: gravity_compensation | hold | track).\n";

template <typename T>
T param(ros::NodeHandle& node, const std::string& name, const T& fallback) {
  T value;
  return node.getParam(name, value) ? value : fallback;
}

Eigen::VectorXd vectorParam(ros::NodeHandle& node, const std::string& name, int n, const Eigen::VectorXd& fallback) {
  std::vector<double> values;
  if (!node.getParam(name, values)) return fallback;
  if (static_cast<int>(values.size()) != n) {
    throw std::invalid_argument("~" + name + " needs " + std::to_string(n) + " values, got " +
                                std::to_string(values.size()));
  }
  return Eigen::Map<const Eigen::VectorXd>(values.data(), n);
}

class CtcControllerNode {
 public:
  CtcControllerNode(ros::NodeHandle& node, ros::NodeHandle& private_node) {
    std::string ns = node.getNamespace();
    ns = ns.substr(ns.find_last_of('/') + 1);
    arm_ = param<std::string>(private_node, "arm", ns);
    if (arm_.empty()) throw std::invalid_argument("no arm name: run in the arm's namespace (__ns:=left) or set ~arm");
    std::string description, key;
    if (!private_node.searchParam("robot_description", key) || !ros::param::get(key, description)) {
      throw std::invalid_argument("parameter 'robot_description' is not set");
    }
    const std::string base = param<std::string>(private_node, "base_link", arm_ + "_wam_base");
    const std::string tip = param<std::string>(private_node, "tip_link", arm_ + "_wam_tool");
    const auto model = bs::kinematics::ChainModel::fromUrdfString(description, base, tip);
    const int n = model.nq();
    joint_names_ = model.jointNames();

    bc::ArmControllerConfig config;
    config.gains.kp = vectorParam(private_node, "kp", n, Eigen::VectorXd::Constant(n, 50.0));
    config.gains.kv = vectorParam(private_node, "kv", n, Eigen::VectorXd::Constant(n, 5.0));
    config.gains.torque_limit = vectorParam(private_node, "torque_limit", n, model.effortLimits());
    config.velocity_limit = vectorParam(private_node, "velocity_limit", n, model.velocityLimits());
    config.state_timeout = param(private_node, "state_timeout", 0.05);
    const std::string friction_file = param<std::string>(private_node, "friction_file", "");
    bs::dynamics::FrictionModel friction;
    if (friction_file.empty()) {
      friction.joints.assign(n, bs::dynamics::JointFriction{});
      config.friction_compensation = false;
    } else {
      friction = bs::dynamics::loadFrictionModel(friction_file);
    }
    config.observer = bc::ObserverGains::diagonal(
        n, param(private_node, "observer/k11", 10.0), param(private_node, "observer/k12", 0.0),
        param(private_node, "observer/k21", 100.0), param(private_node, "observer/k22", 0.0),
        param(private_node, "observer/sigma", 10.0));
    config.observer.rate_hz = param(private_node, "observer/rate", 1000.0);
    config.observer.fir_taps = param(private_node, "observer/fir_taps", 15);
    config.observer.fir_cutoff_hz = param(private_node, "observer/fir_cutoff", 40.0);
    controller_ = std::make_unique<bc::ArmController>(model, friction, config);
    kinematics_ = std::make_unique<bs::kinematics::ChainData>(model);
    base_frame_ = base;
    q_ = qd_ = torque_ = Eigen::VectorXd::Zero(n);
    command_.data.assign(n, 0.0);
    error_message_.name = joint_names_;
    error_message_.position.assign(n, 0.0);
    error_message_.velocity.assign(n, 0.0);

    const std::string initial = param<std::string>(private_node, "initial_mode", "hold");
    bc::ControllerMode mode;
    if (!bc::modeFromString(initial.c_str(), mode) || mode == bc::ControllerMode::Track) {
      throw std::invalid_argument("~initial_mode must be gravity_compensation or hold, got '" + initial + "'");
    }
    controller_->setMode(mode);
    publish_period_ = 1.0 / std::max(1e-3, param(private_node, "publish_rate", 100.0));

    effort_publisher_ = node.advertise<std_msgs::Float64MultiArray>("effort_command", 10);
    wrench_publisher_ = node.advertise<geometry_msgs::WrenchStamped>("estimated_wrench", 10);
    error_publisher_ = node.advertise<sensor_msgs::JointState>("tracking_error", 10);
    path_publisher_ = node.advertise<visualization_msgs::MarkerArray>("tool_paths", 1);
    diagnostics_publisher_ = node.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
    state_subscriber_ =
        node.subscribe("/joint_states", 10, &CtcControllerNode::onJointState, this, ros::TransportHints().tcpNoDelay());
    trajectory_subscriber_ = node.subscribe("command", 10, &CtcControllerNode::onTrajectory, this);
    mode_service_ = node.advertiseService("set_mode", &CtcControllerNode::onSetMode, this);
    watchdog_ = node.createSteadyTimer(ros::WallDuration(0.02), &CtcControllerNode::onWatchdog, this);
    diagnostics_timer_ = node.createSteadyTimer(ros::WallDuration(1.0), &CtcControllerNode::onDiagnostics, this);
    ROS_INFO("ctc_controller %s: %d joints %s -> %s, friction %s, mode %s", arm_.c_str(), n, base.c_str(), tip.c_str(),
             friction_file.empty() ? "none" : friction_file.c_str(), initial.c_str());
  }

 private:
  void onJointState(const sensor_msgs::JointState::ConstPtr& message) {
    if (index_.empty() || message->name.size() != names_seen_) {
      index_.clear();
      names_seen_ = message->name.size();
      for (const std::string& name : joint_names_) {
        const auto it = std::find(message->name.begin(), message->name.end(), name);
        if (it == message->name.end()) {
          index_.clear();
          break;
        }
        index_.push_back(static_cast<int>(it - message->name.begin()));
      }
    }
    if (index_.empty()) {
      ROS_ERROR_THROTTLE(2.0, "ctc_controller %s: /joint_states lacks this arm's joints (%s, ...)", arm_.c_str(),
                         joint_names_.front().c_str());
      return;
    }
    const int n = static_cast<int>(index_.size());
    for (int i = 0; i < n; ++i) {
      const auto j = static_cast<std::size_t>(index_[i]);
      q_[i] = j < message->position.size() ? message->position[j] : std::nan("");
      qd_[i] = j < message->velocity.size() ? message->velocity[j] : std::nan("");
    }
    const double now = ros::Time::now().toSec(), stamp = message->header.stamp.toSec();
    const bc::ControllerStatus status = controller_->update(now, stamp, q_, qd_, torque_);
    count(status);
    if (status == bc::ControllerStatus::InvalidState || status == bc::ControllerStatus::StaleState) return;
    std::copy(torque_.data(), torque_.data() + n, command_.data.begin());
    effort_publisher_.publish(command_);
    if (now >= next_publish_ || now < next_publish_ - 1.0) {
      next_publish_ = now + publish_period_;
      publishEstimates(message->header.stamp);
    }
  }

  void count(bc::ControllerStatus status) {
    ++counts_[static_cast<int>(status)];
    if (status == bc::ControllerStatus::InvalidState) {
      ROS_WARN_THROTTLE(1.0, "ctc_controller %s: joint state rejected (NaN/Inf or missing values); no torque sent",
                        arm_.c_str());
    } else if (status == bc::ControllerStatus::StaleState) {
      ROS_WARN_THROTTLE(1.0, "ctc_controller %s: joint state older than the timeout; no torque sent, will hold",
                        arm_.c_str());
    } else if (status == bc::ControllerStatus::VelocityLimit) {
      ROS_WARN_THROTTLE(1.0, "ctc_controller %s: velocity limit exceeded; holding position", arm_.c_str());
    }
  }

  void publishEstimates(const ros::Time& stamp) {
    geometry_msgs::WrenchStamped wrench;
    wrench.header.stamp = stamp;
    wrench.header.frame_id = base_frame_;
    const auto& w = controller_->estimatedWrench();
    wrench.wrench.force.x = w[0];
    wrench.wrench.force.y = w[1];
    wrench.wrench.force.z = w[2];
    wrench.wrench.torque.x = w[3];
    wrench.wrench.torque.y = w[4];
    wrench.wrench.torque.z = w[5];
    wrench_publisher_.publish(wrench);
    error_message_.header.stamp = stamp;
    const Eigen::VectorXd& e = controller_->trackingError();
    for (int i = 0; i < e.size(); ++i) {
      error_message_.position[i] = e[i];
      error_message_.velocity[i] = controller_->desiredVelocity()[i] - qd_[i];
    }
    error_publisher_.publish(error_message_);
    publishToolPaths(stamp);
  }

  /// Appends the actual and commanded tool positions; publishes both paths every tenth call.
  void publishToolPaths(const ros::Time& stamp) {
    const auto tool = [this](const Eigen::VectorXd& q) {
      if (bs::kinematics::forwardKinematics(controller_->model(), *kinematics_, q) !=
          bs::kinematics::KinematicsStatus::Success) {
        return geometry_msgs::Point();
      }
      return bs::nodes::toPoint(kinematics_->tipPose().translation());
    };
    for (auto* path : {&actual_path_, &desired_path_}) {
      if (path->size() >= kPathLength) path->pop_front();
    }
    actual_path_.push_back(tool(q_));
    desired_path_.push_back(tool(controller_->desiredPosition()));
    if (++path_calls_ % 10 != 0 || path_publisher_.getNumSubscribers() == 0) return;
    visualization_msgs::MarkerArray markers;
    for (int k = 0; k < 2; ++k) {
      visualization_msgs::Marker m;
      m.header.stamp = stamp;
      m.header.frame_id = base_frame_;
      m.ns = k == 0 ? "actual" : "commanded";
      m.type = visualization_msgs::Marker::LINE_STRIP;
      m.pose.orientation.w = 1.0;
      m.scale.x = 0.006;
      m.color.a = 1.0f;
      (k == 0 ? m.color.g : m.color.r) = 0.9f;
      const auto& path = k == 0 ? actual_path_ : desired_path_;
      m.points.assign(path.begin(), path.end());
      markers.markers.push_back(m);
    }
    path_publisher_.publish(markers);
  }

  void onTrajectory(const trajectory_msgs::JointTrajectory::ConstPtr& message) {
    if (message->points.empty()) {
      controller_->setMode(bc::ControllerMode::Hold);
      ROS_INFO("ctc_controller %s: empty trajectory: holding", arm_.c_str());
      return;
    }
    const int n = static_cast<int>(joint_names_.size()), k = static_cast<int>(message->points.size());
    std::vector<int> column(n, -1);
    for (int i = 0; i < n; ++i) {
      const auto it = std::find(message->joint_names.begin(), message->joint_names.end(), joint_names_[i]);
      if (it != message->joint_names.end()) column[i] = static_cast<int>(it - message->joint_names.begin());
    }
    if (message->joint_names.size() != static_cast<std::size_t>(n) ||
        std::find(column.begin(), column.end(), -1) != column.end()) {
      return reject("it must name each of the arm's " + std::to_string(n) + " joints once");
    }
    const double offset =
        message->header.stamp.isZero() ? 0.0 : std::max(0.0, (message->header.stamp - ros::Time::now()).toSec());
    const bool with_velocities = !message->points.front().velocities.empty();
    const bool with_accelerations = !message->points.front().accelerations.empty();
    bc::Waypoints w;
    w.times.resize(k);
    w.positions.resize(n, k);
    if (with_velocities) w.velocities.resize(n, k);
    if (with_accelerations) w.accelerations.resize(n, k);
    for (int p = 0; p < k; ++p) {
      const auto& point = message->points[p];
      if (point.positions.size() != static_cast<std::size_t>(n) ||
          point.velocities.size() != (with_velocities ? static_cast<std::size_t>(n) : 0u) ||
          point.accelerations.size() != (with_accelerations ? static_cast<std::size_t>(n) : 0u)) {
        return reject("point " + std::to_string(p) + " has the wrong number of positions, velocities or accelerations");
      }
      w.times[p] = offset + point.time_from_start.toSec();
      for (int i = 0; i < n; ++i) {
        w.positions(i, p) = point.positions[column[i]];
        if (with_velocities) w.velocities(i, p) = point.velocities[column[i]];
        if (with_accelerations) w.accelerations(i, p) = point.accelerations[column[i]];
      }
    }
    const bc::TrajectoryStatus status = controller_->setTrajectory(w);
    if (status != bc::TrajectoryStatus::Ok) {
      return reject(std::string(bc::toString(status)) +
                    (status == bc::TrajectoryStatus::NotIncreasing ? " (times from start must be > 0 and increase)"
                     : status == bc::TrajectoryStatus::OutOfLimits ? " (a point is outside the joint limits)"
                     : status == bc::TrajectoryStatus::NotFinite   ? " (NaN or Inf)"
                                                                   : " (too many points or wrong sizes)"));
    }
    ++trajectories_;
    ROS_INFO("ctc_controller %s: tracking %d points over %.2f s", arm_.c_str(), k, w.times[k - 1]);
  }

  void reject(const std::string& reason) {
    ++rejected_trajectories_;
    last_rejection_ = reason;
    ROS_WARN("ctc_controller %s: trajectory rejected: %s; the current motion goes on", arm_.c_str(), reason.c_str());
  }

  bool onSetMode(bimanual_skills::SetControlMode::Request& request,
                 bimanual_skills::SetControlMode::Response& response) {
    bc::ControllerMode mode;
    if (!bc::modeFromString(request.mode.c_str(), mode)) {
      response.message = "unknown mode '" + request.mode + "' (gravity_compensation, hold, track)";
      return true;
    }
    controller_->setMode(mode);
    response.success = true;
    response.message = "mode " + request.mode + " from the next control step";
    ROS_INFO("ctc_controller %s: %s", arm_.c_str(), response.message.c_str());
    return true;
  }

  void onWatchdog(const ros::SteadyTimerEvent&) {
    const bool stale = controller_->stale(ros::Time::now().toSec());
    if (stale && !reported_stale_) {
      ++stale_events_;
      ROS_WARN("ctc_controller %s: no joint state for more than the timeout; no torque sent, will hold", arm_.c_str());
    }
    reported_stale_ = stale;
  }

  void onDiagnostics(const ros::SteadyTimerEvent&) {
    diagnostic_msgs::DiagnosticArray array;
    array.header.stamp = ros::Time::now();
    diagnostic_msgs::DiagnosticStatus status;
    status.name = "ctc_controller: " + arm_;
    status.hardware_id = arm_;
    const bool started = controller_->started();
    status.level =
        !started || reported_stale_ ? diagnostic_msgs::DiagnosticStatus::WARN : diagnostic_msgs::DiagnosticStatus::OK;
    status.message = !started          ? "waiting for joint states"
                     : reported_stale_ ? "joint states stale"
                                       : std::string("running, mode ") + bc::toString(controller_->mode());
    const auto add = [&status](const std::string& key, const std::string& value) {
      diagnostic_msgs::KeyValue kv;
      kv.key = key;
      kv.value = value;
      status.values.push_back(kv);
    };
    add("mode", bc::toString(controller_->mode()));
    add("max_tracking_error_rad", std::to_string(controller_->trackingError().cwiseAbs().maxCoeff()));
    add("control_steps", std::to_string(counts_[0] + counts_[1]));
    add("saturated_steps", std::to_string(counts_[static_cast<int>(bc::ControllerStatus::Saturated)]));
    add("invalid_states", std::to_string(counts_[static_cast<int>(bc::ControllerStatus::InvalidState)]));
    add("stale_states", std::to_string(counts_[static_cast<int>(bc::ControllerStatus::StaleState)] + stale_events_));
    add("velocity_limit_events", std::to_string(counts_[static_cast<int>(bc::ControllerStatus::VelocityLimit)]));
    add("trajectories", std::to_string(trajectories_));
    add("rejected_trajectories", std::to_string(rejected_trajectories_));
    add("last_rejection", last_rejection_);
    array.status.push_back(status);
    diagnostics_publisher_.publish(array);
  }

  std::string arm_, base_frame_, last_rejection_;
  std::vector<std::string> joint_names_;
  std::vector<int> index_;
  std::size_t names_seen_ = 0;
  static constexpr std::size_t kPathLength = 1000;
  std::unique_ptr<bc::ArmController> controller_;
  std::unique_ptr<bs::kinematics::ChainData> kinematics_;
  std::deque<geometry_msgs::Point> actual_path_, desired_path_;
  long path_calls_ = 0;
  Eigen::VectorXd q_, qd_, torque_;
  std_msgs::Float64MultiArray command_;
  sensor_msgs::JointState error_message_;
  ros::Publisher effort_publisher_, wrench_publisher_, error_publisher_, path_publisher_, diagnostics_publisher_;
  ros::Subscriber state_subscriber_, trajectory_subscriber_;
  ros::ServiceServer mode_service_;
  ros::SteadyTimer watchdog_, diagnostics_timer_;
  double publish_period_ = 0.01, next_publish_ = 0.0;
  long counts_[5] = {0, 0, 0, 0, 0};
  long stale_events_ = 0, trajectories_ = 0, rejected_trajectories_ = 0;
  bool reported_stale_ = false;
};

}  // namespace

int main(int argc, char** argv) {
  bs::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "ctc_controller");
  ros::NodeHandle node, private_node("~");
  try {
    CtcControllerNode controller(node, private_node);
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("ctc_controller: %s", e.what());
    return 1;
  }
  return 0;
}
