// ctc_controller: one arm's computed-torque controller as a separate process, driven by joint-state messages: for a
// robot whose driver publishes joint states and takes torque commands over ROS. (A robot whose driver can host the
// controller runs it in its own real-time loop instead, as bullet_sim does.) A thin shell around
// ros_layer::ArmControllerInterface: the control step runs per message on a thread and callback queue of its own, so
// trajectory parsing, actions, markers and diagnostics never delay it; it computes with the stamps' Δt, checks the
// joint names of every message, drops duplicate and reordered states and follows one publisher.
#include "bimanual_skills/JointEffortCommand.h"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/realtime/loop_pacer.hpp"
#include "bimanual_skills/realtime/period_recorder.hpp"
#include "bimanual_skills/ros_layer/arm_controller_interface.hpp"
#include "bimanual_skills/ros_layer/hosted_loop.hpp"
#include "bimanual_skills/ros_layer/queue_spinner.hpp"
#include "bimanual_skills/sim/robot_file.hpp"
#include "cli/pinned_numerics.hpp"
#include "io/whole_file.hpp"
#include "node_cli.hpp"

#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>

#include <chrono>
#include <cmath>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace bs = bimanual_skills;
namespace bc = bimanual_skills::control;

namespace {

const std::string kUsage =
    std::string(
        "usage: rosrun bimanual_skills ctc_controller __ns:=ARM [_param:=value ...] [joint_states:=/joint_states]\n"
        "\n"
        "Computed-torque controller of one arm (thesis eq. 4.17) with the identified friction model and the\n"
        "disturbance observer (Sec. 4.1) estimating the external wrench at the tool, in a process of its own: one\n"
        "control step per joint-state message (on its own thread), Δt from the message stamps. Messages that repeat\n"
        "or precede the last stamp are dropped; states from a second publisher are ignored (the first one is\n"
        "followed until it falls silent for 1 s); the joint names are matched in every message.\n"
        "\n"
        "Parameters (private; config/ctc_controller.yaml holds the defaults):\n"
        "  ~arm                  arm name (default: the namespace)\n"
        "  ~robot                robot file (config/robots/*.yaml): the arm's chain, gains and friction model by\n"
        "                        default\n"
        "  ~loop_priority        SCHED_FIFO priority of the control thread, 1-99 (0: unchanged, the default)\n"
        "  ~statistics_file      at exit, write the control steps' wall periods and the times commands were taken\n"
        "                        (CSV)\n"
        "  ~local_impedance      true: each command carries the computed-torque law's PD part as a joint impedance\n"
        "                        (setpoint, Kp, Kv) that the robot closes at its own rate until the next command,\n"
        "                        the effort the rest (as torque-controlled arms' drivers take it: a late or bursty\n"
        "                        command stream then leaves no joint open-loop); false (default): torque only\n") +
    bs::ros_layer::kControllerParameterHelp +
    "Reads robot_description. Topics (relative to the namespace; remap joint_states in a launch file): subscribes\n"
    "joint_states (sensor_msgs/JointState; effort, when complete, is taken as the torque the robot applied) and\n"
    "command (trajectory_msgs/JointTrajectory); serves follow_joint_trajectory (bimanual_skills/FollowJoint-\n"
    "Trajectory action) and set_mode (bimanual_skills/SetControlMode); publishes effort_command\n"
    "(bimanual_skills/JointEffortCommand, stamped with the joint state it answers), state "
    "(bimanual_skills/JointTrajectoryControllerState), estimated_wrench\n"
    "(geometry_msgs/WrenchStamped, base frame), estimated_external_torque (sensor_msgs/JointState, effort: the\n"
    "observer's joint torques), tool_paths (visualization_msgs/MarkerArray), /diagnostics.\n";

/// [s] A state stamped this much before the last one is a reset (the clock may not have followed yet), not a
/// reordered message. So is one stamped at a timeline's start (t = 0: a simulation reset less than this after its own
/// start; a robot's stamps are wall-clock times).
constexpr double kResetJump = 1.0;

class CtcControllerNode {
 public:
  CtcControllerNode(ros::NodeHandle& node, ros::NodeHandle& private_node) : node_(node) {
    std::string ns = node.getNamespace();
    ns = ns.substr(ns.find_last_of('/') + 1);
    bs::ros_layer::ParameterReader parameters(private_node, "ctc_controller");
    const std::string arm = parameters.text("arm", ns);
    loop_priority_ = parameters.integer("loop_priority", 0, 0, 99);
    statistics_file_ = parameters.text("statistics_file", "");
    local_impedance_ = parameters.boolean("local_impedance", false);
    // The robot file (config/robots/*.yaml), when given: the arm's chain, gains and friction model by default.
    const std::string robot_path = parameters.text("robot", "");
    bs::ros_layer::ControllerDefaults defaults;
    if (arm.empty()) throw std::invalid_argument("no arm name: run in the arm's namespace (__ns:=left) or set ~arm");
    std::string description, key;
    if (!private_node.searchParam("robot_description", key) || !ros::param::get(key, description)) {
      throw std::invalid_argument("parameter 'robot_description' is not set");
    }
    if (!robot_path.empty()) {
      const bs::sim::RobotFile robot = bs::sim::RobotFile::fromYamlFile(robot_path);
      defaults = bs::ros_layer::controllerDefaults(&robot, arm);
    }
    interface_ = std::make_unique<bs::ros_layer::ArmControllerInterface>(node, parameters, arm, description,
                                                                         "ctc_controller " + arm, defaults);
    parameters.warnUnknown();
    const int n = static_cast<int>(interface_->jointNames().size());
    q_ = qd_ = applied_ = torque_ = Eigen::VectorXd::Zero(n);
    none_.resize(0);
    command_.name = interface_->jointNames();
    command_.effort.assign(static_cast<std::size_t>(n), 0.0);
    if (local_impedance_) {
      for (auto* v : {&command_.position, &command_.velocity, &command_.stiffness, &command_.damping}) {
        v->assign(static_cast<std::size_t>(n), 0.0);
      }
    }
    nominal_period_ = 1.0 / interface_->settings().config.observer.rate_hz;
    effort_publisher_ = node.advertise<bimanual_skills::JointEffortCommand>("effort_command", 10);
    ros::NodeHandle state_node(node);
    state_node.setCallbackQueue(&state_queue_);
    state_subscriber_ = state_node.subscribe("joint_states", 10, &CtcControllerNode::onJointState, this,
                                             ros::TransportHints().tcpNoDelay());
    diagnostics_timer_ = node.createSteadyTimer(ros::WallDuration(1.0), &CtcControllerNode::onDiagnostics, this);
    ROS_INFO("ctc_controller %s: %d joints %s -> %s, friction %s, subscribed to %s", arm.c_str(), n,
             interface_->settings().base_link.c_str(), interface_->settings().tip_link.c_str(),
             interface_->settings().friction_file.empty() ? "none" : interface_->settings().friction_file.c_str(),
             state_subscriber_.getTopic().c_str());
  }

  void spin() {
    bs::ros_layer::QueueSpinner control(1, &state_queue_);  // the control step, alone on its thread
    control.start();
    bs::ros_layer::QueueSpinner others(2);  // commands, actions, services, publishers, diagnostics
    others.start();
    ros::waitForShutdown();
    control.stop();
    if (!statistics_file_.empty()) writeStatistics();
  }

 private:
  /// Maps the arm's joints into the message (cached while the names are the same); false if one is missing.
  bool mapNames(const std::vector<std::string>& names) {
    if (names == mapped_names_ && !index_.empty()) return true;
    const std::vector<std::string>& joints = interface_->jointNames();
    index_.clear();
    for (const std::string& joint : joints) {
      const auto it = std::find(names.begin(), names.end(), joint);
      if (it == names.end()) {
        index_.clear();
        mapped_names_.clear();
        return false;
      }
      index_.push_back(static_cast<std::size_t>(it - names.begin()));
    }
    mapped_names_ = names;
    return true;
  }

  void onJointState(const ros::MessageEvent<sensor_msgs::JointState const>& event) {
    const sensor_msgs::JointState& message = *event.getConstMessage();
    const double wall = bimanual_skills::realtime::monotonicSeconds();
    if (!priority_requested_ && loop_priority_ > 0) {
      priority_requested_ = true;
      const char* error = bs::realtime::requestRealtimeScheduling(loop_priority_);
      if (*error != '\0') ROS_WARN("ctc_controller: ~loop_priority %d not granted (%s)", loop_priority_, error);
    }
    const std::string& publisher = event.getPublisherName();
    if (publisher != publisher_) {
      if (!publisher_.empty() && wall - last_followed_ < 1.0) {
        ++foreign_;
        ROS_WARN_THROTTLE(5.0, "ctc_controller: ignoring joint states from %s while following %s", publisher.c_str(),
                          publisher_.c_str());
        return;
      }
      if (!publisher_.empty())
        ROS_WARN("ctc_controller: %s fell silent; following %s", publisher_.c_str(), publisher.c_str());
      publisher_ = publisher;
    }
    last_followed_ = wall;
    if (!mapNames(message.name)) {
      ++incomplete_;
      ROS_ERROR_THROTTLE(2.0, "ctc_controller: joint states from %s lack this arm's joints (%s, ...)",
                         publisher.c_str(), interface_->jointNames().front().c_str());
      return;
    }
    const double stamp = message.header.stamp.toSec();
    double now = ros::Time::now().toSec();
    // A stamp that does not advance is a duplicate or a reordered message, unless the clock went back too or the
    // stamps jumped back by more than kResetJump or to t = 0 (a simulation reset), which the controller restarts on.
    const bool back = has_stamp_ && stamp <= last_stamp_ && now >= last_stamp_;
    if (back && last_stamp_ - stamp <= kResetJump && !(stamp <= 0.0 && last_stamp_ > 0.0)) {
      ++(stamp == last_stamp_ ? duplicates_ : reordered_);
      return;
    }
    // A reset seen in the stamps before /clock followed (another connection): until the clock goes back too, it lags
    // the states, and the state's own stamp stands for now (else the fresh states would look stale).
    if (back) clock_before_reset_ = now;
    if (!std::isnan(clock_before_reset_)) {
      if (now < clock_before_reset_) {
        clock_before_reset_ = std::nan("");
      } else {
        now = stamp;
      }
    }
    for (std::size_t i = 0; i < index_.size(); ++i) {
      const std::size_t j = index_[i];
      const auto k = static_cast<Eigen::Index>(i);
      q_[k] = j < message.position.size() ? message.position[j] : std::nan("");
      qd_[k] = j < message.velocity.size() ? message.velocity[j] : std::nan("");
    }
    const bool with_effort = message.effort.size() == message.name.size();
    if (with_effort) {
      for (std::size_t i = 0; i < index_.size(); ++i)
        applied_[static_cast<Eigen::Index>(i)] = message.effort[index_[i]];
    }
    const bc::ControllerStatus status =
        interface_->realtime().update(now, stamp, q_, qd_, with_effort ? applied_ : none_, torque_);
    if (status == bc::ControllerStatus::InvalidState || status == bc::ControllerStatus::StaleState) return;
    if (last_step_wall_ > 0.0) wall_periods_.record(wall - last_step_wall_);
    last_step_wall_ = wall;
    if (interface_->realtime().commandsTaken() != commands_taken_) {
      commands_taken_ = interface_->realtime().commandsTaken();
      command_times_.record(interface_->realtime().lastCommandTaken());
    }
    if (has_stamp_) {
      const double dt = stamp - last_stamp_;
      if (dt > 0.0 && dt < 1.0) periods_.record(dt);
    }
    has_stamp_ = true;
    last_stamp_ = stamp;
    if (wall - last_period_check_ > 5.0 && periods_.recorded() >= 200) checkRate(wall);
    std::copy(torque_.data(), torque_.data() + torque_.size(), command_.effort.begin());
    if (local_impedance_) splitImpedance();
    command_.header.stamp = message.header.stamp;  // the state it answers: a lockstep loop matches the two
    effort_publisher_.publish(command_);
  }

  /// ~local_impedance: the command's effort without the PD part Kp (q_d − q) + Kv (q̇_d − q̇) of this state, and
  /// that part as the impedance the robot closes itself (at this state it adds it back). Without a PD part
  /// (gravity compensation) the gains are zero.
  void splitImpedance() {
    const bc::ArmController& controller = interface_->realtime().controller();
    const bool pd = controller.started() && controller.mode() != bc::ControllerMode::GravityCompensation;
    const bc::ComputedTorqueGains& gains = controller.gains();
    const Eigen::VectorXd& q_d = controller.desiredPosition();
    const Eigen::VectorXd& qd_d = controller.desiredVelocity();
    for (Eigen::Index i = 0; i < torque_.size(); ++i) {
      const auto k = static_cast<std::size_t>(i);
      const double kp = pd ? gains.kp[i] : 0.0, kv = pd ? gains.kv[i] : 0.0;
      command_.position[k] = pd ? q_d[i] : q_[i];
      command_.velocity[k] = pd ? qd_d[i] : qd_[i];
      command_.stiffness[k] = kp;
      command_.damping[k] = kv;
      command_.effort[k] = torque_[i] - kp * (command_.position[k] - q_[i]) - kv * (command_.velocity[k] - qd_[i]);
    }
  }

  /// Warns when the states' rate differs from the observer's nominal rate by more than 20 %.
  void checkRate(double wall) {
    last_period_check_ = wall;
    std::vector<double> periods;
    periods_.snapshot(periods);
    const double median = bs::realtime::quantile(periods, 0.5);
    if (std::abs(median - nominal_period_) > 0.2 * nominal_period_ && !rate_warned_) {
      rate_warned_ = true;
      ROS_WARN(
          "ctc_controller: joint states arrive every %.4f s (median); the observer's nominal rate is %.0f Hz. "
          "It integrates the measured dt, but set observer/rate to the robot's rate for its FIR's cut-off",
          median, 1.0 / nominal_period_);
    }
  }

  void writeStatistics() const {
    const bool written = bs::io::writeWhole(statistics_file_, [this](std::ostream& out) {
      out << "series,value\n";
      wall_periods_.writeCsv(out, "period");
      command_times_.writeCsv(out, "command_taken");
    });
    if (!written) ROS_ERROR("ctc_controller: cannot write %s", statistics_file_.c_str());
  }

  void onDiagnostics(const ros::SteadyTimerEvent&) {
    interface_->setDriverDiagnostics({{"joint_state_publisher", publisher_},
                                      {"ignored_other_publishers", std::to_string(foreign_.load())},
                                      {"dropped_duplicate_states", std::to_string(duplicates_.load())},
                                      {"dropped_reordered_states", std::to_string(reordered_.load())},
                                      {"states_without_the_arm", std::to_string(incomplete_.load())}});
  }

  ros::NodeHandle& node_;
  std::unique_ptr<bs::ros_layer::ArmControllerInterface> interface_;
  ros::CallbackQueue state_queue_;
  ros::Subscriber state_subscriber_;
  ros::Publisher effort_publisher_;
  ros::SteadyTimer diagnostics_timer_;
  // The control thread's.
  std::vector<std::string> mapped_names_;
  std::vector<std::size_t> index_;
  std::string publisher_;
  double last_followed_ = 0.0, last_stamp_ = 0.0, nominal_period_ = 0.001, last_period_check_ = 0.0;
  bool has_stamp_ = false, rate_warned_ = false;
  double clock_before_reset_ = std::nan("");  ///< The clock when a reset came in the stamps before it (NaN: none).
  Eigen::VectorXd q_, qd_, applied_, torque_, none_;
  bimanual_skills::JointEffortCommand command_;
  bs::realtime::PeriodRecorder periods_{1000}, wall_periods_{200000}, command_times_{10000};
  double last_step_wall_ = 0.0;
  std::uint64_t commands_taken_ = 0;
  int loop_priority_ = 0;
  bool priority_requested_ = false, local_impedance_ = false;
  std::string statistics_file_;
  std::atomic<long> foreign_{0}, duplicates_{0}, reordered_{0}, incomplete_{0};
};

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bs::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "ctc_controller");
  ros::NodeHandle node, private_node("~");
  try {
    CtcControllerNode controller(node, private_node);
    controller.spin();
  } catch (const std::exception& e) {
    ROS_FATAL("ctc_controller: %s", e.what());
    return 1;
  }
  return 0;
}
