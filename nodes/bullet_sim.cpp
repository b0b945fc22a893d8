// bullet_sim: the Bullet simulation of the bimanual WAM (sim::BimanualSimulation) as a ROS node, hosting the arms'
// controllers the way a robot's driver hosts them: the simulation is the robot of a hosting::ControlLoop, which
// runs on the main thread (read, hand out, control, write, step the physics, paced on the wall clock or in lockstep);
// publishing runs on threads of its own (sim_publishing.hpp), services, topics and the controllers' ROS interfaces
// on spinner threads that reach the loop only through lock-free handoffs and the loop's request mailbox.
#include "bimanual_skills/ApplyWrench.h"
#include "bimanual_skills/ClothGrasp.h"
#include "bimanual_skills/JointEffortCommand.h"
#include "bimanual_skills/SetPayload.h"
#include "bimanual_skills/SimStep.h"
#include "bimanual_skills/hosting/control_loop.hpp"
#include "bimanual_skills/hosting/simulated_robot.hpp"
#include "bimanual_skills/ros_layer/arm_controller_interface.hpp"
#include "bimanual_skills/ros_layer/hosted_loop.hpp"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/ros_layer/queue_spinner.hpp"
#include "bimanual_skills/sim/bimanual_simulation.hpp"
#include "bimanual_skills/sim/robot_file.hpp"
#include "bimanual_skills/tasks/fold_reward.hpp"
#include "cli/pinned_numerics.hpp"
#include "io/whole_file.hpp"
#include "node_cli.hpp"
#include "sim_publishing.hpp"
#include "testing/allocation_counter.hpp"

#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PointStamped.h>
#include <ros/callback_queue.h>
#include <ros/package.h>
#include <ros/ros.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>

#include <sched.h>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace bs = bimanual_skills;
namespace sim = bimanual_skills::sim;

namespace {

const std::string kUsage =
    std::string(
        "usage: rosrun bimanual_skills bullet_sim [_param:=value ...] [ROS remappings]\n\n"
        "The Bullet simulation of the bimanual WAM (two arms with their true plant, table, cloth) as a ROS node that\n"
        "hosts the arms' computed-torque controllers in its real-time loop (hosting::ControlLoop), as a robot's\n"
        "driver would. Simulated time is published on /clock (set /use_sim_time true for the other nodes).\n\n"
        "Parameters (private, defaults in config/bullet_sim.yaml):\n"
        "  ~config               simulation file (default: the package's config/sim.yaml)\n"
        "  ~robot                robot file (default: the simulation file's): arms, URDF, plant, start, braking,\n"
        "                        payload, and the controllers' chains, gains and friction by default\n"
        "  ~hosted_controllers   arms whose controller runs in this node's loop (default: all); each reads its\n"
        "                        parameters from ARM/ctc_controller/ (see below)\n"
        "  ~external_controllers arms commanded on ARM/effort_command by a separate controller (ctc_controller);\n"
        "                        lockstep waits for them (default: none)\n"
        "  ~lockstep             true: each step waits for the command of every external controller that answers\n"
        "                        its state (by stamp), so a run is repeatable bit for bit; false: free-running\n"
        "  ~lockstep_timeout     wall seconds a lockstep step waits before braking the missing arms (default 0.2)\n"
        "  ~realtime_factor      free-running speed, simulated s per wall s (default 1; 0: as fast as possible)\n"
        "  ~max_drift            wall seconds the loop may fall behind or run ahead before its schedule restarts "
        "(0.05)\n"
        "  ~loop_priority        SCHED_FIFO priority of the loop thread, 1-99 (0: unchanged, the default)\n"
        "  ~max_step_duration    most simulated seconds one ~step call may ask for (default 60)\n"
        "  ~max_payload          heaviest ~set_payload [kg] (default: the robot file's rated payload, else 4)\n"
        "  ~max_force, ~max_torque  largest ~apply_wrench [N, N m] (default 200, 50)\n"
        "  ~command_timeout      simulated s after which an external command is stale: zero torque plus braking "
        "(0.05)\n"
        "  ~braking_damping      N m s/rad per joint applied when external commands are stale\n"
        "  ~initial_positions    map arm -> joint positions at start and after ~reset\n"
        "  ~grasp_at_reset       arms whose tools hold the cloth from each reset on (e.g. [left]: the scarf, held at\n"
        "                        its middle; default none). Refused at start when a tool holds no cloth node there\n"
        "  ~marker_rate          cloth marker and ~cloth rate [Hz of simulated time] (default 30)\n"
        "  ~max_scene_rate       markers, ~cloth and the cameras' images at most this often [Hz of wall time]\n"
        "                        (default 60): faster than real time, images no one could take are not drawn. A\n"
        "                        ~step's last moment and a reset are published at once\n"
        "  ~max_state_rate       joint_states and /clock at most this often [Hz of wall time] (default 2000; 0:\n"
        "                        every state; always every state in lockstep with external controllers)\n"
        "  ~object_seed          the seed of the moving object's path (default -1: the simulation file's)\n"
        "  ~camera_rate          top-down camera images per simulated second, at most marker_rate (default 30; 0: no\n"
        "                        camera)\n"
        "  ~camera_depth_noise, ~camera_colour_noise  the camera's noise: depth [m], colour [levels] (0.001, 2)\n"
        "  ~rgbd_rate            perspective RGB-D camera (Kinect-like, 640 x 480, f 525 px) images per simulated\n"
        "                        second (default 0: none); ~rgbd_eye, ~rgbd_target [m, world] where it is and looks\n"
        "                        (default 1.3 m above and 0.65 m beyond the table's centre, looking at it);\n"
        "                        ~rgbd_depth_noise k of sigma_z = k z^2 [1/m] (1.425e-3), ~rgbd_dropout (0.002)\n"
        "  ~paused               start paused (default false)\n"
        "  ~hardware             stand in for hardware (default false): the wall clock (no /clock; a reset does not\n"
        "                        take the clock back), no ~pause or ~step, real time only, the RGB-D camera as a\n"
        "                        Kinect's driver sends it (rgbd/image_raw raw with its plumb_bob distortion in\n"
        "                        rgbd/camera_info; rgbd/depth/image_raw 16UC1 millimetres on "
        "rgbd_depth_optical_frame,\n"
        "                        2.5 cm aside, with rgbd/depth/camera_info) with the arms in view, every state and\n"
        "                        image delivered ~latency late (0.003 s) give or take ~latency_jitter (0.001 s), and\n"
        "                        ~reset what a person does: the scene laid anew, the grippers opened, the arms left\n"
        "                        where they are\n"
        "  ~statistics_file      at exit, write the loop's periods and the times its controllers took commands "
        "(CSV)\n\n"
        "Hosted controller parameters (ARM/ctc_controller/...):\n") +
    bs::ros_layer::kControllerParameterHelp +
    "\nTopics: publishes joint_states (sensor_msgs/JointState, every step; effort: the applied torque), /clock,\n"
    "  ~markers (cloth TRIANGLE_LIST and table), ~cloth (sensor_msgs/PointCloud2: the cloth's nodes, world frame,\n"
    "  the simulator's ground truth), camera/image_raw (bgr8), camera/depth/image_raw (32FC1 [m]) with\n"
    "  camera/camera_info and camera/depth/camera_info (the orthographic top-down camera of the fold's reward,\n"
    "  frame top_down_camera on /tf_static), rgbd/image_raw, rgbd/depth/image_raw (32FC1 [m], NaN: no return)\n"
    "  with rgbd/camera_info, rgbd/depth/camera_info (frame rgbd_camera_optical_frame), /diagnostics (loop period, "
    "real-time factor, allocations per cycle);\n"
    "  subscribes ARM/effort_command (bimanual_skills/JointEffortCommand; in lockstep each applies to the state\n"
    "  its stamp answers) for external controllers, and, when the scene has a moving object, ~carry_object\n"
    "  (geometry_msgs/PointStamped, frame world or empty): a person carries the object there from then on (the hand\n"
    "  of human guidance, guide_person), instead of its path, until ~reset.\n"
    "  Each hosted controller serves ARM/command (trajectory_msgs/JointTrajectory), ARM/follow_joint_trajectory\n"
    "  (bimanual_skills/FollowJointTrajectory action), ARM/set_mode and publishes ARM/state, ARM/estimated_wrench,\n"
    "  ARM/estimated_external_torque (sensor_msgs/JointState, effort: the observer's joint torques), ARM/tool_paths.\n"
    "Sets ~world_digest: sim::SimConfig::worldDigest of ~config (with its URDF and plant files), and ~time_origin:\n"
    "the robot clock's time at the simulation's t = 0 (0; with ~hardware, the wall's time of the last reset).\n"
    "Services: ~reset (std_srvs/Trigger), ~pause (std_srvs/SetBool), ~step (bimanual_skills/SimStep, bounded),\n"
    "  ~set_payload, ~apply_wrench (bounded), ~grasp (bimanual_skills/ClothGrasp: takes the cloth nodes and the\n"
    "  moving object in reach, fails when there are none; a stamp ahead, at most 600 s, is done by the loop in its\n"
    "  first cycle at or after it).\n";

constexpr double kMaxGripperLead = 600.0;  ///< Simulated seconds ahead a ~grasp may be scheduled.
using bs::hosting::GripperDone;
using bs::hosting::SimulatedRobot;

class BulletSimNode {
 public:
  BulletSimNode(ros::NodeHandle& node, ros::NodeHandle& private_node) {
    private_node.deleteParam("world_digest");  // ours, of an earlier run: set below
    private_node.deleteParam("time_origin");
    bs::ros_layer::ParameterReader p(private_node, "bullet_sim");
    const std::string config_path = p.text("config", ros::package::getPath("bimanual_skills") + "/config/sim.yaml");
    const std::string robot_path = p.text("robot", "");
    sim::SimConfig config = sim::SimConfig::fromYamlFile(config_path, robot_path);
    const int object_seed = p.integer("object_seed", -1, -1, std::numeric_limits<int>::max());
    if (object_seed >= 0) {
      if (!config.has_object) throw std::invalid_argument("~object_seed: the simulation file has no object");
      config.object.path.seed = static_cast<std::uint32_t>(object_seed);
    }
    simulation_ = std::make_unique<sim::BimanualSimulation>(config);
    world_digest_ = sim::SimConfig::worldDigest(config_path, robot_path);
    if (!simulation_->config().robot_path.empty()) {
      robot_file_ = sim::RobotFile::fromYamlFile(simulation_->config().robot_path);
      for (const std::string& derived : robot_file_->derived) {
        ROS_INFO("bullet_sim: robot '%s', from the model: %s", robot_file_->name.c_str(), derived.c_str());
      }
    }
    robot_ = std::make_unique<SimulatedRobot>(*simulation_);
    bs::hosting::LoopSettings loop;
    loop.period = simulation_->stepSize();
    loop.lockstep = p.boolean("lockstep", false);
    loop.lockstep_timeout = p.number("lockstep_timeout", 0.2, 1e-3, 60.0);
    loop.realtime_factor = p.number("realtime_factor", 1.0, 0.0, 1000.0);
    loop.max_drift = p.number("max_drift", 0.05, 1e-3, 10.0);
    loop_priority_ = p.integer("loop_priority", 0, 0, 99);
    if (loop_priority_ > 0 && (loop.realtime_factor == 0.0 || loop.lockstep)) {
      throw std::invalid_argument(
          "~loop_priority needs a paced loop: with ~realtime_factor 0 or ~lockstep the loop never sleeps, and at "
          "SCHED_FIFO it would starve every other thread of its core (set ~loop_priority 0)");
    }
    if (sched_getscheduler(0) == SCHED_FIFO && (loop.realtime_factor == 0.0 || loop.lockstep)) {
      throw std::invalid_argument(
          "bullet_sim runs at SCHED_FIFO (sim.launch process_priority) but its loop never sleeps (~realtime_factor 0 "
          "or ~lockstep): it would starve every other thread of its core (process_priority:=0)");
    }
    max_step_duration_ = p.number("max_step_duration", 60.0, simulation_->stepSize(), 86400.0);
    max_payload_ = p.number("max_payload", robot_file_ ? robot_file_->rated_payload : 4.0, 0.0, 1000.0);
    max_force_ = p.number("max_force", 200.0, 0.0, 1e9);
    max_torque_ = p.number("max_torque", 50.0, 0.0, 1e9);
    bs::nodes::SimPublishing::Settings publishing;
    publishing.marker_rate = p.number("marker_rate", 30.0, 0.1, 1000.0);
    publishing.max_scene_rate = p.number("max_scene_rate", publishing.max_scene_rate, 1.0, 1000.0);
    publishing.max_state_rate = p.number("max_state_rate", publishing.max_state_rate, 0.0, 1e6);
    publishing.camera_rate = p.number("camera_rate", 30.0, 0.0, 1000.0);
    publishing.camera_noise.depth_stddev =
        p.number("camera_depth_noise", publishing.camera_noise.depth_stddev, 0.0, 1.0);
    publishing.camera_noise.colour_stddev =
        p.number("camera_colour_noise", publishing.camera_noise.colour_stddev, 0.0, 255.0);
    publishing.rgbd_rate = p.number("rgbd_rate", 0.0, 0.0, 1000.0);
    publishing.rgbd = bs::tasks::rgbdCameraFor(simulation_->config());
    const Eigen::Vector3d from = publishing.rgbd.pose.translation(), to = simulation_->config().table.topCentre();
    const auto eye = p.numbers("rgbd_eye", {from.x(), from.y(), from.z()}, 3);
    const auto target = p.numbers("rgbd_target", {to.x(), to.y(), to.z()}, 3);
    publishing.rgbd = bs::vision::PinholeCamera::lookingAt(Eigen::Vector3d(eye[0], eye[1], eye[2]),
                                                           Eigen::Vector3d(target[0], target[1], target[2]));
    publishing.rgbd_noise.axial = p.number("rgbd_depth_noise", publishing.rgbd_noise.axial, 0.0, 1.0);
    publishing.rgbd_noise.dropout = p.number("rgbd_dropout", publishing.rgbd_noise.dropout, 0.0, 1.0);
    loop.paused = p.boolean("paused", false);
    hardware_ = p.boolean("hardware", false);
    if (hardware_) {
      // Standing in for hardware: what a real robot does not offer is refused by name.
      if (loop.lockstep)
        throw std::invalid_argument("~hardware: a robot does not wait for its controllers (~lockstep)");
      if (loop.realtime_factor != 1.0) {
        throw std::invalid_argument("~hardware: a robot runs at real time (~realtime_factor 1)");
      }
      if (loop.paused) throw std::invalid_argument("~hardware: a robot cannot start paused (~paused)");
      loop.pausable = false;  // as a driver's loop: its clock is never held
      publishing.publish_clock = false;
      publishing.raw_rgbd = true;
      publishing.arms_in_view = true;
      publishing.latency = p.number("latency", 0.003, 0.0, 0.5);
      publishing.latency_jitter = p.number("latency_jitter", 0.001, 0.0, publishing.latency);
    }
    statistics_file_ = p.text("statistics_file", "");
    const double command_timeout = p.number("command_timeout", 0.05, 1e-4, 10.0);
    std::vector<std::string> all_arms, names;
    for (int a = 0; a < simulation_->armCount(); ++a) all_arms.push_back(simulation_->config().arms[a].name);
    const std::vector<std::string> external = p.texts("external_controllers", {});
    std::vector<std::string> hosted_default;
    for (const std::string& a : all_arms) {
      if (std::find(external.begin(), external.end(), a) == external.end()) hosted_default.push_back(a);
    }
    const std::vector<std::string> hosted = p.texts("hosted_controllers", hosted_default);
    if (!external.empty() && loop.realtime_factor == 0.0 && !loop.lockstep) {
      throw std::invalid_argument(
          "~external_controllers with ~realtime_factor 0 (as fast as possible) and no ~lockstep: controllers in other "
          "processes would get states faster than they answer them and fall behind by whole steps (their velocity "
          "limits and stale-state checks then stop every goal); set ~lockstep true, or a ~realtime_factor > 0 they "
          "can follow");
    }
    if (loop.lockstep && !external.empty()) publishing.max_state_rate = 0.0;  // each state has its answer to wait for
    for (const std::vector<std::string>* list : {&external, &hosted}) {
      for (const std::string& name : *list) {
        if (simulation_->armIndex(name) < 0) {
          std::string known;
          for (const std::string& a : all_arms) known += (known.empty() ? "" : ", ") + a;
          throw std::invalid_argument("~hosted_controllers and ~external_controllers name an unknown arm '" + name +
                                      "' (the robot's arms: " + known +
                                      "; sim.launch takes them as first_arm:=NAME second_arm:=NAME)");
        }
      }
    }
    std::string description, description_key;
    if (!node.searchParam("robot_description", description_key) || !node.getParam(description_key, description)) {
      std::ifstream urdf(simulation_->config().urdf_path);
      description.assign(std::istreambuf_iterator<char>(urdf), std::istreambuf_iterator<char>());
    }
    // Each arm's initial positions and braking damping, read before the first reset.
    std::vector<Eigen::VectorXd> damping;
    for (std::size_t a = 0; a < all_arms.size(); ++a) {
      const int n = simulation_->jointCount(static_cast<int>(a));
      const auto size = static_cast<std::size_t>(n);
      const sim::RobotArm* from_robot = robot_file_ ? robot_file_->arm(all_arms[a]) : nullptr;
      initial_.push_back(from_robot ? from_robot->start : simulation_->trueState(static_cast<int>(a)).q);
      if (p.has("initial_positions/" + all_arms[a])) {
        const auto q = p.numbers("initial_positions/" + all_arms[a], {}, size);
        initial_.back() = Eigen::Map<const Eigen::VectorXd>(q.data(), n);
      }
      const Eigen::VectorXd braking =
          robot_file_ ? robot_file_->braking_damping : Eigen::VectorXd(Eigen::VectorXd::Constant(n, 10.0));
      const auto d = p.numbers("braking_damping", std::vector<double>(braking.data(), braking.data() + braking.size()),
                               size, 0.0, 1e4);
      damping.push_back(Eigen::Map<const Eigen::VectorXd>(d.data(), n));
      joint_names_.push_back(simulation_->armModel(static_cast<int>(a)).jointNames());
      names.insert(names.end(), joint_names_.back().begin(), joint_names_.back().end());
    }
    for (const std::string& arm : p.texts("grasp_at_reset", {})) {
      const auto found = std::find(all_arms.begin(), all_arms.end(), arm);
      if (found == all_arms.end()) throw std::invalid_argument("~grasp_at_reset: no arm '" + arm + "'");
      if (!simulation_->hasCloth()) throw std::invalid_argument("~grasp_at_reset: the simulation has no cloth");
      grasp_at_reset_.push_back(static_cast<int>(found - all_arms.begin()));
    }
    p.warnUnknown();
    if (hardware_) {
      robot_->setClockOffset(ros::WallTime::now().toSec());
      robot_->followWallClock(true);
    }
    resetSimulation();
    gripper_logged_.assign(all_arms.size(), 0);
    publishing_ = std::make_unique<bs::nodes::SimPublishing>(node, private_node, *simulation_, names, publishing,
                                                             [this] { logGripperCommands(); });
    loop_ = std::make_unique<bs::hosting::ControlLoop>(*robot_, *publishing_, loop, &probe_);
    for (std::size_t a = 0; a < all_arms.size(); ++a) {
      const std::string& arm = all_arms[a];
      const bool is_external = std::find(external.begin(), external.end(), arm) != external.end();
      if (std::find(hosted.begin(), hosted.end(), arm) != hosted.end()) {
        if (is_external) throw std::invalid_argument("arm '" + arm + "' is both hosted and external");
        controllers_.push_back(bs::ros_layer::hostArmController(
            *loop_, static_cast<int>(a), node, arm, joint_names_[a], description, "bullet_sim",
            bs::ros_layer::controllerDefaults(robot_file_ ? &*robot_file_ : nullptr, arm)));
        continue;
      }
      // Commanded from outside: on a queue and thread of their own, handed to the loop lock-free.
      loop_->commandFromOutside(static_cast<int>(a), command_timeout, damping[a], is_external);
      ros::SubscribeOptions options = ros::SubscribeOptions::create<bimanual_skills::JointEffortCommand>(
          arm + "/effort_command", 10,
          [this, a](const bimanual_skills::JointEffortCommand::ConstPtr& message) { onCommand(a, *message); },
          ros::VoidPtr(), &command_queue_);
      options.transport_hints = ros::TransportHints().tcpNoDelay();
      subscribers_.push_back(node.subscribe(options));
    }
    if (simulation_->hasObject()) {
      // A scene command, not a control one: on the services' queue, handed to the loop between two cycles.
      ros::SubscribeOptions carry = ros::SubscribeOptions::create<geometry_msgs::PointStamped>(
          "carry_object", 1, [this](const geometry_msgs::PointStamped::ConstPtr& message) { onCarry(*message); },
          ros::VoidPtr(), &service_queue_);
      subscribers_.push_back(private_node.subscribe(carry));
    }
    diagnostics_publisher_ = node.advertise<diagnostic_msgs::DiagnosticArray>("/diagnostics", 10);
    // Clients that assume a world (the learner) compare it with theirs before they use the simulator's services.
    private_node.setParam("world_digest", world_digest_);
    // The robot clock's time at the simulation's t = 0, when a scripted scene (the object's path) starts: 0 on the
    // simulated clock, the wall's time of the last reset with ~hardware.
    private_node.setParam("time_origin", robot_->time() - simulation_->time());
    // The services on a queue and threads of their own: a long ~step or a loop that is slow to take a request never
    // holds up the controllers' topics and timers, and those never hold up a service.
    ros::NodeHandle services(private_node);
    services.setCallbackQueue(&service_queue_);
    services_.push_back(services.advertiseService("reset", &BulletSimNode::onReset, this));
    if (!hardware_) {  // a robot's clock cannot be held or stepped
      services_.push_back(services.advertiseService("pause", &BulletSimNode::onPause, this));
      services_.push_back(services.advertiseService("step", &BulletSimNode::onStep, this));
    }
    services_.push_back(services.advertiseService("set_payload", &BulletSimNode::onSetPayload, this));
    services_.push_back(services.advertiseService("apply_wrench", &BulletSimNode::onApplyWrench, this));
    services_.push_back(services.advertiseService("grasp", &BulletSimNode::onGrasp, this));
    diagnostics_timer_ = node.createSteadyTimer(ros::WallDuration(1.0), &BulletSimNode::onDiagnostics, this);
    std::string hosted_list, external_list;
    for (const std::string& arm : all_arms) {
      (std::find(hosted.begin(), hosted.end(), arm) != hosted.end() ? hosted_list : external_list) += " " + arm;
    }
    ROS_INFO("bullet_sim: %zu arms, step %.4f s, cloth %s, %s%s; hosted controllers:%s; external:%s", all_arms.size(),
             simulation_->stepSize(), simulation_->hasCloth() ? "on" : "off",
             hardware_       ? "as hardware (wall clock, no ~pause or ~step, a Kinect's images with the arms in view)"
             : loop.lockstep ? "lockstep"
                             : "free-running",
             loop.paused ? ", paused" : "", hosted_list.empty() ? " none" : hosted_list.c_str(),
             external_list.empty() ? " none" : external_list.c_str());
  }

  /// Runs the loop on the calling thread until shutdown; services and topics on other threads.
  void run() {
    bs::ros_layer::QueueSpinner topics(2);  // the controllers' topics, actions and timers, diagnostics
    bs::ros_layer::QueueSpinner services(3, &service_queue_);
    bs::ros_layer::QueueSpinner commands(1, &command_queue_);
    topics.start();
    services.start();
    commands.start();
    if (loop_priority_ > 0) {
      const char* error = bs::realtime::requestRealtimeScheduling(loop_priority_);
      if (*error == '\0') {
        ROS_INFO("bullet_sim: loop thread at SCHED_FIFO priority %d", loop_priority_);
      } else {
        ROS_WARN("bullet_sim: ~loop_priority %d not granted (%s); the loop runs at normal priority", loop_priority_,
                 error);
      }
    }
    loop_->run([] { return ros::ok(); });
    publishing_.reset();
    if (!statistics_file_.empty() &&
        !bs::io::writeWhole(statistics_file_, [this](std::ostream& out) { loop_->writeStatistics(out); })) {
      ROS_ERROR("bullet_sim: cannot write %s", statistics_file_.c_str());
    }
  }

 private:
  void resetSimulation() {
    std::vector<sim::ArmState> state;
    for (std::size_t a = 0; a < initial_.size(); ++a) {
      // Standing in for hardware a reset is what a person does: the scene laid anew, the grippers opened, the arms
      // left where and as they are (a robot's arms do not jump).
      if (hardware_ && started_) {
        state.push_back(simulation_->trueState(static_cast<int>(a)));
      } else {
        state.push_back({initial_[a], Eigen::VectorXd::Zero(initial_[a].size())});
      }
    }
    started_ = true;
    // Standing in for hardware the robot's clock is the wall's (SimulatedRobot::followWallClock), and a reset does
    // not take it back.
    const double clock = hardware_ ? robot_->time() + simulation_->stepSize() : 0.0;
    const sim::SimStatus status = simulation_->reset(state);
    robot_->setClockOffset(clock);
    simulation_->setRandomGenerator(std::mt19937(simulation_->config().seed));
    if (status != sim::SimStatus::Ok) {
      throw std::invalid_argument(std::string("initial positions rejected: ") + sim::toString(status));
    }
    robot_->reset();
    for (const int a : grasp_at_reset_) {
      int attached = 0;
      if (simulation_->grasp(a, &attached) != sim::SimStatus::Ok || attached == 0) {
        throw std::invalid_argument(
            "~grasp_at_reset: the tool of '" + simulation_->config().arms[static_cast<std::size_t>(a)].name +
            "' holds no cloth node at reset (none within " + std::to_string(simulation_->config().grasp_radius) +
            " m: check the cloth's pose against the arm's initial positions)");
      }
    }
  }

  void onCommand(std::size_t arm, const bimanual_skills::JointEffortCommand& message) {
    const std::vector<std::string>& joints = joint_names_[arm];
    const bool named = message.name.empty() || message.name == joints;
    const std::size_t n = joints.size();
    const bool impedance = !message.position.empty() || !message.velocity.empty() || !message.stiffness.empty() ||
                           !message.damping.empty();
    const bool sized =
        message.effort.size() == n && (!impedance || (message.position.size() == n && message.velocity.size() == n &&
                                                      message.stiffness.size() == n && message.damping.size() == n));
    if (!named || !sized) {
      ROS_WARN_THROTTLE(1.0,
                        "bullet_sim: effort_command for %s rejected: %zu efforts%s%s for the joints %s, ... (the "
                        "impedance's position, velocity, stiffness and damping: all empty or all of the efforts' size)",
                        simulation_->config().arms[arm].name.c_str(), message.effort.size(),
                        impedance ? " with an impedance" : "", named ? "" : " named otherwise", joints.front().c_str());
    }
    const double stamp = message.header.stamp.isZero() ? std::nan("") : message.header.stamp.toSec();
    const bs::hosting::CommandImpedance arrays{message.position.data(), message.velocity.data(),
                                               message.stiffness.data(), message.damping.data()};
    loop_->torqueCommand(static_cast<int>(arm), stamp, message.effort.data(), named && sized ? n : 0,
                         impedance ? &arrays : nullptr);
  }

  /// Publisher thread: logs the scheduled gripper commands the loop did since the last call.
  void logGripperCommands() {
    for (std::size_t a = 0; a < gripper_logged_.size(); ++a) {
      const std::uint64_t count = robot_->doneCount(a);
      if (count == gripper_logged_[a]) continue;
      gripper_logged_[a] = count;
      const GripperDone done = robot_->done(a);
      const double at = done.at;
      ROS_INFO("bullet_sim: %s's scheduled gripper command %s at t = %.6f s, scheduled for t = %.6f s",
               simulation_->config().arms[a].name.c_str(), at >= 0.0 ? "done" : "failed", at >= 0.0 ? at : -at - 1.0,
               done.due);
    }
  }

  bool onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    const auto r = loop_->call([this] {
      resetSimulation();
      loop_->restart("~reset");
      std::ostringstream said;
      said << std::fixed << std::setprecision(6) << "reset to the initial positions at t = " << robot_->time()
           << " s (sensor noise reseeded)";
      return bs::hosting::LoopOutcome{true, said.str(), robot_->time()};
    });
    response.success = r.success;
    response.message = r.message;
    if (r.success) ros::NodeHandle("~").setParam("time_origin", r.time);
    ROS_INFO("bullet_sim: %s", response.message.c_str());
    return true;
  }

  bool onPause(std_srvs::SetBool::Request& request, std_srvs::SetBool::Response& response) {
    const auto r = loop_->pause(request.data);
    response.success = r.success;
    response.message = r.message;
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
      response.time = loop_->time();
      return true;
    }
    const auto r = loop_->step(request.steps);
    response.success = r.success;
    response.message = r.message;
    response.time = r.time;
    return true;
  }

  int armOf(const std::string& name, std::string& message) const {
    const int a = simulation_->armIndex(name);
    if (a < 0) {
      message = "unknown arm '" + name + "'; arms:";
      for (const auto& arm : simulation_->config().arms) message += " " + arm.name;
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
              << "] kg (~max_payload";
      if (robot_file_) message << "; the robot file's rated payload is " << robot_file_->rated_payload << " kg";
      message << ")";
      response.message = message.str();
      return true;
    }
    if (!payload.com.allFinite() || payload.com.norm() > 1.0) {
      response.message = "rejected: the centre of mass must be finite and within 1 m of the tool";
      return true;
    }
    const std::string arm = request.arm;
    const auto r = loop_->call([this, a, payload, arm] {
      const sim::SimStatus status = simulation_->setPayload(a, payload);
      const bool ok = status == sim::SimStatus::Ok;
      return bs::hosting::LoopOutcome{ok,
                                      ok ? "payload of " + std::to_string(payload.mass) + " kg on " + arm
                                         : "rejected: " + std::string(sim::toString(status)),
                                      robot_->time()};
    });
    response.success = r.success;
    response.message = r.message;
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
    const auto r = loop_->call([this, link, force, torque, point, name] {
      const sim::SimStatus status = simulation_->setExternalWrench(link, force, torque, point);
      const bool ok = status == sim::SimStatus::Ok;
      return bs::hosting::LoopOutcome{
          ok, ok ? "wrench applied on " + name : "rejected: " + std::string(sim::toString(status)), robot_->time()};
    });
    response.success = r.success;
    response.message = r.message;
    return true;
  }

  void onCarry(const geometry_msgs::PointStamped& message) {
    if (!message.header.frame_id.empty() && message.header.frame_id != "world") {
      ROS_WARN_THROTTLE(5.0, "bullet_sim: ~carry_object in frame '%s' ignored: it takes points in world",
                        message.header.frame_id.c_str());
      return;
    }
    const Eigen::Vector3d p(message.point.x, message.point.y, message.point.z);
    const auto r = loop_->call(
        [this, p] {
          const sim::SimStatus status = simulation_->carryObject(p);
          return bs::hosting::LoopOutcome{status == sim::SimStatus::Ok, sim::toString(status), robot_->time()};
        },
        0.5);
    if (!r.success) {
      ROS_WARN_THROTTLE(5.0, "bullet_sim: ~carry_object (%g, %g, %g) not taken: %s", p.x(), p.y(), p.z(),
                        r.message.c_str());
    }
  }

  bool onGrasp(bimanual_skills::ClothGrasp::Request& request, bimanual_skills::ClothGrasp::Response& response) {
    const int a = armOf(request.arm, response.message);
    if (a < 0) return true;
    const bool grasp = request.grasp;
    const std::string arm = request.arm;
    const double at = request.stamp.toSec();
    if (at > loop_->time() + kMaxGripperLead) {
      std::ostringstream message;
      message << "refused: a stamp " << at - loop_->time() << " s ahead of the simulation's clock; at most "
              << kMaxGripperLead << " s";
      response.message = message.str();
      return true;
    }
    int attached = 0;
    bool object = false;
    const auto r = loop_->call([this, a, grasp, arm, at, &attached, &object] {
      std::ostringstream message;
      message << std::fixed << std::setprecision(6);
      if (at > robot_->time()) {  // ahead: the loop does it at its time (SimulatedRobot::due)
        robot_->schedule(a, at, grasp);
        message << arm << (grasp ? " grasp" : " release") << " scheduled at t = " << at << " s";
        return bs::hosting::LoopOutcome{true, message.str(), at};
      }
      robot_->schedule(a, SimulatedRobot::kNever, grasp);  // done now: one scheduled before is replaced
      const bool held = simulation_->hasObject() && simulation_->objectHolder() == a;
      const sim::SimStatus status = grasp ? simulation_->grasp(a, &attached, &object) : simulation_->release(a);
      const double t = robot_->time();
      if (status != sim::SimStatus::Ok)
        return bs::hosting::LoopOutcome{false, "failed: " + std::string(sim::toString(status)), t};
      const sim::SimConfig& config = simulation_->config();
      if (grasp && attached == 0 && !object) {
        message << arm << " grasped nothing:";
        if (config.has_cloth) message << " no free cloth node within " << config.grasp_radius << " m of its tool;";
        if (config.has_object) {
          const Eigen::Vector3d point = simulation_->objectPose().translation() + config.object.grasp_point;
          message << " the object's grasp point is " << (simulation_->toolPose(a).translation() - point).norm()
                  << " m from its tool (grasp_radius " << config.object.grasp_radius << " m)";
        }
        return bs::hosting::LoopOutcome{false, message.str(), t};
      }
      if (!grasp) return bs::hosting::LoopOutcome{true, arm + (held ? " let the object go" : " released the cloth"), t};
      message << arm << " grasped " << (object ? "the object" : "") << (object && attached > 0 ? " and " : "");
      if (attached > 0) message << attached << " cloth nodes";
      return bs::hosting::LoopOutcome{true, message.str(), t};
    });
    response.success = r.success;
    response.nodes = attached;
    response.message = r.message;
    response.executed = ros::Time(std::max(0.0, r.time));
    ROS_INFO("bullet_sim: %s", response.message.c_str());
    return true;
  }

  void onDiagnostics(const ros::SteadyTimerEvent&) {
    diagnostic_msgs::DiagnosticArray array;
    array.header.stamp = ros::Time::now();
    diagnostic_msgs::DiagnosticStatus status = diagnostics_.status(*loop_, "bullet_sim");
    if (!loop_->stopped() && robot_->clothDiverged()) {
      status.level = diagnostic_msgs::DiagnosticStatus::ERROR;
      status.message = "the cloth diverged (" + std::string(sim::toString(robot_->clothDivergence())) +
                       "): it is frozen until ~reset";
    }
    for (std::size_t a = 0; a < gripper_logged_.size(); ++a) {
      const double done = robot_->done(a).at;
      if (std::isnan(done)) continue;
      std::ostringstream at;
      at << std::fixed << std::setprecision(6) << (done >= 0.0 ? done : -done - 1.0)
         << (done >= 0.0 ? "" : " (failed)");
      bs::ros_layer::LoopDiagnostics::add(status, simulation_->config().arms[a].name + "_gripper_scheduled_done_at",
                                          at.str());
    }
    array.status.push_back(status);
    diagnostics_publisher_.publish(array);
  }

  std::unique_ptr<sim::BimanualSimulation> simulation_;
  std::unique_ptr<SimulatedRobot> robot_;
  bool hardware_ = false;                     ///< Standing in for hardware (~hardware).
  bool started_ = false;                      ///< The first reset (to the initial positions) was done.
  std::optional<sim::RobotFile> robot_file_;  ///< The robot the simulation runs (none when its file names the arms).
  bs::realtime::ScopedCounterProbe<bs::testing::AllocationCounter> probe_;  ///< The loop's allocations per cycle.
  std::vector<Eigen::VectorXd> initial_;
  std::vector<int> grasp_at_reset_;  ///< Arms holding the cloth from each reset on.
  std::vector<std::vector<std::string>> joint_names_;
  std::vector<std::uint64_t> gripper_logged_;  ///< Publisher thread: scheduled commands logged per arm.
  std::unique_ptr<bs::nodes::SimPublishing> publishing_;
  std::unique_ptr<bs::hosting::ControlLoop> loop_;
  std::vector<std::unique_ptr<bs::ros_layer::ArmControllerInterface>> controllers_;
  ros::CallbackQueue command_queue_, service_queue_;
  std::vector<ros::Subscriber> subscribers_;
  ros::Publisher diagnostics_publisher_;
  std::vector<ros::ServiceServer> services_;
  ros::SteadyTimer diagnostics_timer_;
  std::string statistics_file_, world_digest_;
  double max_step_duration_ = 60.0, max_payload_ = 4.0, max_force_ = 200.0, max_torque_ = 50.0;
  int loop_priority_ = 0;
  bs::ros_layer::LoopDiagnostics diagnostics_;
};

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
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
