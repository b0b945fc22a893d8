// bimanual_ik_demo: asks ik_server for a pose of each arm's tool (<arm>/solve_ik), commands the solutions on
// /joint_states, and checks the tool poses robot_state_publisher then publishes against the targets.
// Exits 0 when every arm was solved and reached its target within 1e-4 (m and rad), unless ~hold is true.
#include "bimanual_skills/SolveIk.h"
#include "cli/pinned_numerics.hpp"

#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/sim/robot_file.hpp"
#include "joint_state_publishing.hpp"
#include "node_cli.hpp"

#include <ros/package.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <tf2_ros/transform_listener.h>

#include <Eigen/Geometry>

#include <cstdio>
#include <map>
#include <string>
#include <vector>

namespace {

struct Arm {
  std::string name;
  std::string tool;  ///< Its tool link (the robot file's).
  geometry_msgs::PoseStamped target;
  sensor_msgs::JointState solution;
  bool solved = false;
};

/// ~target_<arm>: {position: [x, y, z], orientation: [x, y, z, w]}; false with a message if malformed.
bool readTarget(const ros::NodeHandle& node, const std::string& arm, const std::string& world,
                geometry_msgs::PoseStamped& out) {
  XmlRpc::XmlRpcValue value;
  if (!node.getParam("target_" + arm, value) || value.getType() != XmlRpc::XmlRpcValue::TypeStruct ||
      !value.hasMember("position") || !value.hasMember("orientation") || value["position"].size() != 3 ||
      value["orientation"].size() != 4) {
    ROS_FATAL("bimanual_ik_demo: ~target_%s must be {position: [x, y, z], orientation: [x, y, z, w]}", arm.c_str());
    return false;
  }
  const auto number = [](XmlRpc::XmlRpcValue& v) {
    return v.getType() == XmlRpc::XmlRpcValue::TypeInt ? static_cast<double>(static_cast<int>(v))
                                                       : static_cast<double>(v);
  };
  out.header.frame_id = world;
  out.pose.position.x = number(value["position"][0]);
  out.pose.position.y = number(value["position"][1]);
  out.pose.position.z = number(value["position"][2]);
  out.pose.orientation.x = number(value["orientation"][0]);
  out.pose.orientation.y = number(value["orientation"][1]);
  out.pose.orientation.z = number(value["orientation"][2]);
  out.pose.orientation.w = number(value["orientation"][3]);
  return true;
}

}  // namespace

namespace {

const char* const kUsage = R"(usage: rosrun bimanual_skills bimanual_ik_demo [_param:=value ...]

Asks ik_server for a pose of each arm's tool (<arm>/solve_ik), commands the solutions on /joint_states and
checks the tool poses robot_state_publisher then publishes against the targets. Exits 0 when every arm reached its
target within 1e-4 m and rad (unless ~hold is true). launch/demo.launch runs it with robot_state_publisher.

parameters (private, config/ik_demo.yaml): robot (the robot file: arms and tool links; default the package's
config/robots/wam.yaml), world_frame, arms (default the robot file's), target_<arm> {position, orientation}, method
  (empty: the server's default), timeout, tf_timeout, publish_rate, hold
calls: <arm>/solve_ik        publishes: /joint_states        reads: tf
)";

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bimanual_skills::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "bimanual_ik_demo");
  ros::NodeHandle node("~");
  ros::NodeHandle root;
  std::string world, method;
  double timeout = 0.05, tf_timeout = 5.0, rate_hz = 50.0;
  bool hold = false;
  std::vector<std::string> names;
  std::map<std::string, std::string> tools;
  try {
    bimanual_skills::ros_layer::ParameterReader p(node, "bimanual_ik_demo");
    world = p.text("world_frame", "world");
    method = p.text("method", "");  // empty: the server's default
    timeout = p.number("timeout", 0.05, 0.0, 60.0);
    tf_timeout = p.number("tf_timeout", 5.0, 0.0, 600.0);
    rate_hz = p.number("publish_rate", 50.0, 0.1, 1000.0);
    hold = p.boolean("hold", false);
    const bimanual_skills::sim::RobotFile robot = bimanual_skills::sim::RobotFile::fromYamlFile(
        p.text("robot", ros::package::getPath("bimanual_skills") + "/config/robots/wam.yaml"));
    for (const bimanual_skills::sim::RobotArm& arm : robot.arms) tools[arm.name] = arm.tip_link;
    std::vector<std::string> robot_arms;
    for (const bimanual_skills::sim::RobotArm& arm : robot.arms) robot_arms.push_back(arm.name);
    names = p.texts("arms", robot_arms);
    for (const std::string& name : names) {
      if (tools.count(name) == 0)
        throw std::invalid_argument("the robot file " + robot.path + " has no arm '" + name + "'");
    }
    for (const std::string& name : names) p.accept("target_" + name);  // read below
    p.warnUnknown();
  } catch (const std::invalid_argument& e) {
    ROS_FATAL("bimanual_ik_demo: %s", e.what());
    return 2;
  }

  std::vector<Arm> arms;
  for (const std::string& name : names) {
    Arm arm;
    arm.name = name;
    arm.tool = tools[name];
    if (!readTarget(node, name, world, arm.target)) return 2;
    arms.push_back(arm);
  }
  std::printf("bimanual_ik_demo: IK of %zu arms through ik_server (%s, %.0f ms per request), targets in '%s'\n",
              arms.size(), method.empty() ? "the server's default method" : method.c_str(), 1e3 * timeout,
              world.c_str());
  sensor_msgs::JointState command;
  for (Arm& arm : arms) {
    const std::string service = "/" + arm.name + "/solve_ik";
    if (!ros::service::waitForService(service, ros::Duration(10.0))) {
      std::printf("  %-5s %s is not available (is ik_server running?)\n", arm.name.c_str(), service.c_str());
      continue;
    }
    bimanual_skills::SolveIk srv;
    srv.request.target = arm.target;
    srv.request.method = method;
    srv.request.timeout = timeout;
    const ros::WallTime start = ros::WallTime::now();
    if (!ros::service::call(service, srv)) {
      std::printf("  %-5s call to %s failed\n", arm.name.c_str(), service.c_str());
      continue;
    }
    const double ms = 1e3 * (ros::WallTime::now() - start).toSec();
    const auto& p = arm.target.pose.position;
    std::printf("  %-5s target (%.3f, %.3f, %.3f): error_code %d, %s, residual %.1e, %.1f ms round trip\n",
                arm.name.c_str(), p.x, p.y, p.z, srv.response.error_code, srv.response.message.c_str(),
                srv.response.residual, ms);
    if (srv.response.error_code != bimanual_skills::SolveIk::Response::SUCCESS) continue;
    arm.solved = true;
    arm.solution = srv.response.solution;
    std::printf("        q = [");
    for (std::size_t i = 0; i < arm.solution.position.size(); ++i) {
      std::printf("%s%.3f", i ? ", " : "", arm.solution.position[i]);
    }
    std::printf("] rad\n");
    command.name.insert(command.name.end(), arm.solution.name.begin(), arm.solution.name.end());
    command.position.insert(command.position.end(), arm.solution.position.begin(), arm.solution.position.end());
  }

  // Command the solutions and read back the tool poses robot_state_publisher derives from them.
  ros::Publisher publisher = root.advertise<sensor_msgs::JointState>("joint_states", 1);
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  ros::Rate rate(rate_hz > 0.0 ? rate_hz : 50.0);
  bool all_reached = true;
  for (Arm& arm : arms) {
    if (!arm.solved) {
      all_reached = false;
      continue;
    }
    const std::string& tool = arm.tool;
    geometry_msgs::TransformStamped tf;
    const bool received = bimanual_skills::nodes::publishUntil(publisher, command, rate, tf_timeout, [&] {
      try {
        tf = buffer.lookupTransform(world, tool, ros::Time(0));
      } catch (const tf2::TransformException&) {
        return false;
      }
      // Until the transform reflects the commanded joints (a stale one still shows the zero pose).
      return std::abs(tf.transform.translation.x - arm.target.pose.position.x) < 1e-4 &&
             std::abs(tf.transform.translation.y - arm.target.pose.position.y) < 1e-4 &&
             std::abs(tf.transform.translation.z - arm.target.pose.position.z) < 1e-4;
    });
    const auto& o = arm.target.pose.orientation;
    const Eigen::Quaterniond want(o.w, o.x, o.y, o.z);
    const Eigen::Quaterniond got(tf.transform.rotation.w, tf.transform.rotation.x, tf.transform.rotation.y,
                                 tf.transform.rotation.z);
    const double angle = want.normalized().angularDistance(got.normalized());
    const bool reached = received && angle < 1e-4;
    all_reached = all_reached && reached;
    std::printf("  %-5s tf %s -> %s: (%.4f, %.4f, %.4f), orientation error %.1e rad: %s\n", arm.name.c_str(),
                world.c_str(), tool.c_str(), tf.transform.translation.x, tf.transform.translation.y,
                tf.transform.translation.z, angle, reached ? "target reached" : "TARGET NOT REACHED");
  }
  std::fflush(stdout);
  if (hold) bimanual_skills::nodes::publishUntilShutdown(publisher, command, rate);
  return all_reached ? 0 : 1;
}
