// bullet_sim: the Bullet simulation of the bimanual WAM (sim::BimanualSimulation) as a ROS node. A thin shell: it
// moves joint states, torque commands, the cloth and service requests between ROS and the library.
#include "bimanual_skills/ApplyWrench.h"
#include "bimanual_skills/ClothGrasp.h"
#include "bimanual_skills/SetPayload.h"
#include "bimanual_skills/SimStep.h"
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "bimanual_skills/sim/torque_command_gate.hpp"
#include "node_cli.hpp"
#include "scene_markers.hpp"

#include <ros/callback_queue.h>
#include <ros/package.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/JointState.h>
#include <std_msgs/Float64MultiArray.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <visualization_msgs/MarkerArray.h>

#include <chrono>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace bs = bimanual_skills;
namespace sim = bimanual_skills::sim;

namespace {

const char* const kUsage =
    "usage: rosrun bimanual_skills bullet_sim [_config:=FILE] [_lockstep:=true|false] [ROS remappings]\n"
    "\n"
    "The Bullet simulation of the bimanual WAM (two arms with their true plant, table, cloth) as a ROS node.\n"
    "Simulated time is published on /clock (set /use_sim_time true for the other nodes).\n"
    "\n"
    "Parameters (private, defaults in config/bullet_sim.yaml):\n"
    "  ~config             simulation file (default: the package's config/sim.yaml)\n"
    "  ~lockstep           true: each physics step waits for one command of every expected controller, so a run\n"
    "                      is repeatable bit for bit; false: free-running at ~realtime_factor\n"
    "  ~controllers        arms whose commands a lockstep step waits for (default: all)\n"
    "  ~lockstep_timeout   wall seconds a lockstep step waits before braking the missing arms (default 0.2)\n"
    "  ~realtime_factor    free-running speed, simulated s per wall s (default 1; 0: as fast as possible)\n"
    "  ~command_timeout    simulated s after which a command is stale: zero torque plus braking (default 0.05)\n"
    "  ~braking_damping    N m s/rad per joint applied when commands are stale\n"
    "  ~initial_positions  map arm -> joint positions at start and after ~reset\n"
    "  ~marker_rate        cloth and table marker rate [Hz of simulated time] (default 30)\n"
    "  ~paused             start paused (default false)\n"
    "\n"
    "Topics: publishes /joint_states (sensor_msgs/JointState, every step), /clock, ~markers\n"
    "  (visualization_msgs/MarkerArray: cloth TRIANGLE_LIST and table); subscribes <arm>/effort_command\n"
    "  (std_msgs/Float64MultiArray, one torque per joint [N m]).\n"
    "Services: ~reset (std_srvs/Trigger), ~pause (std_srvs/SetBool), ~step (bimanual_skills/SimStep),\n"
    "  ~set_payload (bimanual_skills/SetPayload), ~apply_wrench (bimanual_skills/ApplyWrench),\n"
    "  ~grasp (bimanual_skills/ClothGrasp).\n";

/// One arm as the node sees it.
struct Arm {
  std::string name;
  std::vector<std::string> joint_names;
  std::unique_ptr<sim::TorqueCommandGate> gate;
  ros::Subscriber command_subscriber;
  sim::JointState state;
  Eigen::VectorXd command, torque, initial;
  bool expected = true;   ///< Lockstep waits for its commands.
  int commands_seen = 0;  ///< Commands accepted since the last joint-state publication.
  bool braking = false;
};

class BulletSimNode {
 public:
  BulletSimNode(ros::NodeHandle& node, ros::NodeHandle& private_node) : node_(node) {
    std::string config_path;
    private_node.param<std::string>("config", config_path,
                                    ros::package::getPath("bimanual_skills") + "/config/sim.yaml");
    simulation_ = std::make_unique<sim::BimanualSimulation>(sim::SimConfig::fromYamlFile(config_path));
    private_node.param("lockstep", lockstep_, false);
    private_node.param("lockstep_timeout", lockstep_timeout_, 0.2);
    private_node.param("realtime_factor", realtime_factor_, 1.0);
    private_node.param("marker_rate", marker_rate_, 30.0);
    private_node.param("paused", paused_, false);
    double command_timeout = 0.05;
    private_node.param("command_timeout", command_timeout, command_timeout);
    std::vector<double> damping;
    private_node.param("braking_damping", damping, std::vector<double>{});
    std::vector<std::string> controllers;
    const bool controllers_given = private_node.getParam("controllers", controllers);
    if (lockstep_timeout_ <= 0.0 || realtime_factor_ < 0.0 || marker_rate_ <= 0.0) {
      throw std::invalid_argument("lockstep_timeout and marker_rate must be > 0, realtime_factor >= 0");
    }
    for (int a = 0; a < simulation_->armCount(); ++a) {
      Arm arm;
      arm.name = simulation_->config().arms[a].name;
      const int n = simulation_->jointCount(a);
      arm.joint_names = simulation_->armModel(a).jointNames();
      if (damping.empty()) damping.assign(n, 10.0);
      if (static_cast<int>(damping.size()) != n) {
        throw std::invalid_argument("~braking_damping needs " + std::to_string(n) + " entries");
      }
      arm.gate = std::make_unique<sim::TorqueCommandGate>(n, command_timeout,
                                                          Eigen::Map<const Eigen::VectorXd>(damping.data(), n));
      arm.state = sim::JointState(n);
      arm.command = arm.torque = Eigen::VectorXd::Zero(n);
      std::vector<double> initial;
      if (private_node.getParam("initial_positions/" + arm.name, initial)) {
        if (static_cast<int>(initial.size()) != n) {
          throw std::invalid_argument("~initial_positions/" + arm.name + " needs " + std::to_string(n) + " entries");
        }
        arm.initial = Eigen::Map<const Eigen::VectorXd>(initial.data(), n);
      } else {
        arm.initial = simulation_->trueState(a).q;
      }
      arm.expected =
          !controllers_given || std::find(controllers.begin(), controllers.end(), arm.name) != controllers.end();
      arms_.push_back(std::move(arm));
    }
    for (const std::string& c : controllers) {
      if (simulation_->armIndex(c) < 0) throw std::invalid_argument("~controllers names an unknown arm '" + c + "'");
    }
    resetSimulation();

    // Commands have their own queue: a lockstep step waits on it alone, so services can run steps.
    for (int a = 0; a < static_cast<int>(arms_.size()); ++a) {
      ros::SubscribeOptions options = ros::SubscribeOptions::create<std_msgs::Float64MultiArray>(
          arms_[a].name + "/effort_command", 10,
          [this, a](const std_msgs::Float64MultiArray::ConstPtr& message) { onCommand(a, *message); }, ros::VoidPtr(),
          &command_queue_);
      options.transport_hints = ros::TransportHints().tcpNoDelay();
      arms_[a].command_subscriber = node_.subscribe(options);
    }
    joint_state_publisher_ = node_.advertise<sensor_msgs::JointState>("joint_states", 10);
    clock_publisher_ = node_.advertise<rosgraph_msgs::Clock>("/clock", 10);
    marker_publisher_ = private_node.advertise<visualization_msgs::MarkerArray>("markers", 1, true);
    services_.push_back(private_node.advertiseService("reset", &BulletSimNode::onReset, this));
    services_.push_back(private_node.advertiseService("pause", &BulletSimNode::onPause, this));
    services_.push_back(private_node.advertiseService("step", &BulletSimNode::onStep, this));
    services_.push_back(private_node.advertiseService("set_payload", &BulletSimNode::onSetPayload, this));
    services_.push_back(private_node.advertiseService("apply_wrench", &BulletSimNode::onApplyWrench, this));
    services_.push_back(private_node.advertiseService("grasp", &BulletSimNode::onGrasp, this));
    ROS_INFO("bullet_sim: %d arms, step %.4f s, cloth %s, %s%s", simulation_->armCount(), simulation_->stepSize(),
             simulation_->hasCloth() ? "on" : "off", lockstep_ ? "lockstep" : "free-running",
             paused_ ? ", paused" : "");
  }

  void run() {
    const auto wall_start = std::chrono::steady_clock::now();
    const double sim_start = simulation_->time();
    publishClock();
    publishMarkers();
    while (ros::ok()) {
      ros::getGlobalCallbackQueue()->callAvailable();
      if (paused_ || diverged_) {
        command_queue_.callAvailable(ros::WallDuration(0.01));
        continue;
      }
      stepOnce();
      if (realtime_factor_ > 0.0) {
        const double ahead = (simulation_->time() - sim_start) / realtime_factor_ -
                             std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
        if (ahead > 0.002) std::this_thread::sleep_for(std::chrono::duration<double>(ahead));
      }
    }
  }

 private:
  void resetSimulation() {
    std::vector<sim::ArmState> state;
    for (const Arm& arm : arms_) state.push_back({arm.initial, Eigen::VectorXd::Zero(arm.initial.size())});
    const sim::SimStatus status = simulation_->reset(state);
    simulation_->setRandomGenerator(std::mt19937(simulation_->config().seed));
    if (status != sim::SimStatus::Ok) {
      throw std::invalid_argument(std::string("initial positions rejected: ") + sim::toString(status));
    }
    for (Arm& arm : arms_) arm.gate->clear();
    diverged_ = false;
    next_marker_time_ = 0.0;
  }

  void onCommand(int a, const std_msgs::Float64MultiArray& message) {
    Arm& arm = arms_[a];
    if (static_cast<int>(message.data.size()) != arm.command.size()) {
      ROS_WARN_THROTTLE(1.0, "bullet_sim: %s/effort_command rejected: %zu values for %d joints", arm.name.c_str(),
                        message.data.size(), static_cast<int>(arm.command.size()));
      ++arm.commands_seen;  // answered, though wrongly: a lockstep step need not wait for it
      return;
    }
    arm.command = Eigen::Map<const Eigen::VectorXd>(message.data.data(), arm.command.size());
    if (arm.gate->accept(simulation_->time(), arm.command) != sim::RobotStatus::Ok) {
      ROS_WARN_THROTTLE(1.0, "bullet_sim: %s/effort_command rejected: not finite (NaN or Inf)", arm.name.c_str());
    }
    ++arm.commands_seen;
  }

  void publishJointStates() {
    sensor_msgs::JointState message;
    message.header.stamp = ros::Time(simulation_->time());
    for (int a = 0; a < static_cast<int>(arms_.size()); ++a) {
      Arm& arm = arms_[a];
      simulation_->readJointState(a, arm.state);
      message.name.insert(message.name.end(), arm.joint_names.begin(), arm.joint_names.end());
      message.position.insert(message.position.end(), arm.state.position.data(),
                              arm.state.position.data() + arm.state.position.size());
      message.velocity.insert(message.velocity.end(), arm.state.velocity.data(),
                              arm.state.velocity.data() + arm.state.velocity.size());
      message.effort.insert(message.effort.end(), arm.state.effort.data(),
                            arm.state.effort.data() + arm.state.effort.size());
      arm.commands_seen = 0;
    }
    joint_state_publisher_.publish(message);
  }

  void publishClock() {
    rosgraph_msgs::Clock clock;
    clock.clock = ros::Time(simulation_->time());
    clock_publisher_.publish(clock);
  }

  /// Waits (wall clock) until every expected arm answered the last joint states; false on timeout.
  bool waitForCommands() {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(lockstep_timeout_);
    for (;;) {
      bool all = true;
      for (const Arm& arm : arms_) all = all && (!arm.expected || arm.commands_seen > 0);
      if (all) return true;
      if (!ros::ok() || std::chrono::steady_clock::now() > deadline) return false;
      command_queue_.callAvailable(ros::WallDuration(0.001));
    }
  }

  bool stepOnce() {
    publishJointStates();
    if (lockstep_) {
      if (!waitForCommands()) {
        std::string missing;
        for (const Arm& arm : arms_) {
          if (arm.expected && arm.commands_seen == 0) missing += " " + arm.name;
        }
        ROS_WARN_THROTTLE(2.0, "bullet_sim: lockstep: no command within %.2f s from:%s (those arms brake)",
                          lockstep_timeout_, missing.c_str());
      }
    } else {
      command_queue_.callAvailable();
    }
    for (int a = 0; a < static_cast<int>(arms_.size()); ++a) {
      Arm& arm = arms_[a];
      const bool braking = arm.gate->torque(simulation_->time(), arm.state.velocity, arm.torque);
      if (braking != arm.braking && arm.gate->hasCommand()) {
        if (braking) {
          ROS_WARN("bullet_sim: %s: commands stopped arriving; zero torque plus braking damping", arm.name.c_str());
        } else {
          ROS_INFO("bullet_sim: %s: commands arrive again", arm.name.c_str());
        }
      }
      arm.braking = braking;
      simulation_->writeJointTorques(a, arm.torque);
    }
    const sim::SimStatus status = simulation_->step();
    if (status == sim::SimStatus::ArmDiverged) {
      ROS_ERROR("bullet_sim: an arm diverged at t = %.3f s; paused until ~reset", simulation_->time());
      diverged_ = true;
    } else if (status == sim::SimStatus::ClothDiverged && !cloth_diverged_) {
      ROS_ERROR("bullet_sim: the cloth diverged at t = %.3f s; it is frozen until ~reset", simulation_->time());
    }
    cloth_diverged_ = status == sim::SimStatus::ClothDiverged;
    publishClock();
    if (simulation_->time() >= next_marker_time_) {
      publishMarkers();
      next_marker_time_ = simulation_->time() + 1.0 / marker_rate_;
    }
    return status != sim::SimStatus::ArmDiverged;
  }

  void publishMarkers() {
    visualization_msgs::MarkerArray markers;
    const ros::Time stamp(simulation_->time());
    if (simulation_->config().has_table)
      markers.markers.push_back(bs::nodes::tableMarker(simulation_->config().table, stamp));
    if (simulation_->hasCloth()) {
      markers.markers.push_back(
          bs::nodes::clothMarker(simulation_->cloth().vertices(), simulation_->cloth().triangles(), stamp));
    }
    marker_publisher_.publish(markers);
  }

  int armOf(const std::string& name, std::string& message) const {
    const int a = simulation_->armIndex(name);
    if (a < 0) {
      message = "unknown arm '" + name + "'; arms:";
      for (const Arm& arm : arms_) message += " " + arm.name;
    }
    return a;
  }

  bool onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    resetSimulation();
    publishClock();  // before the states, so the controllers' clocks go back first
    publishJointStates();
    publishMarkers();
    response.success = true;
    response.message = "reset to the initial positions at t = 0 (sensor noise reseeded)";
    ROS_INFO("bullet_sim: %s", response.message.c_str());
    return true;
  }

  bool onPause(std_srvs::SetBool::Request& request, std_srvs::SetBool::Response& response) {
    paused_ = request.data;
    response.success = true;
    response.message = paused_ ? "paused" : "running";
    return true;
  }

  bool onStep(bimanual_skills::SimStep::Request& request, bimanual_skills::SimStep::Response& response) {
    if (!paused_) {
      response.message = "the simulation is running; pause it first (~pause true)";
    } else if (diverged_) {
      response.message = "the simulation diverged; call ~reset";
    } else {
      uint32_t done = 0;
      while (done < request.steps && ros::ok() && stepOnce()) ++done;
      response.success = done == request.steps;
      response.message = "stepped " + std::to_string(done) + " of " + std::to_string(request.steps);
    }
    response.time = simulation_->time();
    return true;
  }

  bool onSetPayload(bimanual_skills::SetPayload::Request& request, bimanual_skills::SetPayload::Response& response) {
    const int a = armOf(request.arm, response.message);
    if (a < 0) return true;
    bs::dynamics::Payload payload;
    payload.mass = request.mass;
    payload.com = Eigen::Vector3d(request.center_of_mass.x, request.center_of_mass.y, request.center_of_mass.z);
    const sim::SimStatus status = simulation_->setPayload(a, payload);
    response.success = status == sim::SimStatus::Ok;
    response.message = response.success
                           ? "payload of " + std::to_string(request.mass) + " kg on " + request.arm
                           : std::string("rejected: ") + sim::toString(status) + " (mass must be finite and >= 0)";
    ROS_INFO("bullet_sim: %s", response.message.c_str());
    return true;
  }

  bool onApplyWrench(bimanual_skills::ApplyWrench::Request& request, bimanual_skills::ApplyWrench::Response& response) {
    sim::LinkHandle link;
    try {
      link = simulation_->link(request.link);
    } catch (const std::invalid_argument& e) {
      response.message = e.what();
      return true;
    }
    const auto& w = request.wrench;
    const sim::SimStatus status = simulation_->setExternalWrench(
        link, Eigen::Vector3d(w.force.x, w.force.y, w.force.z), Eigen::Vector3d(w.torque.x, w.torque.y, w.torque.z),
        Eigen::Vector3d(request.point.x, request.point.y, request.point.z));
    response.success = status == sim::SimStatus::Ok;
    response.message =
        response.success ? "wrench applied on " + request.link : std::string("rejected: ") + sim::toString(status);
    return true;
  }

  bool onGrasp(bimanual_skills::ClothGrasp::Request& request, bimanual_skills::ClothGrasp::Response& response) {
    const int a = armOf(request.arm, response.message);
    if (a < 0) return true;
    int attached = 0;
    const sim::SimStatus status = request.grasp ? simulation_->grasp(a, &attached) : simulation_->release(a);
    response.nodes = attached;
    response.success = status == sim::SimStatus::Ok;
    response.message = !response.success ? std::string("failed: ") + sim::toString(status)
                       : request.grasp   ? request.arm + " grasped " + std::to_string(attached) + " cloth nodes"
                                         : request.arm + " released the cloth";
    ROS_INFO("bullet_sim: %s", response.message.c_str());
    return true;
  }

  ros::NodeHandle& node_;
  std::unique_ptr<sim::BimanualSimulation> simulation_;
  std::vector<Arm> arms_;
  ros::CallbackQueue command_queue_;
  ros::Publisher joint_state_publisher_, clock_publisher_, marker_publisher_;
  std::vector<ros::ServiceServer> services_;
  bool lockstep_ = false, paused_ = false, diverged_ = false, cloth_diverged_ = false;
  double lockstep_timeout_ = 0.2, realtime_factor_ = 1.0, marker_rate_ = 30.0, next_marker_time_ = 0.0;
};

}  // namespace

int main(int argc, char** argv) {
  bs::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "bullet_sim");
  ros::NodeHandle node, private_node("~");
  try {
    BulletSimNode sim_node(node, private_node);
    sim_node.run();
  } catch (const std::exception& e) {
    ROS_FATAL("bullet_sim: %s", e.what());
    return 1;
  }
  return 0;
}
