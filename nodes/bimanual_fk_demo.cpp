// bimanual_fk_demo: commands a joint configuration to each arm of the bimanual model (on /joint_states), prints
// both arms' forward kinematics from the core library, and checks them against the transforms that
// robot_state_publisher derives from the same robot_description. Exits (0 on agreement) unless ~hold is true.
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "cli/pinned_numerics.hpp"

#include "bimanual_skills/ros_layer/parameters.hpp"
#include "bimanual_skills/sim/robot_file.hpp"
#include "joint_state_publishing.hpp"
#include "node_cli.hpp"

#include <ros/package.h>
#include <ros/ros.h>
#include <sensor_msgs/JointState.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/transform_listener.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace bk = bimanual_skills::kinematics;

namespace {

struct Arm {
  std::string name;
  std::string tip;  ///< Its tool link (the robot file's).
  std::unique_ptr<bk::ChainModel> model;
  std::unique_ptr<bk::ChainData> data;
  Eigen::VectorXd q;
};

std::string formatVector(const Eigen::Ref<const Eigen::VectorXd>& v, int precision = 4) {
  std::string out = "[";
  char buffer[32];
  for (int i = 0; i < v.size(); ++i) {
    std::snprintf(buffer, sizeof(buffer), "%s%.*f", i ? ", " : "", precision, v[i]);
    out += buffer;
  }
  return out + "]";
}

/// Parses "[a, b, c]" (roscpp hands `_name:=[...]` command-line parameters over as strings).
std::vector<double> parseNumberList(const std::string& name, std::string text) {
  for (char& c : text) {
    if (c == '[' || c == ']' || c == ',') c = ' ';
  }
  std::istringstream stream(text);
  std::vector<double> out;
  std::string token;
  while (stream >> token) {
    char* end = nullptr;
    const double x = std::strtod(token.c_str(), &end);
    if (end == token.c_str() || *end != '\0') {
      throw std::invalid_argument("~" + name + ": '" + token + "' is not a number");
    }
    out.push_back(x);
  }
  return out;
}

/// Reads a private list-of-numbers parameter (a list of integers or reals, or its text). Absent: returns false.
/// Present but not such a list: throws std::invalid_argument naming the parameter.
bool readNumberList(const ros::NodeHandle& node, const std::string& name, std::vector<double>& out) {
  XmlRpc::XmlRpcValue value;
  if (!node.getParam(name, value)) return false;
  if (value.getType() == XmlRpc::XmlRpcValue::TypeString) {
    out = parseNumberList(name, static_cast<std::string>(value));
    return true;
  }
  if (value.getType() != XmlRpc::XmlRpcValue::TypeArray) {
    throw std::invalid_argument("~" + name + " must be a list of numbers");
  }
  out.clear();
  for (int i = 0; i < value.size(); ++i) {
    XmlRpc::XmlRpcValue& item = value[i];
    if (item.getType() == XmlRpc::XmlRpcValue::TypeInt) {
      out.push_back(static_cast<int>(item));
    } else if (item.getType() == XmlRpc::XmlRpcValue::TypeDouble) {
      out.push_back(static_cast<double>(item));
    } else {
      throw std::invalid_argument("~" + name + "[" + std::to_string(i) + "] is not a number");
    }
  }
  return true;
}

/// Loads the arms named in ~arms from robot_description, their tips and default postures (their starts) from the
/// robot file; throws std::invalid_argument with a clear message.
std::vector<Arm> loadArms(const ros::NodeHandle& node, const std::vector<std::string>& names, const std::string& world,
                          const bimanual_skills::sim::RobotFile& robot) {
  std::string description;
  if (!ros::param::get("robot_description", description)) {
    throw std::invalid_argument("parameter 'robot_description' is not set");
  }
  std::vector<Arm> arms;
  for (const std::string& name : names) {
    const bimanual_skills::sim::RobotArm* file_arm = robot.arm(name);
    if (file_arm == nullptr) throw std::invalid_argument("the robot file " + robot.path + " has no arm '" + name + "'");
    Arm arm;
    arm.name = name;
    arm.tip = file_arm->tip_link;
    arm.model = std::make_unique<bk::ChainModel>(bk::ChainModel::fromUrdfString(description, world, arm.tip));
    arm.data = std::make_unique<bk::ChainData>(*arm.model);
    std::vector<double> q;
    if (!readNumberList(node, "q_" + name, q))
      q.assign(file_arm->start.data(), file_arm->start.data() + file_arm->start.size());
    arm.q = Eigen::Map<const Eigen::VectorXd>(q.data(), static_cast<Eigen::Index>(q.size()));
    if (!arm.model->withinLimits(arm.q)) {
      throw std::invalid_argument("~q_" + name + " must hold " + std::to_string(arm.model->nq()) +
                                  " finite values within the joint limits, got " + formatVector(arm.q));
    }
    if (bk::computeJacobian(*arm.model, *arm.data, arm.q) != bk::KinematicsStatus::Success) {
      throw std::invalid_argument("forward kinematics failed for arm '" + name + "'");
    }
    arms.push_back(std::move(arm));
  }
  return arms;
}

sensor_msgs::JointState jointStates(const std::vector<Arm>& arms) {
  sensor_msgs::JointState msg;
  for (const Arm& arm : arms) {
    for (const std::string& joint : arm.model->jointNames()) msg.name.push_back(joint);
    msg.position.insert(msg.position.end(), arm.q.data(), arm.q.data() + arm.q.size());
  }
  return msg;
}

}  // namespace

namespace {

const char* const kUsage = R"(usage: rosrun bimanual_skills bimanual_fk_demo [_param:=value ...]

Commands a joint configuration to each arm of the bimanual model on /joint_states, prints both arms' forward
kinematics from the core library and checks them against the tf that robot_state_publisher publishes from the
same robot_description. Exits 0 on agreement (unless ~hold is true). Run it with launch/bimanual_model.launch.

parameters (private, config/fk_demo.yaml): robot (the robot file: arms, tool links and default postures; default
the package's config/robots/wam.yaml), world_frame, arms (default the robot file's), q_<arm> (default its start),
publish_rate, tf_timeout, hold
reads: robot_description, tf        publishes: /joint_states
)";

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bimanual_skills::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "bimanual_fk_demo");
  ros::NodeHandle node("~");
  std::string world;
  double rate_hz = 50.0, tf_timeout = 5.0;
  bool hold = false;
  std::vector<Arm> arms;
  try {
    bimanual_skills::ros_layer::ParameterReader p(node, "bimanual_fk_demo");
    world = p.text("world_frame", "world");
    const bimanual_skills::sim::RobotFile robot = bimanual_skills::sim::RobotFile::fromYamlFile(
        p.text("robot", ros::package::getPath("bimanual_skills") + "/config/robots/wam.yaml"));
    std::vector<std::string> robot_arms;
    for (const bimanual_skills::sim::RobotArm& arm : robot.arms) robot_arms.push_back(arm.name);
    rate_hz = p.number("publish_rate", 50.0, 0.1, 1000.0);
    tf_timeout = p.number("tf_timeout", 5.0, 0.0, 600.0);
    hold = p.boolean("hold", false);
    const std::vector<std::string> names = p.texts("arms", robot_arms);
    for (const std::string& name : names) p.accept("q_" + name);  // read by loadArms
    p.warnUnknown();
    arms = loadArms(node, names, world, robot);
  } catch (const std::invalid_argument& e) {
    ROS_FATAL("bimanual_fk_demo: %s", e.what());
    return 2;
  }

  ros::NodeHandle root;
  ros::Publisher publisher = root.advertise<sensor_msgs::JointState>("joint_states", 1);
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  sensor_msgs::JointState msg = jointStates(arms);
  ros::Rate rate(rate_hz > 0.0 ? rate_hz : 50.0);

  std::printf("bimanual_fk_demo: forward kinematics of %zu arms in frame '%s' (core library, chain %s -> tool)\n",
              arms.size(), world.c_str(), world.c_str());
  bool all_agree = true;
  for (Arm& arm : arms) {
    const Eigen::Isometry3d& pose = arm.data->tipPose();
    const Eigen::Quaterniond rotation(pose.linear());
    std::printf("  %-5s q           = %s rad\n", arm.name.c_str(), formatVector(arm.q, 3).c_str());
    std::printf("        position    = %s m\n", formatVector(pose.translation()).c_str());
    std::printf("        orientation = %s (quaternion x y z w)\n", formatVector(rotation.coeffs()).c_str());
    std::printf("        manipulability %.4f, condition number %.2f\n", bk::manipulability(*arm.data),
                bk::conditionNumber(*arm.data));

    // The same frame as robot_state_publisher computes it from /joint_states.
    const std::string& tip_frame = arm.tip;
    const bool found = bimanual_skills::nodes::publishUntil(
        publisher, msg, rate, tf_timeout, [&] { return buffer.canTransform(world, tip_frame, ros::Time(0)); });
    if (!found) {
      std::printf("        tf %s -> %s: not received within %.1f s (is robot_state_publisher running?)\n",
                  world.c_str(), tip_frame.c_str(), tf_timeout);
      all_agree = false;
      continue;
    }
    const Eigen::Isometry3d tf = tf2::transformToEigen(buffer.lookupTransform(world, tip_frame, ros::Time(0)));
    const double difference = (tf.matrix() - pose.matrix()).cwiseAbs().maxCoeff();
    const bool agree = difference < 1e-6;
    all_agree = all_agree && agree;
    std::printf("        robot_state_publisher tf %s: max |difference| = %.2e\n", agree ? "agrees" : "DISAGREES",
                difference);
  }
  std::fflush(stdout);

  if (hold) bimanual_skills::nodes::publishUntilShutdown(publisher, msg, rate);
  return all_agree ? 0 : 1;
}
