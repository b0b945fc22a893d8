// teach_demonstration: teach the fold by showing it. Either the arms are moved by hand in gravity compensation (a
// real robot), or each tool follows a hand target (an rviz marker you drag, or a script's targets) through global IK
// and the arms' trajectory controllers (teleoperation, the simulator). The tools' poses are recorded from the joint
// states and fitted into the Cartesian DMP files the fold learner starts from. A thin shell:
// primitives::DemonstrationRecorder trims, resamples and fits; kinematics gives the poses and the IK.
#include "bimanual_skills/ClothGrasp.h"
#include "bimanual_skills/SetControlMode.h"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "bimanual_skills/primitives/demonstration_recorder.hpp"
#include "bimanual_skills/primitives/dmp_yaml.hpp"
#include "bimanual_skills/rollout/fold_learning.hpp"
#include "bimanual_skills/ros_layer/bounded_call.hpp"
#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/sim/sim_config.hpp"
#include "cli/pinned_numerics.hpp"
#include "node_cli.hpp"

#include <geometry_msgs/PointStamped.h>
#include <interactive_markers/interactive_marker_server.h>
#include <ros/package.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <trajectory_msgs/JointTrajectory.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace bs = bimanual_skills;
namespace bk = bimanual_skills::kinematics;

namespace {

const char* const kUsage =
    "usage: rosrun bimanual_skills teach_demonstration [_config:=FILE] [_out:=DIR] [_mode:=teleoperation|hand]\n"
    "\n"
    "Teach the cloth fold by showing it on the arms of sim.launch (or real ones), and write the Cartesian DMP files a\n"
    "learning file's task: {demonstration: [DIR/taught_left.yaml, DIR/taught_right.yaml]} starts from.\n"
    "  teleoperation (default): each tool follows its hand: a marker you drag in rviz (interactive markers on\n"
    "                teach_demonstration/hands) or targets on ARM/hand_target; global IK keeps the tool's\n"
    "                orientation and ARM/command moves the arm there at most at half its joints' speed limits.\n"
    "  hand:         both arms in gravity compensation (ARM/set_mode); move them with your hands.\n"
    "Call ~grasp (true) to close the grippers on the cloth, ~start to record, fold, ~grasp (false) to let the cloth\n"
    "go, and ~save to fit one DMP per tool (the still parts before and after trimmed) and write the files.\n"
    "  roslaunch bimanual_skills teach.launch     (sim.launch with the tools at the cloth's far corners, this node, "
    "rviz)\n"
    "\n"
    "Parameters (private):\n"
    "  ~config          learning file: its simulation gives the arms and tool links, its kernels the DMPs'\n"
    "                   (default: the package's config/fold_demo.yaml)\n"
    "  ~robot           robot file (config/robots/*.yaml) whose arms and tool links are taught, instead of the one\n"
    "                   the learning file's simulation names (teach.launch robot:=FILE sets it)\n"
    "  ~out             directory of the DMP files and taught_poses.csv (default: taught, in the working directory)\n"
    "  ~mode            teleoperation or hand (default teleoperation)\n"
    "  ~world_frame     root link of robot_description, the frame of hands and poses (default world)\n"
    "  ~grasp_service   bimanual_skills/ClothGrasp (default bullet_sim/grasp)\n"
    "  ~service_timeout [s] of wall time any service call may take (default 5)\n"
    "\n"
    "Topics: subscribes joint_states (sensor_msgs/JointState), ARM/hand_target (geometry_msgs/PointStamped in\n"
    "  ~world_frame; teleoperation); publishes ARM/command (trajectory_msgs/JointTrajectory; teleoperation) and the\n"
    "  interactive markers teach_demonstration/hands. Services: ~start, ~save (std_srvs/Trigger), ~grasp\n"
    "  (std_srvs/SetBool).\n";

/// Targets closer than this to the last one sent are not sent again [m].
constexpr double kTargetResolution = 0.003;

struct Arm {
  std::string name;
  std::unique_ptr<bk::ChainModel> model;  ///< From the world frame to the tool.
  std::unique_ptr<bk::ChainData> data;
  std::unique_ptr<bk::GlobalIkSolver> ik;
  std::vector<int> state_index;  ///< Of each joint in the last joint_states message (-1: not there).
  Eigen::VectorXd q;             ///< Measured joints.
  bool measured = false;
  bs::primitives::Pose tool;                                 ///< Measured tool pose (world).
  Eigen::Quaterniond grip = Eigen::Quaterniond::Identity();  ///< The orientation teleoperation keeps.
  Eigen::Vector3d sent = Eigen::Vector3d::Constant(1e9);     ///< The last hand target sent.
  bool has_grip = false;
  ros::Subscriber target;
  ros::Publisher command;
  std::string mode;  ///< Its controller's set_mode service.
};

class TeachNode {
 public:
  TeachNode() : private_node_("~"), parameters_(private_node_, "teach_demonstration") {
    const std::string config =
        parameters_.text("config", ros::package::getPath("bimanual_skills") + "/config/fold_demo.yaml");
    out_ = parameters_.text("out", "taught");
    teleoperation_ = parameters_.text("mode", "teleoperation", {"teleoperation", "hand"}) == "teleoperation";
    world_ = parameters_.text("world_frame", "world");
    const std::string robot = parameters_.text("robot", "");
    timeout_ = parameters_.number("service_timeout", 5.0, 0.1, 60.0);
    const std::string grasp = parameters_.text("grasp_service", "bullet_sim/grasp");
    parameters_.warnUnknown();

    const bs::rollout::FoldLearningConfig learning = bs::rollout::FoldLearningConfig::fromYamlFile(config);
    kernels_ = learning.task.kernels;
    // The arms and their tool links: the robot file's (the learning file's simulation names one by default).
    const bs::sim::SimConfig sim = bs::sim::SimConfig::fromYamlFile(learning.task.sim_config, robot);
    std::string urdf;
    if (!node_.getParam("robot_description", urdf)) throw std::invalid_argument("no robot_description parameter");
    for (const bs::sim::ArmConfig& a : sim.arms) {
      auto arm = std::make_unique<Arm>();
      arm->name = a.name;
      arm->model = std::make_unique<bk::ChainModel>(bk::ChainModel::fromUrdfString(urdf, world_, a.tip_link));
      arm->data = std::make_unique<bk::ChainData>(*arm->model);
      bk::GlobalIkParameters ik;
      ik.timeout = 0.05;
      arm->ik = std::make_unique<bk::GlobalIkSolver>(*arm->model, ik);
      arm->q = Eigen::VectorXd::Zero(arm->model->nq());
      arm->mode = a.name + "/set_mode";
      arm->command = node_.advertise<trajectory_msgs::JointTrajectory>(a.name + "/command", 1);
      Arm* raw = arm.get();
      arm->target = node_.subscribe<geometry_msgs::PointStamped>(
          a.name + "/hand_target", 10,
          [this, raw](const geometry_msgs::PointStamped::ConstPtr& m) { onTarget(*raw, *m); });
      arms_.push_back(std::move(arm));
    }
    recorder_ = std::make_unique<bs::primitives::DemonstrationRecorder>(static_cast<int>(arms_.size()));
    grasp_ = grasp;
    caller_ = std::make_unique<bs::ros_layer::ServiceCaller>(node_);
    states_ = node_.subscribe("joint_states", 10, &TeachNode::onStates, this);
    services_.push_back(private_node_.advertiseService("start", &TeachNode::onStart, this));
    services_.push_back(private_node_.advertiseService("save", &TeachNode::onSave, this));
    services_.push_back(private_node_.advertiseService("grasp", &TeachNode::onGrasp, this));
    markers_ = std::make_unique<interactive_markers::InteractiveMarkerServer>("teach_demonstration/hands");
    ROS_INFO("teach_demonstration: %zu arms by %s; files into %s", arms_.size(),
             teleoperation_ ? "teleoperation (drag the hands in rviz or publish ARM/hand_target)" : "hand",
             out_.c_str());
  }

  /// Hand mode: puts the arms into gravity compensation (bounded calls). False, with a message, when one refuses.
  bool start() {
    if (teleoperation_) return true;
    for (const auto& arm : arms_) {
      bimanual_skills::SetControlMode mode;
      mode.request.mode = "gravity_compensation";
      const auto outcome = caller_->call(arm->mode, mode, timeout_);
      if (outcome != bs::ros_layer::CallOutcome::Answered || !mode.response.success) {
        ROS_ERROR("teach_demonstration: %s/set_mode gravity_compensation failed: %s", arm->name.c_str(),
                  outcome == bs::ros_layer::CallOutcome::Answered ? mode.response.message.c_str()
                                                                  : bs::ros_layer::describe(outcome));
        return false;
      }
    }
    return true;
  }

 private:
  void onStates(const sensor_msgs::JointState::ConstPtr& m) {
    const std::lock_guard<std::mutex> lock(mutex_);
    std::vector<bs::primitives::Pose> poses;
    for (const auto& arm : arms_) {
      const std::vector<std::string> names = arm->model->jointNames();
      for (std::size_t j = 0; j < names.size(); ++j) {
        const auto found = std::find(m->name.begin(), m->name.end(), names[j]);
        if (found == m->name.end() || m->position.size() != m->name.size()) return;  // not this robot's joints
        arm->q[static_cast<Eigen::Index>(j)] = m->position[static_cast<std::size_t>(found - m->name.begin())];
      }
      if (!arm->q.allFinite() ||
          bk::forwardKinematics(*arm->model, *arm->data, arm->q) != bk::KinematicsStatus::Success) {
        return;
      }
      arm->tool.position = arm->data->tipPose().translation();
      arm->tool.orientation = Eigen::Quaterniond(arm->data->tipPose().linear()).normalized();
      if (!arm->has_grip) {  // the first state: the hand takes the tool as it is
        arm->grip = arm->tool.orientation;
        arm->has_grip = true;
        addMarker(*arm);
        markers_->applyChanges();
      }
      arm->measured = true;
      poses.push_back(arm->tool);
    }
    if (recording_ && !recorder_->add(m->header.stamp.toSec(), poses)) {
      ROS_WARN_THROTTLE(1.0, "teach_demonstration: a joint state not after the last one was left out");
    }
  }

  void onTarget(Arm& arm, const geometry_msgs::PointStamped& m) {
    const Eigen::Vector3d p(m.point.x, m.point.y, m.point.z);
    if (!p.allFinite() || (!m.header.frame_id.empty() && m.header.frame_id != world_)) {
      ROS_WARN_THROTTLE(1.0, "teach_demonstration: %s/hand_target refused: not finite or not in %s", arm.name.c_str(),
                        world_.c_str());
      return;
    }
    const std::lock_guard<std::mutex> lock(mutex_);
    geometry_msgs::Pose pose;
    pose.position = m.point;
    pose.orientation.w = 1.0;
    markers_->setPose(arm.name, pose);
    markers_->applyChanges();
    moveTo(arm, p);
  }

  /// Teleoperation: the arm to the joints global IK finds for the hand at `p` with the grip's orientation, at most
  /// at half its speed limits. Under the lock.
  void moveTo(Arm& arm, const Eigen::Vector3d& p) {
    if (!teleoperation_ || !arm.measured || (p - arm.sent).norm() < kTargetResolution) return;
    Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
    target.translation() = p;
    target.linear() = arm.grip.toRotationMatrix();
    Eigen::VectorXd q(arm.model->nq());
    const bk::GlobalIkResult result = arm.ik->solve(target, arm.q, q);
    if (result.status != bk::IkStatus::Converged) {
      ROS_WARN_THROTTLE(1.0, "teach_demonstration: %s's hand at (%.3f, %.3f, %.3f) is out of reach", arm.name.c_str(),
                        p.x(), p.y(), p.z());
      return;
    }
    const Eigen::VectorXd step = (q - arm.q).cwiseAbs();
    double seconds = 0.1;
    for (Eigen::Index j = 0; j < step.size(); ++j)
      seconds = std::max(seconds, step[j] / (0.5 * arm.model->velocityLimits()[j]));
    trajectory_msgs::JointTrajectory command;
    command.joint_names = arm.model->jointNames();
    trajectory_msgs::JointTrajectoryPoint point;
    point.positions.assign(q.data(), q.data() + q.size());
    point.velocities.assign(static_cast<std::size_t>(q.size()), 0.0);
    point.time_from_start = ros::Duration(seconds);
    command.points.push_back(point);
    arm.command.publish(command);
    arm.sent = p;
  }

  void addMarker(const Arm& arm) {
    visualization_msgs::InteractiveMarker marker;
    marker.header.frame_id = world_;
    marker.name = arm.name;
    marker.description = arm.name + " hand";
    marker.scale = 0.15;
    marker.pose.position.x = arm.tool.position.x();
    marker.pose.position.y = arm.tool.position.y();
    marker.pose.position.z = arm.tool.position.z();
    marker.pose.orientation.w = 1.0;
    visualization_msgs::Marker ball;
    ball.type = visualization_msgs::Marker::SPHERE;
    ball.scale.x = ball.scale.y = ball.scale.z = 0.05;
    ball.color.r = 1.0f;
    ball.color.g = 0.6f;
    ball.color.a = 0.8f;
    visualization_msgs::InteractiveMarkerControl body;
    body.always_visible = true;
    body.interaction_mode = visualization_msgs::InteractiveMarkerControl::MOVE_3D;
    body.markers.push_back(ball);
    marker.controls.push_back(body);
    const double axes[3][4] = {{1, 1, 0, 0}, {1, 0, 1, 0}, {1, 0, 0, 1}};  // w, x, y, z: the x, z and y axes
    for (const auto& a : axes) {
      visualization_msgs::InteractiveMarkerControl control;
      control.orientation.w = a[0];
      control.orientation.x = a[1];
      control.orientation.y = a[2];
      control.orientation.z = a[3];
      control.interaction_mode = visualization_msgs::InteractiveMarkerControl::MOVE_AXIS;
      marker.controls.push_back(control);
    }
    markers_->insert(marker, [this](const visualization_msgs::InteractiveMarkerFeedbackConstPtr& f) {
      const std::lock_guard<std::mutex> lock(mutex_);
      for (const auto& arm : arms_) {
        if (arm->name == f->marker_name) {
          moveTo(*arm, Eigen::Vector3d(f->pose.position.x, f->pose.position.y, f->pose.position.z));
        }
      }
    });
  }

  bool onStart(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    const std::lock_guard<std::mutex> lock(mutex_);
    recorder_->clear();
    recording_ = true;
    response.success = true;
    response.message = "recording the tools' poses; ~save fits and writes them";
    return true;
  }

  bool onSave(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& response) {
    const std::lock_guard<std::mutex> lock(mutex_);
    recording_ = false;
    try {
      bs::primitives::DmpParameters parameters;
      parameters.kernels = kernels_;
      constexpr double kStep = 0.01, kStill = 0.003;
      const std::vector<bs::primitives::CartesianDmp> dmps = recorder_->fit(parameters, kStep, kStill);
      std::filesystem::create_directories(out_);
      std::string files;
      for (std::size_t i = 0; i < arms_.size(); ++i) {
        const std::string path = out_ + "/taught_" + arms_[i]->name + ".yaml";
        bs::primitives::saveCartesianDmp(
            dmps[i], path,
            "The cloth fold taught by teach_demonstration, " + arms_[i]->name +
                " tool, world frame; tasks::ClothFoldConfig::demonstration_files reads it.");
        files += (files.empty() ? "" : ", ") + path;
      }
      std::ofstream csv(out_ + "/taught_poses.csv");
      csv << "tool,t,x,y,z,qw,qx,qy,qz\n";
      const auto paths = recorder_->resampled(kStep, kStill);
      for (std::size_t i = 0; i < paths.size(); ++i) {
        for (std::size_t k = 0; k < paths[i].size(); ++k) {
          const bs::primitives::Pose& p = paths[i][k];
          csv << arms_[i]->name << ',' << kStep * static_cast<double>(k) << ',' << p.position.x() << ','
              << p.position.y() << ',' << p.position.z() << ',' << p.orientation.w() << ',' << p.orientation.x() << ','
              << p.orientation.y() << ',' << p.orientation.z() << '\n';
        }
      }
      char text[64];
      std::snprintf(text, sizeof text, "%.2f s taught, ", dmps.front().duration());
      response.success = true;
      response.message = std::string(text) + "written to " + files;
      ROS_INFO("teach_demonstration: %s", response.message.c_str());
    } catch (const std::exception& e) {
      response.message = e.what();
    }
    return true;
  }

  bool onGrasp(std_srvs::SetBool::Request& request, std_srvs::SetBool::Response& response) {
    response.success = true;
    for (const auto& arm : arms_) {
      bimanual_skills::ClothGrasp grasp;
      grasp.request.arm = arm->name;
      grasp.request.grasp = request.data;
      const auto outcome = caller_->call(grasp_, grasp, timeout_);
      const bool ok = outcome == bs::ros_layer::CallOutcome::Answered && grasp.response.success;
      response.success = response.success && ok;
      const std::string why = outcome != bs::ros_layer::CallOutcome::Answered ? bs::ros_layer::describe(outcome)
                              : ok                                            ? (request.data ? "grasped" : "released")
                                                                              : grasp.response.message;
      response.message += arm->name + ": " + why + "; ";
    }
    return true;
  }

  ros::NodeHandle node_, private_node_;
  bs::ros_layer::ParameterReader parameters_;
  std::vector<std::unique_ptr<Arm>> arms_;
  std::unique_ptr<bs::primitives::DemonstrationRecorder> recorder_;
  std::unique_ptr<interactive_markers::InteractiveMarkerServer> markers_;
  ros::Subscriber states_;
  std::string grasp_;  ///< The gripper's service.
  std::unique_ptr<bs::ros_layer::ServiceCaller> caller_;
  std::vector<ros::ServiceServer> services_;
  std::mutex mutex_;
  std::string out_, world_;
  double timeout_ = 5.0;
  int kernels_ = 20;
  bool teleoperation_ = true, recording_ = false;
};

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bs::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "teach_demonstration");
  try {
    TeachNode node;
    if (!node.start()) return 1;
    ros::AsyncSpinner spinner(2);
    spinner.start();
    ros::waitForShutdown();
  } catch (const std::exception& e) {
    ROS_FATAL("teach_demonstration: %s", e.what());
    return 1;
  }
  return 0;
}
