// bullet_sim: the Bullet simulation of the bimanual WAM (sim::BimanualSimulation) as a ROS node, hosting the arms'
// controllers the way a robot's driver hosts them. The loop thread owns the simulation: each cycle it reads the
// joint states, runs each hosted controller (control::RealtimeArmController), writes the torques and steps the
// physics, paced on the wall clock; services, topics and the controllers' ROS interfaces run on other threads and
// reach the loop only through lock-free handoffs and a request mailbox the loop polls without waiting.
#include "bimanual_skills/ApplyWrench.h"
#include "bimanual_skills/ClothGrasp.h"
#include "bimanual_skills/SetPayload.h"
#include "bimanual_skills/SimStep.h"
#include "bimanual_skills/realtime/clock.hpp"
#include "bimanual_skills/realtime/loop_pacer.hpp"
#include "bimanual_skills/realtime/period_recorder.hpp"
#include "bimanual_skills/realtime/triple_buffer.hpp"
#include "bimanual_skills/ros_layer/arm_controller_interface.hpp"
#include "bimanual_skills/ros_layer/camera_messages.hpp"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "bimanual_skills/sim/torque_command_gate.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "bimanual_skills/vision/cloth_renderer.hpp"
#include "node_cli.hpp"
#include "scene_markers.hpp"
#include "testing/allocation_counter.hpp"

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/callback_queue.h>
#include <ros/package.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/JointState.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <std_msgs/Float64MultiArray.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>

#include <semaphore.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <deque>
#include <fstream>
#include <functional>
#include <future>
#include <iomanip>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace bs = bimanual_skills;
namespace sim = bimanual_skills::sim;
namespace rt = bimanual_skills::realtime;
namespace vision = bimanual_skills::vision;

namespace {

const std::string kUsage =
    std::string(
        "usage: rosrun bimanual_skills bullet_sim [_param:=value ...] [ROS remappings]\n"
        "\n"
        "The Bullet simulation of the bimanual WAM (two arms with their true plant, table, "
        "cloth) as a ROS node that hosts\n"
        "the arms' computed-torque controllers in its real-time loop, as a robot's driver "
        "would. Simulated time is\n"
        "published on /clock (set /use_sim_time true for the other nodes).\n"
        "\n"
        "Parameters (private, defaults in config/bullet_sim.yaml):\n"
        "  ~config               simulation file (default: the package's config/sim.yaml)\n"
        "  ~hosted_controllers   arms whose controller runs in this node's loop (default: "
        "all); each reads its\n"
        "                        parameters from ARM/ctc_controller/ (see below)\n"
        "  ~external_controllers arms commanded on ARM/effort_command by a separate "
        "controller (ctc_controller);\n"
        "                        lockstep waits for them (default: none)\n"
        "  ~lockstep             true: each step waits for one command of every external "
        "controller, so a run is\n"
        "                        repeatable bit for bit; false: free-running at "
        "~realtime_factor\n"
        "  ~lockstep_timeout     wall seconds a lockstep step waits before braking the "
        "missing arms (default 0.2)\n"
        "  ~realtime_factor      free-running speed, simulated s per wall s (default 1; 0: as "
        "fast as possible)\n"
        "  ~max_drift            wall seconds the loop may fall behind or run ahead before "
        "its schedule restarts (0.05)\n"
        "  ~loop_priority        SCHED_FIFO priority of the loop thread, 1-99 (0: "
        "unchanged, the default)\n"
        "  ~max_step_duration    most simulated seconds one ~step call may ask for (default "
        "60)\n"
        "  ~max_payload          heaviest ~set_payload [kg] (default 4, the WAM's rated "
        "payload)\n"
        "  ~max_force, ~max_torque  largest ~apply_wrench [N, N m] (default 200, 50)\n"
        "  ~command_timeout      simulated s after which an external command is stale: zero "
        "torque plus braking (0.05)\n"
        "  ~braking_damping      N m s/rad per joint applied when external commands are "
        "stale\n"
        "  ~initial_positions    map arm -> joint positions at start and after ~reset\n"
        "  ~marker_rate          cloth marker and ~cloth rate [Hz of simulated time] (default "
        "30)\n"
        "  ~camera_rate          top-down camera images per simulated second, at most marker_rate (default 30; 0: "
        "no camera)\n"
        "  ~camera_depth_noise, ~camera_colour_noise  the camera's noise: depth [m], colour "
        "[levels] (0.001, 2)\n"
        "  ~paused               start paused (default false)\n"
        "  ~statistics_file      at exit, write the loop's periods and the times its "
        "controllers took commands (CSV)\n"
        "\n"
        "Hosted controller parameters (ARM/ctc_controller/...):\n") +
    bs::ros_layer::kControllerParameterHelp +
    "\n"
    "Topics: publishes joint_states (sensor_msgs/JointState, every step; effort: the applied "
    "torque), /clock,\n"
    "  ~markers (cloth TRIANGLE_LIST and table), ~cloth (sensor_msgs/PointCloud2: the cloth's "
    "nodes, world frame,\n"
    "  the simulator's ground truth), camera/image_raw (bgr8), camera/depth/image_raw (32FC1 "
    "[m]) with\n"
    "  camera/camera_info and camera/depth/camera_info (the orthographic top-down camera of "
    "the fold's reward,\n"
    "  frame top_down_camera on /tf_static), /diagnostics (loop period, real-time factor, "
    "allocations per cycle);\n"
    "  subscribes ARM/effort_command (std_msgs/Float64MultiArray) for external controllers.\n"
    "  Each hosted controller serves ARM/command (trajectory_msgs/JointTrajectory), "
    "ARM/follow_joint_trajectory\n"
    "  (bimanual_skills/FollowJointTrajectory action), ARM/set_mode and publishes ARM/state, "
    "ARM/estimated_wrench,\n"
    "  ARM/tool_paths.\n"
    "Services: ~reset (std_srvs/Trigger), ~pause (std_srvs/SetBool), ~step "
    "(bimanual_skills/SimStep, bounded),\n"
    "  ~set_payload, ~apply_wrench (bounded), ~grasp (bimanual_skills/ClothGrasp: fails when "
    "no cloth node is in reach;\n"
    "  a stamp ahead is done by the loop in its first cycle at or after it).\n";

/// Wall seconds a service waits for the loop to take a request (the loop polls between cycles).
constexpr double kServiceWait = 5.0;

/// A torque command of an external controller, handed from the subscriber thread to the loop.
struct ExternalCommand {
  Eigen::VectorXd torque;
  bool well_formed = false;
};

/// One arm in the loop.
struct Arm {
  std::string name;
  std::vector<std::string> joint_names;
  int n = 0;
  sim::JointState state;
  Eigen::VectorXd torque, initial;
  std::unique_ptr<bs::ros_layer::ArmControllerInterface> controller;  ///< Hosted; null for an external one.
  std::uint64_t commands_taken = 0;                                   ///< By the hosted controller (loop side).
  // External controllers.
  bool external = false;
  std::unique_ptr<sim::TorqueCommandGate> gate;
  std::unique_ptr<rt::TripleBuffer<ExternalCommand>> commands;
  std::atomic<long> commands_received{0};
  long commands_answered = 0;  ///< Loop side: commands_received when the state was last published.
  bool braking = false;
  ros::Subscriber subscriber;
  // The gripper's scheduled command (loop side), and when the last one was done (for /diagnostics; −t − 1 when it
  // failed at t).
  double gripper_due = std::numeric_limits<double>::infinity();
  bool gripper_grasp = false;
  std::atomic<double> gripper_done_at{std::nan("")}, gripper_done_due{std::nan("")};
  std::atomic<std::uint64_t> gripper_done_count{0};  ///< Scheduled commands done (the publisher thread logs them).
};

/// What the loop hands to the publisher thread after a cycle.
struct Snapshot {
  double time = 0.0;
  Eigen::VectorXd position, velocity, effort;  ///< All arms, in joint-name order.
};

/// The cloth, handed to the scene thread at marker_rate.
struct ClothFrame {
  double time = 0.0;
  Eigen::Matrix3Xd vertices;
  bool image = false;  ///< The camera's images of this frame too, whatever the camera's rate (the end of a ~step).
};

constexpr const char* kCameraFrame = "top_down_camera";
constexpr double kNever = std::numeric_limits<double>::infinity();  ///< No gripper command scheduled.

/// A service request for the loop thread; the service thread waits for `done`.
struct Request {
  /// Runs on the loop thread; returns false when the loop finishes the request later (a ~step in progress).
  std::function<bool(const std::shared_ptr<Request>&)> run;
  std::promise<void> done;
  bool success = false;
  std::string message;
  double time = 0.0;
  int nodes = 0;
  std::uint32_t steps = 0, stepped = 0;  ///< ~step: asked and done.
};

class BulletSimNode {
 public:
  BulletSimNode(ros::NodeHandle& node, ros::NodeHandle& private_node) : node_(node) {
    bs::ros_layer::ParameterReader p(private_node, "bullet_sim");
    const std::string config_path = p.text("config", ros::package::getPath("bimanual_skills") + "/config/sim.yaml");
    simulation_ = std::make_unique<sim::BimanualSimulation>(sim::SimConfig::fromYamlFile(config_path));
    lockstep_ = p.boolean("lockstep", false);
    lockstep_timeout_ = p.number("lockstep_timeout", 0.2, 1e-3, 60.0);
    realtime_factor_ = p.number("realtime_factor", 1.0, 0.0, 1000.0);
    const double max_drift = p.number("max_drift", 0.05, 1e-3, 10.0);
    loop_priority_ = p.integer("loop_priority", 0, 0, 99);
    max_step_duration_ = p.number("max_step_duration", 60.0, simulation_->stepSize(), 86400.0);
    max_payload_ = p.number("max_payload", 4.0, 0.0, 1000.0);
    max_force_ = p.number("max_force", 200.0, 0.0, 1e9);
    max_torque_ = p.number("max_torque", 50.0, 0.0, 1e9);
    marker_rate_ = p.number("marker_rate", 30.0, 0.1, 1000.0);
    camera_rate_ = p.number("camera_rate", 30.0, 0.0, 1000.0);
    camera_noise_.depth_stddev = p.number("camera_depth_noise", camera_noise_.depth_stddev, 0.0, 1.0);
    camera_noise_.colour_stddev = p.number("camera_colour_noise", camera_noise_.colour_stddev, 0.0, 255.0);
    paused_ = p.boolean("paused", false);
    statistics_file_ = p.text("statistics_file", "");
    const double command_timeout = p.number("command_timeout", 0.05, 1e-4, 10.0);
    std::vector<std::string> all_arms;
    for (int a = 0; a < simulation_->armCount(); ++a) all_arms.push_back(simulation_->config().arms[a].name);
    const std::vector<std::string> external = p.texts("external_controllers", {});
    std::vector<std::string> hosted_default;
    for (const std::string& a : all_arms) {
      if (std::find(external.begin(), external.end(), a) == external.end()) hosted_default.push_back(a);
    }
    const std::vector<std::string> hosted = p.texts("hosted_controllers", hosted_default);
    for (const std::vector<std::string>* list : {&external, &hosted}) {
      for (const std::string& name : *list) {
        if (simulation_->armIndex(name) < 0) {
          throw std::invalid_argument("~hosted_controllers and ~external_controllers name an unknown arm '" + name +
                                      "'");
        }
      }
    }
    pacer_ = std::make_unique<rt::LoopPacer>(
        simulation_->stepSize() / (realtime_factor_ > 0.0 ? realtime_factor_ : 1.0), max_drift);
    std::string description;
    std::string description_key;
    if (!node.searchParam("robot_description", description_key) || !node.getParam(description_key, description)) {
      std::ifstream urdf(simulation_->config().urdf_path);
      description.assign(std::istreambuf_iterator<char>(urdf), std::istreambuf_iterator<char>());
    }
    const std::size_t arms = all_arms.size();
    arms_.reserve(arms);
    int total = 0;
    for (std::size_t a = 0; a < arms; ++a) {
      arms_.push_back(std::make_unique<Arm>());
      Arm& arm = *arms_.back();
      arm.name = all_arms[a];
      arm.n = simulation_->jointCount(static_cast<int>(a));
      arm.joint_names = simulation_->armModel(static_cast<int>(a)).jointNames();
      arm.state = sim::JointState(arm.n);
      arm.torque = Eigen::VectorXd::Zero(arm.n);
      arm.initial = simulation_->trueState(static_cast<int>(a)).q;
      const auto n = static_cast<std::size_t>(arm.n);
      if (p.has("initial_positions/" + arm.name)) {
        const auto q = p.numbers("initial_positions/" + arm.name, {}, n);
        arm.initial = Eigen::Map<const Eigen::VectorXd>(q.data(), arm.n);
      }
      const std::vector<double> damping = p.numbers("braking_damping", std::vector<double>(n, 10.0), n, 0.0, 1e4);
      arm.gate = std::make_unique<sim::TorqueCommandGate>(arm.n, command_timeout,
                                                          Eigen::Map<const Eigen::VectorXd>(damping.data(), arm.n));
      ExternalCommand initial;
      initial.torque = Eigen::VectorXd::Zero(arm.n);
      arm.commands = std::make_unique<rt::TripleBuffer<ExternalCommand>>(initial);
      arm.external = std::find(external.begin(), external.end(), arm.name) != external.end();
      if (std::find(hosted.begin(), hosted.end(), arm.name) != hosted.end()) {
        if (arm.external) throw std::invalid_argument("arm '" + arm.name + "' is both hosted and external");
        ros::NodeHandle arm_node(node, arm.name);
        bs::ros_layer::ParameterReader parameters(ros::NodeHandle(arm_node, "ctc_controller"),
                                                  "bullet_sim: " + arm.name + " controller");
        arm.controller = std::make_unique<bs::ros_layer::ArmControllerInterface>(
            arm_node, parameters, arm.name, description, "bullet_sim: " + arm.name + " controller");
        parameters.warnUnknown();
        if (arm.controller->jointNames() != arm.joint_names) {
          throw std::invalid_argument("the controller of '" + arm.name +
                                      "' does not drive the simulated arm's joints (check base_link and tip_link)");
        }
        const double rate = arm.controller->settings().config.observer.rate_hz;
        if (std::abs(rate * simulation_->stepSize() - 1.0) > 0.2) {
          ROS_WARN(
              "bullet_sim: %s: the observer's rate (%.0f Hz, %s) differs from the simulation's (%.0f Hz); it "
              "integrates the measured step, but its FIR cut-off was designed for %.0f Hz",
              arm.name.c_str(), rate, ros::NodeHandle(arm_node, "ctc_controller").resolveName("observer/rate").c_str(),
              1.0 / simulation_->stepSize(), rate);
        }
      }
      total += arm.n;
    }
    p.warnUnknown();
    resetSimulation();

    Snapshot initial_snapshot;
    initial_snapshot.position = initial_snapshot.velocity = initial_snapshot.effort = Eigen::VectorXd::Zero(total);
    snapshots_ = std::make_unique<rt::TripleBuffer<Snapshot>>(initial_snapshot);
    ClothFrame initial_frame;
    if (simulation_->hasCloth()) {
      initial_frame.vertices = simulation_->cloth().vertices();
      cloth_triangles_ = simulation_->cloth().triangles();
      if (camera_rate_ > 0.0) {
        vision::ClothRendererParameters camera = bs::tasks::rendererFor(simulation_->config());
        camera.noise = camera_noise_;
        renderer_ = std::make_unique<vision::ClothRenderer>(camera);
        camera_rng_.seed(simulation_->config().seed);
      }
    }
    cloth_frames_ = std::make_unique<rt::TripleBuffer<ClothFrame>>(initial_frame);
    for (const auto& arm : arms_) names_.insert(names_.end(), arm->joint_names.begin(), arm->joint_names.end());
    sem_init(&publish_signal_, 0, 0);
    sem_init(&scene_signal_, 0, 0);

    // External commands arrive on a queue and thread of their own and reach the loop through a triple buffer.
    for (std::size_t a = 0; a < arms_.size(); ++a) {
      Arm& arm = *arms_[a];
      if (arm.controller) continue;
      ros::SubscribeOptions options = ros::SubscribeOptions::create<std_msgs::Float64MultiArray>(
          arm.name + "/effort_command", 10,
          [this, &arm](const std_msgs::Float64MultiArray::ConstPtr& message) { onCommand(arm, *message); },
          ros::VoidPtr(), &command_queue_);
      options.transport_hints = ros::TransportHints().tcpNoDelay();
      arm.subscriber = node_.subscribe(options);
    }
    joint_state_publisher_ = node_.advertise<sensor_msgs::JointState>("joint_states", 10);
    clock_publisher_ = node_.advertise<rosgraph_msgs::Clock>("/clock", 10);
    marker_publisher_ = private_node.advertise<visualization_msgs::MarkerArray>("markers", 1, true);
    cloth_publisher_ = private_node.advertise<sensor_msgs::PointCloud2>("cloth", 1, true);
    if (renderer_) {
      image_publisher_ = node_.advertise<sensor_msgs::Image>("camera/image_raw", 1);
      info_publisher_ = node_.advertise<sensor_msgs::CameraInfo>("camera/camera_info", 1);
      depth_publisher_ = node_.advertise<sensor_msgs::Image>("camera/depth/image_raw", 1);
      depth_info_publisher_ = node_.advertise<sensor_msgs::CameraInfo>("camera/depth/camera_info", 1);
      camera_frame_.sendTransform(
          bs::ros_layer::cameraTransform(renderer_->parameters().camera, "world", kCameraFrame, ros::Time(0)));
    }
    diagnostics_publisher_ = node_.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
    services_.push_back(private_node.advertiseService("reset", &BulletSimNode::onReset, this));
    services_.push_back(private_node.advertiseService("pause", &BulletSimNode::onPause, this));
    services_.push_back(private_node.advertiseService("step", &BulletSimNode::onStep, this));
    services_.push_back(private_node.advertiseService("set_payload", &BulletSimNode::onSetPayload, this));
    services_.push_back(private_node.advertiseService("apply_wrench", &BulletSimNode::onApplyWrench, this));
    services_.push_back(private_node.advertiseService("grasp", &BulletSimNode::onGrasp, this));
    diagnostics_timer_ = node_.createSteadyTimer(ros::WallDuration(1.0), &BulletSimNode::onDiagnostics, this);
    std::string hosted_list, external_list;
    for (const auto& arm : arms_) (arm->controller ? hosted_list : external_list) += " " + arm->name;
    ROS_INFO("bullet_sim: %zu arms, step %.4f s, cloth %s, %s%s; hosted controllers:%s; external:%s", arms_.size(),
             simulation_->stepSize(), simulation_->hasCloth() ? "on" : "off", lockstep_ ? "lockstep" : "free-running",
             paused_ ? ", paused" : "", hosted_list.empty() ? " none" : hosted_list.c_str(),
             external_list.empty() ? " none" : external_list.c_str());
  }

  ~BulletSimNode() {
    sem_destroy(&publish_signal_);
    sem_destroy(&scene_signal_);
  }

  /// Runs the loop on the calling thread until shutdown; services and topics on other threads.
  void run() {
    ros::AsyncSpinner services(3);  // services, the controllers' topics, actions and timers, diagnostics
    ros::AsyncSpinner commands(1, &command_queue_);
    services.start();
    commands.start();
    std::thread publisher([this] { publishLoop(); });
    std::thread scene([this] { sceneLoop(); });
    if (loop_priority_ > 0) {
      const char* error = rt::requestRealtimeScheduling(loop_priority_);
      if (*error == '\0') {
        ROS_INFO("bullet_sim: loop thread at SCHED_FIFO priority %d", loop_priority_);
      } else {
        ROS_WARN("bullet_sim: ~loop_priority %d not granted (%s); the loop runs at normal priority", loop_priority_,
                 error);
      }
    }
    publishState(true);
    loop();
    running_ = false;
    sem_post(&publish_signal_);
    sem_post(&scene_signal_);
    publisher.join();
    scene.join();
    for (auto& request : takeRequests()) finish(*request, "the simulation is shutting down");
    interruptStepping("the simulation is shutting down");
    if (!statistics_file_.empty()) writeStatistics();
  }

 private:
  // ---------------------------------------------------------------- the loop thread
  void loop() {
    bool consecutive = false;  ///< The previous cycle was paced and not interrupted: its period counts.
    double last_start = 0.0;
    while (ros::ok()) {
      for (auto& request : takeRequests()) {
        if (request->run(request)) request->done.set_value();
      }
      const bool stepping = stepping_ != nullptr;
      if (!diverged_ && (!paused_ || stepping)) gripperDue(simulation_->time());
      if (diverged_ || (paused_ && !stepping)) {
        for (auto& arm : arms_) {
          if (!arm->controller) continue;
          if (!diverged_) {
            arm->controller->realtime().idle();  // paused: goals still reach the loop (and are accepted)
          } else if (!divergence_told_) {
            arm->controller->loopStopped("the simulation diverged");
          }
        }
        divergence_told_ = diverged_;
        if (diverged_ && bimanual_skills::realtime::monotonicSeconds() > next_diverged_publish_) {
          next_diverged_publish_ = bimanual_skills::realtime::monotonicSeconds() + 0.1;
          publishState(false);  // the last valid states keep coming, stamp frozen; /diagnostics says why
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        pacer_->reanchor();
        consecutive = false;
        continue;
      }
      const bool paced = !stepping && realtime_factor_ > 0.0 && !lockstep_;
      if (paced && !pacer_->waitUntilDue(0.005)) continue;  // short slices: requests are served meanwhile
      const double start = bimanual_skills::realtime::monotonicSeconds();
      if (paced && consecutive) periods_.record(start - last_start);
      last_start = start;
      cycle();
      cycle_times_.record(bimanual_skills::realtime::monotonicSeconds() - start);
      if (paced) {
        const long slips = pacer_->slips();
        pacer_->advance();
        consecutive = pacer_->slips() == slips;
      } else {
        pacer_->reanchor();
        consecutive = false;
      }
      if (stepping_ && (++stepping_->stepped == stepping_->steps || diverged_)) {
        stepping_->success = !diverged_;
        stepping_->message = "stepped " + std::to_string(stepping_->stepped) + " of " +
                             std::to_string(stepping_->steps) + (diverged_ ? ": the simulation diverged" : "");
        stepping_->time = simulation_->time();
        // The state, the cloth and the camera's images where the steps ended: a client that stepped to a moment
        // observes that moment (the clock stands still there).
        for (std::size_t a = 0; a < arms_.size(); ++a)
          simulation_->readJointState(static_cast<int>(a), arms_[a]->state);
        publishState(true, true);
        stepping_->done.set_value();
        stepping_.reset();
        pacer_->reanchor();
      }
    }
  }

  /// One cycle: read, publish, (lockstep: wait), control, write, step. The control part is allocation-free (counted
  /// apart from the physics step, in which Bullet's soft body allocates).
  void cycle() {
    std::optional<bs::testing::AllocationCounter> allocations(std::in_place);
    const double t = simulation_->time();
    for (std::size_t a = 0; a < arms_.size(); ++a) {
      Arm& arm = *arms_[a];
      simulation_->readJointState(static_cast<int>(a), arm.state);
      arm.commands_answered = arm.commands_received.load(std::memory_order_acquire);
    }
    publishState(false);
    if (lockstep_) waitForExternalCommands();
    for (std::size_t a = 0; a < arms_.size(); ++a) {
      Arm& arm = *arms_[a];
      if (arm.controller) {
        const auto status = arm.controller->realtime().update(t, t, arm.state.position, arm.state.velocity,
                                                              arm.state.effort, arm.torque);
        if (status == bs::control::ControllerStatus::InvalidState ||
            status == bs::control::ControllerStatus::StaleState) {
          arm.torque.setZero();
        }
        if (arm.controller->realtime().commandsTaken() != arm.commands_taken) {
          arm.commands_taken = arm.controller->realtime().commandsTaken();
          command_times_.record(arm.controller->realtime().lastCommandTaken());
        }
      } else {
        if (const ExternalCommand* command = arm.commands->readNew()) {
          if (command->well_formed) {
            if (arm.gate->accept(t, command->torque) != sim::RobotStatus::Ok) ++rejected_commands_;
          } else {
            ++rejected_commands_;
          }
        }
        arm.braking = arm.gate->torque(t, arm.state.velocity, arm.torque);
      }
      simulation_->writeJointTorques(static_cast<int>(a), arm.torque);
    }
    const std::size_t control_allocations = allocations->allocations();
    allocations.reset();
    allocations.emplace();
    const sim::SimStatus status = simulation_->step();
    time_.store(simulation_->time(), std::memory_order_relaxed);
    if (status == sim::SimStatus::ArmDiverged) {
      divergence_time_ = simulation_->time();
      diverged_ = true;
    }
    cloth_diverged_ = status == sim::SimStatus::ClothDiverged;
    if (cloth_diverged_) cloth_divergence_.store(static_cast<int>(simulation_->cloth().divergence()));
    const std::size_t physics_allocations = allocations->allocations();
    if (control_allocations > 0) {
      control_allocation_cycles_.fetch_add(1, std::memory_order_relaxed);
      control_allocations_.fetch_add(static_cast<long>(control_allocations), std::memory_order_relaxed);
    }
    if (physics_allocations > 0) physics_allocation_cycles_.fetch_add(1, std::memory_order_relaxed);
    cycles_.fetch_add(1, std::memory_order_relaxed);
  }

  /// Lockstep: waits (wall clock, bounded) until every external controller answered the published state.
  void waitForExternalCommands() {
    const double deadline = bimanual_skills::realtime::monotonicSeconds() + lockstep_timeout_;
    for (;;) {
      bool all = true;
      for (const auto& arm : arms_) {
        all =
            all && (!arm->external || arm->commands_received.load(std::memory_order_acquire) > arm->commands_answered);
      }
      if (all || !ros::ok() || bimanual_skills::realtime::monotonicSeconds() > deadline) {
        if (!all) ++lockstep_timeouts_;
        return;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(50));
    }
  }

  /// Hands the joint states to the publisher thread, and at marker_rate the cloth to the scene thread.
  void publishState(bool force_cloth, bool force_image = false) {
    Snapshot& s = snapshots_->writeSlot();
    s.time = diverged_ ? divergence_time_ : simulation_->time();
    published_time_ = s.time;
    if (!diverged_) {
      Eigen::Index offset = 0;
      for (const auto& arm : arms_) {
        s.position.segment(offset, arm->n) = arm->state.position;
        s.velocity.segment(offset, arm->n) = arm->state.velocity;
        s.effort.segment(offset, arm->n) = arm->state.effort;
        offset += arm->n;
      }
    }
    snapshots_->publish();
    sem_post(&publish_signal_);
    if (simulation_->hasCloth() && (force_cloth || simulation_->time() >= next_marker_time_)) {
      ClothFrame& frame = cloth_frames_->writeSlot();
      frame.time = s.time;
      frame.vertices = simulation_->cloth().vertices();
      frame.image = force_image;
      cloth_frames_->publish();
      sem_post(&scene_signal_);
      next_marker_time_ = simulation_->time() + 1.0 / marker_rate_;
    }
  }

  void resetSimulation() {
    std::vector<sim::ArmState> state;
    for (const auto& arm : arms_) state.push_back({arm->initial, Eigen::VectorXd::Zero(arm->initial.size())});
    const sim::SimStatus status = simulation_->reset(state);
    simulation_->setRandomGenerator(std::mt19937(simulation_->config().seed));
    if (status != sim::SimStatus::Ok) {
      throw std::invalid_argument(std::string("initial positions rejected: ") + sim::toString(status));
    }
    for (std::size_t a = 0; a < arms_.size(); ++a) {
      arms_[a]->gate->clear();
      arms_[a]->gripper_due = kNever;  // scheduled on the old clock
      simulation_->readJointState(static_cast<int>(a), arms_[a]->state);
    }
    diverged_ = false;
    cloth_diverged_ = false;
    next_marker_time_ = 0.0;
    published_time_ = 0.0;
    time_.store(0.0);
    pacer_->reanchor();
  }

  /// The loop's periods [s], the times [monotonic s] its controllers took commands, and its allocation counts.
  void writeStatistics() const {
    std::ofstream out(statistics_file_);
    out << "series,value\n";
    periods_.writeCsv(out, "period");
    cycle_times_.writeCsv(out, "cycle_time");
    command_times_.writeCsv(out, "command_taken");
    out << "cycles," << cycles_.load() << "\ncontrol_allocations," << control_allocations_.load()
        << "\ncontrol_cycles_that_allocated," << control_allocation_cycles_.load() << "\nphysics_steps_that_allocated,"
        << physics_allocation_cycles_.load() << '\n';
    if (!out) ROS_ERROR("bullet_sim: cannot write %s", statistics_file_.c_str());
  }

  // ---------------------------------------------------------------- other threads
  void onCommand(Arm& arm, const std_msgs::Float64MultiArray& message) {
    ExternalCommand& command = arm.commands->writeSlot();
    command.well_formed = static_cast<int>(message.data.size()) == arm.n;
    if (command.well_formed) {
      command.torque = Eigen::Map<const Eigen::VectorXd>(message.data.data(), arm.n);
    } else {
      ROS_WARN_THROTTLE(1.0, "bullet_sim: %s/effort_command rejected: %zu values for %d joints", arm.name.c_str(),
                        message.data.size(), arm.n);
    }
    arm.commands->publish();
    arm.commands_received.fetch_add(1, std::memory_order_release);  // answered, even wrongly: lockstep goes on
  }

  /// Waits for the loop's signal, at most 0.1 s (so that a stopping node is seen).
  static void waitForSignal(sem_t& signal) {
    timespec deadline{};
    clock_gettime(CLOCK_REALTIME, &deadline);
    deadline.tv_nsec += 100000000;
    if (deadline.tv_nsec >= 1000000000) deadline.tv_nsec -= 1000000000, ++deadline.tv_sec;
    sem_timedwait(&signal, &deadline);
  }

  /// Publishes what the loop handed over: /clock first, so the controllers' clocks move before the states.
  void publishLoop() {
    sensor_msgs::JointState states;
    states.name = names_;
    std::vector<std::uint64_t> grippers_done(arms_.size(), 0);
    while (running_ && ros::ok()) {
      waitForSignal(publish_signal_);
      logGripperCommands(grippers_done);
      const Snapshot* s = snapshots_->readNew();
      if (!s) continue;
      const ros::Time stamp(s->time);
      rosgraph_msgs::Clock clock;
      clock.clock = stamp;
      clock_publisher_.publish(clock);
      states.header.stamp = stamp;
      states.position.assign(s->position.data(), s->position.data() + s->position.size());
      states.velocity.assign(s->velocity.data(), s->velocity.data() + s->velocity.size());
      states.effort.assign(s->effort.data(), s->effort.data() + s->effort.size());
      joint_state_publisher_.publish(states);
    }
  }

  /// Publisher thread: logs the scheduled gripper commands the loop did since the last call.
  void logGripperCommands(std::vector<std::uint64_t>& done) {
    for (std::size_t a = 0; a < arms_.size(); ++a) {
      const Arm& arm = *arms_[a];
      const std::uint64_t count = arm.gripper_done_count.load(std::memory_order_acquire);
      if (count == done[a]) continue;
      done[a] = count;
      const double at = arm.gripper_done_at.load(std::memory_order_relaxed);
      ROS_INFO("bullet_sim: %s's scheduled gripper command %s at t = %.6f s, scheduled for t = %.6f s",
               arm.name.c_str(), at >= 0.0 ? "done" : "failed", at >= 0.0 ? at : -at - 1.0,
               arm.gripper_done_due.load(std::memory_order_relaxed));
    }
  }

  /// Publishes what the loop handed over of the cloth: the markers, ~cloth, and at camera_rate the camera's images.
  void sceneLoop() {
    bool first = true;
    double next_image = 0.0, last_time = 0.0;
    while (running_ && ros::ok()) {
      waitForSignal(scene_signal_);
      const ClothFrame* frame = cloth_frames_->readNew();
      if (!frame && !first) continue;
      if (!frame) frame = &cloth_frames_->current();
      const ros::Time stamp(frame->time);
      // The table each time too: the topic is latched, and a late subscriber gets only the last message. Stamped
      // 0 (the latest transform): rviz drops markers stamped before a reset's jump back in time.
      visualization_msgs::MarkerArray markers;
      if (simulation_->config().has_table) {
        markers.markers.push_back(bs::nodes::tableMarker(simulation_->config().table, ros::Time()));
      }
      first = false;
      if (!simulation_->hasCloth()) {
        marker_publisher_.publish(markers);
        continue;
      }
      markers.markers.push_back(bs::nodes::clothMarker(frame->vertices, cloth_triangles_, ros::Time()));
      marker_publisher_.publish(markers);
      cloth_publisher_.publish(clothCloud(frame->vertices, stamp));
      // An image every 1/camera_rate simulated seconds, and at once after a reset (time going back).
      if (renderer_ && (frame->image || frame->time >= next_image - 1e-9 || frame->time < last_time)) {
        publishImages(*frame);
        next_image = frame->time + 1.0 / camera_rate_;
      }
      last_time = frame->time;
    }
  }

  /// The cloth's nodes (world frame) as a point cloud, in the simulation's node order.
  static sensor_msgs::PointCloud2 clothCloud(const Eigen::Matrix3Xd& vertices, const ros::Time& stamp) {
    sensor_msgs::PointCloud2 cloud;
    cloud.header.stamp = stamp;
    cloud.header.frame_id = "world";
    sensor_msgs::PointCloud2Modifier modifier(cloud);
    modifier.setPointCloud2FieldsByString(1, "xyz");
    modifier.resize(static_cast<std::size_t>(vertices.cols()));
    sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z");
    for (Eigen::Index i = 0; i < vertices.cols(); ++i, ++x, ++y, ++z) {
      *x = static_cast<float>(vertices(0, i));
      *y = static_cast<float>(vertices(1, i));
      *z = static_cast<float>(vertices(2, i));
    }
    return cloud;
  }

  /// The top-down camera's colour and depth images of `frame`, with noise, and their camera_info.
  void publishImages(const ClothFrame& frame) {
    if (renderer_->render(frame.vertices, cloth_triangles_, camera_rng_) != vision::VisionStatus::Ok) return;
    std_msgs::Header header;
    header.stamp = ros::Time(frame.time);
    header.frame_id = kCameraFrame;
    const sensor_msgs::CameraInfo info = bs::ros_layer::cameraInfo(renderer_->parameters().camera, header);
    image_publisher_.publish(cv_bridge::CvImage(header, "bgr8", renderer_->bgr()).toImageMsg());
    info_publisher_.publish(info);
    depth_publisher_.publish(cv_bridge::CvImage(header, "32FC1", renderer_->depth()).toImageMsg());
    depth_info_publisher_.publish(info);
  }

  std::vector<std::shared_ptr<Request>> takeRequests() {
    std::vector<std::shared_ptr<Request>> taken;
    std::unique_lock<std::mutex> lock(requests_mutex_, std::try_to_lock);
    if (!lock.owns_lock() || requests_.empty()) return taken;
    taken.assign(requests_.begin(), requests_.end());
    requests_.clear();
    return taken;
  }

  static void finish(Request& request, const std::string& why = "") {
    if (!why.empty()) {
      request.success = false;
      request.message = why;
    }
    request.done.set_value();
  }

  /// Runs `run` on the loop thread between two cycles and waits for it: at most kServiceWait for the loop to take
  /// it, then until the loop finishes it (a ~step: bounded by ~max_step_duration) or the node shuts down.
  std::shared_ptr<Request> submit(std::function<bool(const std::shared_ptr<Request>&)> run) {
    auto request = std::make_shared<Request>();
    request->run = std::move(run);
    std::future<void> done = request->done.get_future();
    {
      const std::lock_guard<std::mutex> lock(requests_mutex_);
      requests_.push_back(request);
    }
    const auto taken = std::chrono::steady_clock::now() + std::chrono::duration<double>(kServiceWait);
    while (done.wait_for(std::chrono::milliseconds(20)) != std::future_status::ready) {
      bool queued = false;
      {
        const std::lock_guard<std::mutex> lock(requests_mutex_);
        queued = std::find(requests_.begin(), requests_.end(), request) != requests_.end();
        if (queued && (!ros::ok() || std::chrono::steady_clock::now() > taken)) {
          requests_.erase(std::find(requests_.begin(), requests_.end(), request));
          request->message =
              ros::ok() ? "the simulation loop did not take the request within " + std::to_string(kServiceWait) + " s"
                        : "the simulation is shutting down";
          return request;
        }
      }
    }
    return request;
  }

  /// Ends a ~step in progress (loop thread) with `why`.
  void interruptStepping(const std::string& why) {
    if (!stepping_) return;
    stepping_->success = false;
    stepping_->message = "interrupted after " + std::to_string(stepping_->stepped) + " of " +
                         std::to_string(stepping_->steps) + " steps: " + why;
    stepping_->time = simulation_->time();
    stepping_->done.set_value();
    stepping_.reset();
  }

  bool onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    const auto r = submit([this](const std::shared_ptr<Request>& request) {
      interruptStepping("~reset");
      resetSimulation();
      publishState(true);
      request->success = true;
      request->message = "reset to the initial positions at t = 0 (sensor noise reseeded)";
      return true;
    });
    response.success = r->success;
    response.message = r->message;
    ROS_INFO("bullet_sim: %s", response.message.c_str());
    return true;
  }

  bool onPause(std_srvs::SetBool::Request& request, std_srvs::SetBool::Response& response) {
    const bool pause = request.data;
    const auto r = submit([this, pause](const std::shared_ptr<Request>& req) {
      if (!pause) interruptStepping("the simulation was resumed");
      paused_ = pause;
      pacer_->reanchor();
      req->success = true;
      std::ostringstream message;
      // The time of the last states and /clock published (a cycle publishes, then steps), to the microsecond: a
      // client may read it back (ros_layer::FoldOnRobotTask waits for its clock to get there).
      message << (pause ? "paused" : "running") << " at t = " << std::fixed << std::setprecision(6) << published_time_
              << " s";
      req->message = message.str();
      return true;
    });
    response.success = r->success;
    response.message = r->message;
    return true;
  }

  bool onStep(bimanual_skills::SimStep::Request& request, bimanual_skills::SimStep::Response& response) {
    const double duration = request.steps * simulation_->stepSize();
    if (duration > max_step_duration_ + 1e-9) {
      std::ostringstream message;
      message << "refused: " << request.steps << " steps are " << duration << " s of simulated time; ~max_step_duration"
              << " allows " << max_step_duration_ << " s ("
              << static_cast<long>(max_step_duration_ / simulation_->stepSize()) << " steps) per call";
      response.message = message.str();
      response.time = time_.load();
      return true;
    }
    const std::uint32_t steps = request.steps;
    const auto r = submit([this, steps](const std::shared_ptr<Request>& req) {
      req->time = simulation_->time();
      if (!paused_) {
        req->message = "the simulation is running; pause it first (~pause true)";
      } else if (diverged_) {
        req->message = "the simulation diverged; call ~reset";
      } else if (stepping_) {
        req->message = "another ~step call is running";
      } else if (steps == 0) {
        req->success = true;
        req->message = "stepped 0 of 0";
      } else {
        req->steps = steps;  // the loop steps it, one step per cycle, serving other requests in between
        stepping_ = req;
        return false;
      }
      return true;
    });
    response.success = r->success;
    response.message = r->message;
    response.time = r->time;
    return true;
  }

  int armOf(const std::string& name, std::string& message) const {
    const int a = simulation_->armIndex(name);
    if (a < 0) {
      message = "unknown arm '" + name + "'; arms:";
      for (const auto& arm : arms_) message += " " + arm->name;
    }
    return a;
  }

  bool onSetPayload(bimanual_skills::SetPayload::Request& request, bimanual_skills::SetPayload::Response& response) {
    const int a = armOf(request.arm, response.message);
    if (a < 0) return true;
    bs::dynamics::Payload payload;
    payload.mass = request.mass;
    payload.com = Eigen::Vector3d(request.center_of_mass.x, request.center_of_mass.y, request.center_of_mass.z);
    if (!std::isfinite(payload.mass) || payload.mass < 0.0 || payload.mass > max_payload_) {
      std::ostringstream message;
      message << "rejected: mass " << payload.mass << " kg; it must lie in [0, " << max_payload_
              << "] kg (~max_payload; the WAM's rated payload is 4 kg)";
      response.message = message.str();
      return true;
    }
    if (!payload.com.allFinite() || payload.com.norm() > 1.0) {
      response.message = "rejected: the centre of mass must be finite and within 1 m of the tool";
      return true;
    }
    const auto r = submit([this, a, payload](const std::shared_ptr<Request>& req) {
      const sim::SimStatus status = simulation_->setPayload(a, payload);
      req->success = status == sim::SimStatus::Ok;
      req->message = req->success ? "payload of " + std::to_string(payload.mass) + " kg on " + arms_[a]->name
                                  : std::string("rejected: ") + sim::toString(status);
      return true;
    });
    response.success = r->success;
    response.message = r->message;
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
    const Eigen::Vector3d force(w.force.x, w.force.y, w.force.z), torque(w.torque.x, w.torque.y, w.torque.z);
    const Eigen::Vector3d point(request.point.x, request.point.y, request.point.z);
    if (!force.allFinite() || !torque.allFinite() || !point.allFinite() || force.norm() > max_force_ ||
        torque.norm() > max_torque_ || point.norm() > 1.0) {
      std::ostringstream message;
      message << "rejected: |force| " << force.norm() << " N, |torque| " << torque.norm() << " N m, point "
              << point.norm() << " m from the link; limits " << max_force_ << " N (~max_force), " << max_torque_
              << " N m (~max_torque), 1 m";
      response.message = message.str();
      return true;
    }
    const std::string name = request.link;
    const auto r = submit([this, link, force, torque, point, name](const std::shared_ptr<Request>& req) {
      const sim::SimStatus status = simulation_->setExternalWrench(link, force, torque, point);
      req->success = status == sim::SimStatus::Ok;
      req->message = req->success ? "wrench applied on " + name : std::string("rejected: ") + sim::toString(status);
      return true;
    });
    response.success = r->success;
    response.message = r->message;
    return true;
  }

  bool onGrasp(bimanual_skills::ClothGrasp::Request& request, bimanual_skills::ClothGrasp::Response& response) {
    const int a = armOf(request.arm, response.message);
    if (a < 0) return true;
    const bool grasp = request.grasp;
    const std::string arm = request.arm;
    const double at = request.stamp.toSec();
    const auto r = submit([this, a, grasp, arm, at](const std::shared_ptr<Request>& req) {
      if (at > simulation_->time()) {  // ahead: the loop does it at its time (gripperDue)
        Arm& held = *arms_[static_cast<std::size_t>(a)];
        held.gripper_due = at;
        held.gripper_grasp = grasp;
        req->success = true;
        req->time = at;
        std::ostringstream message;
        message << arm << (grasp ? " grasp" : " release") << " scheduled at t = " << std::fixed << std::setprecision(6)
                << at << " s";
        req->message = message.str();
        return true;
      }
      arms_[static_cast<std::size_t>(a)]->gripper_due = kNever;  // done now: one scheduled before is replaced
      req->time = simulation_->time();
      int attached = 0;
      const sim::SimStatus status = grasp ? simulation_->grasp(a, &attached) : simulation_->release(a);
      req->nodes = attached;
      if (status != sim::SimStatus::Ok) {
        req->message = std::string("failed: ") + sim::toString(status);
      } else if (grasp && attached == 0) {
        std::ostringstream message;
        message << arm << " grasped nothing: no free cloth node within " << simulation_->config().grasp_radius
                << " m of its tool";
        req->message = message.str();
      } else {
        req->success = true;
        req->message =
            grasp ? arm + " grasped " + std::to_string(attached) + " cloth nodes" : arm + " released the cloth";
      }
      return true;
    });
    response.success = r->success;
    response.nodes = r->nodes;
    response.message = r->message;
    response.executed = ros::Time(std::max(0.0, r->time));
    ROS_INFO("bullet_sim: %s", response.message.c_str());
    return true;
  }

  /// Loop thread, at the start of a cycle: the grippers' scheduled commands that are due at time t.
  void gripperDue(double t) {
    for (std::size_t a = 0; a < arms_.size(); ++a) {
      Arm& arm = *arms_[a];
      if (!(t >= arm.gripper_due)) continue;
      int attached = 0;
      const sim::SimStatus status = arm.gripper_grasp ? simulation_->grasp(static_cast<int>(a), &attached)
                                                      : simulation_->release(static_cast<int>(a));
      arm.gripper_done_at.store(status == sim::SimStatus::Ok ? t : -t - 1.0, std::memory_order_relaxed);
      arm.gripper_done_due.store(arm.gripper_due, std::memory_order_relaxed);
      arm.gripper_done_count.fetch_add(1, std::memory_order_release);
      arm.gripper_due = kNever;
    }
  }

  void onDiagnostics(const ros::SteadyTimerEvent&) {
    diagnostic_msgs::DiagnosticArray array;
    array.header.stamp = ros::Time::now();
    diagnostic_msgs::DiagnosticStatus status;
    status.name = "bullet_sim";
    status.hardware_id = "bullet_sim";
    const auto add = [&status](const std::string& key, const std::string& value) {
      diagnostic_msgs::KeyValue kv;
      kv.key = key;
      kv.value = value;
      status.values.push_back(kv);
    };
    const double now = bimanual_skills::realtime::monotonicSeconds(), t = time_.load(std::memory_order_relaxed);
    const double factor =
        last_diagnostics_wall_ > 0.0 ? (t - last_diagnostics_time_) / (now - last_diagnostics_wall_) : 0.0;
    last_diagnostics_wall_ = now;
    last_diagnostics_time_ = t;
    std::ostringstream message;
    if (diverged_) {
      status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
      message << "an arm diverged at t = " << divergence_time_
              << " s (a state became non-finite or faster than 100 rad/s): stopped until ~reset";
    } else if (cloth_diverged_) {
      status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
      message << "the cloth diverged (" << sim::toString(static_cast<sim::ClothDivergence>(cloth_divergence_.load()))
              << "): it is frozen until ~reset";
    } else {
      status.level = diagnostic_msgs::DiagnosticStatus::OK;
      message << (paused_ ? "paused" : lockstep_ ? "lockstep" : "free-running") << ", t = " << t << " s";
    }
    status.message = message.str();
    std::vector<double> periods;
    periods_.snapshot(periods);
    const std::size_t recent = std::min<std::size_t>(periods.size(), 1000);
    std::vector<double> last(periods.end() - static_cast<std::ptrdiff_t>(recent), periods.end());
    const rt::PeriodSummary summary = rt::summarize(last);
    add("simulated_time_s", std::to_string(t));
    add("realtime_factor_target", std::to_string(realtime_factor_));
    add("realtime_factor_last_second", std::to_string(factor));
    add("loop_period_median_s", std::to_string(summary.median));
    add("loop_period_p99_s", std::to_string(summary.p99));
    add("loop_period_max_s", std::to_string(summary.max));
    add("loop_schedule_restarts", std::to_string(pacer_->slips()));
    add("cycles", std::to_string(cycles_.load()));
    add("control_allocations", std::to_string(control_allocations_.load()));
    add("control_cycles_that_allocated", std::to_string(control_allocation_cycles_.load()));
    add("physics_steps_that_allocated", std::to_string(physics_allocation_cycles_.load()));
    add("rejected_external_commands", std::to_string(rejected_commands_.load()));
    add("lockstep_timeouts", std::to_string(lockstep_timeouts_.load()));
    for (const auto& arm : arms_) {
      const double done = arm->gripper_done_at.load(std::memory_order_relaxed);
      if (std::isnan(done)) continue;
      std::ostringstream at;
      at << std::fixed << std::setprecision(6) << (done >= 0.0 ? done : -done - 1.0)
         << (done >= 0.0 ? "" : " (failed)");
      add(arm->name + "_gripper_scheduled_done_at", at.str());
    }
    array.status.push_back(status);
    diagnostics_publisher_.publish(array);
  }

  ros::NodeHandle& node_;
  std::unique_ptr<sim::BimanualSimulation> simulation_;
  std::vector<std::unique_ptr<Arm>> arms_;
  std::vector<std::string> names_;
  std::unique_ptr<rt::LoopPacer> pacer_;
  std::unique_ptr<rt::TripleBuffer<Snapshot>> snapshots_;
  sem_t publish_signal_{}, scene_signal_{};
  std::unique_ptr<rt::TripleBuffer<ClothFrame>> cloth_frames_;
  std::unique_ptr<vision::ClothRenderer> renderer_;  ///< The top-down camera (scene thread); null without one.
  vision::RenderNoise camera_noise_;
  std::mt19937 camera_rng_;
  tf2_ros::StaticTransformBroadcaster camera_frame_;
  rt::PeriodRecorder periods_{200000}, cycle_times_{200000}, command_times_{10000};
  std::string statistics_file_;
  ros::CallbackQueue command_queue_;
  ros::Publisher joint_state_publisher_, clock_publisher_, marker_publisher_, diagnostics_publisher_, cloth_publisher_,
      image_publisher_, info_publisher_, depth_publisher_, depth_info_publisher_;
  std::vector<ros::ServiceServer> services_;
  ros::SteadyTimer diagnostics_timer_;
  std::mutex requests_mutex_;
  std::deque<std::shared_ptr<Request>> requests_;
  std::shared_ptr<Request> stepping_;  ///< Loop thread only.
  // Settings.
  bool lockstep_ = false;
  double lockstep_timeout_ = 0.2, realtime_factor_ = 1.0, marker_rate_ = 30.0, camera_rate_ = 30.0;
  double max_step_duration_ = 60.0, max_payload_ = 4.0, max_force_ = 200.0, max_torque_ = 50.0;
  int loop_priority_ = 0;
  // Loop state (written by the loop; flags read by diagnostics).
  std::atomic<bool> paused_{false}, diverged_{false}, cloth_diverged_{false}, running_{true};
  bool divergence_told_ = false;  ///< Loop side: the controllers were told the loop stopped for the divergence.
  std::atomic<double> time_{0.0};
  std::atomic<int> cloth_divergence_{0};
  Eigen::Matrix3Xi cloth_triangles_;  ///< Constant; copied for the publisher thread.
  double divergence_time_ = 0.0, next_marker_time_ = 0.0, next_diverged_publish_ = 0.0;
  double published_time_ = 0.0;  ///< Of the last states handed to the publisher (loop thread only).
  std::atomic<long> cycles_{0}, control_allocation_cycles_{0}, control_allocations_{0}, physics_allocation_cycles_{0};
  std::atomic<long> rejected_commands_{0}, lockstep_timeouts_{0};
  double last_diagnostics_wall_ = 0.0, last_diagnostics_time_ = 0.0;
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
