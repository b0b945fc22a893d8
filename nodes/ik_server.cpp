// ik_server: forward and inverse kinematics services for each arm of a robot description.
//   <arm>/solve_ik (bimanual_skills/SolveIk): global CLIK solver, MoveIt error codes
//   <arm>/solve_fk (bimanual_skills/SolveFk)
// Parameters (private): arms [{name, base_link, tip_link}] (or robot, a robot file that names them), method,
// default_timeout, max_timeout, max_attempts,
// tf_timeout; see config/ik_server.yaml. A thin shell: all kinematics is in the core library.
#include "bimanual_skills/SolveFk.h"
#include "bimanual_skills/SolveIk.h"
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "bimanual_skills/sim/robot_file.hpp"
#include "cli/pinned_numerics.hpp"

#include "bimanual_skills/ros_layer/parameters.hpp"
#include "node_cli.hpp"

#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_ros/transform_listener.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace bk = bimanual_skills::kinematics;
using bimanual_skills::SolveFk;
using bimanual_skills::SolveIk;

namespace {

struct Settings {
  std::string method = "ED";
  double default_timeout = 0.02;
  double max_timeout = 5.0;
  int max_attempts = 100000;
  double tf_timeout = 1.0;
};

/// A failed request: the error code and message to answer with.
struct RequestError {
  int code;
  std::string message;
};

/// Pose message to a rigid transform; rejects NaN/Inf and zero or unnormalised quaternions (|‖q‖ − 1| > 1e-3).
Eigen::Isometry3d checkedPose(const geometry_msgs::Pose& pose, int invalid_code) {
  const Eigen::Vector3d p(pose.position.x, pose.position.y, pose.position.z);
  const Eigen::Quaterniond q(pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z);
  if (!p.allFinite() || !q.coeffs().allFinite()) throw RequestError{invalid_code, "target pose contains NaN or Inf"};
  const double norm = q.norm();
  if (norm < 1e-9) throw RequestError{invalid_code, "target orientation is a zero quaternion"};
  if (std::abs(norm - 1.0) > 1e-3) {
    std::ostringstream message;
    message << "target orientation quaternion is not normalised (norm " << norm << ")";
    throw RequestError{invalid_code, message.str()};
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = p;
  T.linear() = q.normalized().toRotationMatrix();
  return T;
}

/// Joint positions of `model` from a JointState: by name (others default to `fallback`), or positions only in chain
/// order. `strict` (forward kinematics): every joint of the chain and no other. Otherwise (a seed) names of other
/// joints are skipped, so a whole /joint_states message of a two-arm robot seeds either arm, but at least one of the
/// chain's joints must be named.
Eigen::VectorXd jointVector(const bk::ChainModel& model, const sensor_msgs::JointState& state,
                            const Eigen::VectorXd& fallback, bool strict, int invalid_input) {
  const int n = model.nq();
  Eigen::VectorXd q = fallback;
  const std::vector<std::string> names = model.jointNames();
  if (!strict && state.name.empty() && state.position.empty()) return q;
  if (state.name.empty()) {
    if (static_cast<int>(state.position.size()) != n) {
      throw RequestError{SolveIk::Response::INVALID_ROBOT_STATE, "joint state has " +
                                                                     std::to_string(state.position.size()) +
                                                                     " positions and no names; the "
                                                                     "chain has " +
                                                                     std::to_string(n) + " joints"};
    }
    for (int i = 0; i < n; ++i) q[i] = state.position[static_cast<std::size_t>(i)];
  } else {
    if (state.name.size() != state.position.size()) {
      throw RequestError{SolveIk::Response::INVALID_ROBOT_STATE,
                         "joint state has " + std::to_string(state.name.size()) + " names but " +
                             std::to_string(state.position.size()) + " positions"};
    }
    int found = 0;
    for (std::size_t k = 0; k < state.name.size(); ++k) {
      const auto it = std::find(names.begin(), names.end(), state.name[k]);
      if (it == names.end()) {
        if (!strict) continue;
        throw RequestError{
            SolveIk::Response::INVALID_ROBOT_STATE,
            "joint '" + state.name[k] + "' is not in the chain " + model.baseLink() + " -> " + model.tipLink()};
      }
      q[it - names.begin()] = state.position[k];
      ++found;
    }
    if (!strict && found == 0) {
      throw RequestError{SolveIk::Response::INVALID_ROBOT_STATE,
                         "the seed names none of the chain's joints (" + names.front() + ", ...)"};
    }
    if (strict && found != n) {
      throw RequestError{
          SolveIk::Response::INVALID_ROBOT_STATE,
          "joint state names " + std::to_string(found) + " of the chain's " + std::to_string(n) + " joints"};
    }
  }
  if (!q.allFinite()) throw RequestError{invalid_input, "joint positions contain NaN or Inf"};
  return q;
}

/// One arm's services, on a callback queue and thread of their own: a long request on one arm never delays
/// another arm's. Requests to the same arm are answered in turn.
class ArmServices {
 public:
  ArmServices(std::string name, std::string base, std::string tip, const std::string& description,
              const Settings& settings, tf2_ros::Buffer& tf, const ros::NodeHandle& node)
      : name_(std::move(name)),
        base_(std::move(base)),
        tip_(std::move(tip)),
        description_(description),
        settings_(settings),
        tf_(tf),
        node_(node),
        spinner_(1, &queue_) {
    solver(tip_, settings_.method);  // load the configured chain now: configuration errors surface at start-up
    node_.setCallbackQueue(&queue_);
    ik_ = node_.advertiseService(name_ + "/solve_ik", &ArmServices::solveIk, this);
    fk_ = node_.advertiseService(name_ + "/solve_fk", &ArmServices::solveFk, this);
    spinner_.start();
  }
  ~ArmServices() {
    spinner_.stop();
    ik_.shutdown();
    fk_.shutdown();
  }

  std::string describe() const {
    return ik_.getService() + ", " + fk_.getService() + " (" + base_ + " -> " + tip_ + ")";
  }

 private:
  /// The global solver for a tip, method and mode, built on first use. Throws RequestError for unknown
  /// links, methods or modes.
  bk::GlobalIkSolver& solver(const std::string& tip, const std::string& method, const std::string& mode = "first") {
    const std::string key = tip + '\n' + method + '\n' + mode;
    auto it = solvers_.find(key);
    if (it != solvers_.end()) return *it->second;
    bk::GlobalIkParameters parameters;
    if (!bk::parseMethodName(method, parameters.local.inverse, parameters.local.limits)) {
      std::string known;
      for (const std::string& name : bk::methodNames()) known += (known.empty() ? "" : ", ") + name;
      throw RequestError{SolveIk::Response::INVALID_INPUT, "unknown method '" + method + "' (" + known + ")"};
    }
    if (mode == "first") {
      parameters.mode = bk::SolutionMode::FirstFound;
    } else if (mode == "closest") {
      parameters.mode = bk::SolutionMode::ClosestToSeed;
    } else if (mode == "all") {
      parameters.mode = bk::SolutionMode::AllDistinct;
    } else {
      throw RequestError{SolveIk::Response::INVALID_INPUT, "unknown mode '" + mode + "' (first, closest, all)"};
    }
    parameters.timeout = settings_.default_timeout;
    parameters.max_attempts = settings_.max_attempts;
    try {
      parameters.validate();
      auto model = bk::ChainModel::fromUrdfString(description_, base_, tip);
      it = solvers_.emplace(key, std::make_unique<bk::GlobalIkSolver>(model, parameters)).first;
    } catch (const std::invalid_argument& e) {
      throw RequestError{SolveIk::Response::INVALID_LINK_NAME, e.what()};
    }
    return *it->second;
  }

  /// Transform from `frame` to the chain base (identity when frame is empty or the base itself).
  Eigen::Isometry3d baseFrom(const std::string& frame) const {
    if (frame.empty() || frame == base_) return Eigen::Isometry3d::Identity();
    try {
      return tf2::transformToEigen(
          tf_.lookupTransform(base_, frame, ros::Time(0), ros::Duration(settings_.tf_timeout)));
    } catch (const tf2::TransformException& e) {
      throw RequestError{SolveIk::Response::FRAME_TRANSFORM_FAILURE,
                         "no transform from '" + frame + "' to '" + base_ + "': " + e.what()};
    }
  }

  bool solveIk(SolveIk::Request& request, SolveIk::Response& response) {
    try {
      const std::string tip = request.tip_link.empty() ? tip_ : request.tip_link;
      const std::string method = request.method.empty() ? settings_.method : request.method;
      const std::string mode = request.mode.empty() ? "first" : request.mode;
      bk::GlobalIkSolver& global = solver(tip, method, mode);
      const bk::ChainModel& model = global.model();
      std::string note;
      double timeout = request.timeout;
      if (!std::isfinite(timeout) || timeout < 0.0) {
        throw RequestError{SolveIk::Response::INVALID_INPUT, "timeout must be a finite number >= 0 (0: default)"};
      }
      if (timeout == 0.0) timeout = settings_.default_timeout;
      if (timeout > settings_.max_timeout) {
        note = " (timeout capped at max_timeout " + std::to_string(settings_.max_timeout) + " s)";
        timeout = settings_.max_timeout;
      }
      const Eigen::Isometry3d target_in_frame = checkedPose(request.target.pose, SolveIk::Response::INVALID_INPUT);
      const Eigen::Isometry3d target = baseFrom(request.target.header.frame_id) * target_in_frame;
      const Eigen::VectorXd middle = 0.5 * (model.lowerLimits() + model.upperLimits());
      const Eigen::VectorXd seed = jointVector(model, request.seed, middle, false, SolveIk::Response::INVALID_INPUT);
      for (int i = 0; i < model.nq(); ++i) {
        if (seed[i] < model.lowerLimits()[i] - 1e-9 || seed[i] > model.upperLimits()[i] + 1e-9) {
          std::ostringstream message;
          message << "seed of joint '" << model.joints()[static_cast<std::size_t>(i)].name << "' = " << seed[i]
                  << " is outside its limits [" << model.lowerLimits()[i] << ", " << model.upperLimits()[i] << "]";
          throw RequestError{SolveIk::Response::INVALID_ROBOT_STATE, message.str()};
        }
      }
      response.solution.header.stamp = ros::Time::now();
      response.solution.name = model.jointNames();
      const double distance = (target.translation() - model.firstJointOrigin()).norm();
      if (distance > model.reachBound()) {
        std::ostringstream message;
        message << "target is " << distance << " m from the first joint, beyond the chain's reach ("
                << model.reachBound() << " m)";
        response.solution.position.assign(seed.data(), seed.data() + seed.size());
        response.residual = distance - model.reachBound();
        response.error_code = SolveIk::Response::NO_IK_SOLUTION;
        response.message = message.str();
        return true;
      }
      Eigen::VectorXd q(model.nq());
      const bk::GlobalIkResult result = global.solve(target, seed, q, timeout);
      response.solution.position.assign(q.data(), q.data() + q.size());
      if (global.parameters().mode == bk::SolutionMode::AllDistinct && result.status == bk::IkStatus::Converged) {
        for (int i = 0; i < global.solutionCount(); ++i) {
          sensor_msgs::JointState other = response.solution;
          other.position.assign(global.solution(i).data(), global.solution(i).data() + global.solution(i).size());
          response.solutions.push_back(other);
        }
      }
      response.residual = result.residual;
      response.iterations = result.iterations;
      switch (result.status) {
        case bk::IkStatus::Converged:
          response.error_code = SolveIk::Response::SUCCESS;
          break;
        case bk::IkStatus::Timeout:
          response.error_code = SolveIk::Response::TIMED_OUT;
          break;
        case bk::IkStatus::MaxIterations:
          response.error_code = SolveIk::Response::NO_IK_SOLUTION;
          break;
        default:
          response.error_code = SolveIk::Response::INVALID_INPUT;
      }
      response.message =
          std::string(method) + ": " + bk::toString(result.status) + " after " + std::to_string(result.attempts) +
          " attempt(s)" +
          (response.solutions.empty() ? ""
                                      : ", " + std::to_string(response.solutions.size()) + " distinct solution(s)") +
          note;
    } catch (const RequestError& error) {
      response.error_code = error.code;
      response.message = error.message;
      ROS_DEBUG("%s/solve_ik: %s", name_.c_str(), error.message.c_str());
    }
    return true;
  }

  bool solveFk(SolveFk::Request& request, SolveFk::Response& response) {
    try {
      const std::string tip = request.tip_link.empty() ? tip_ : request.tip_link;
      const bk::ChainModel& model = solver(tip, settings_.method).model();
      const Eigen::VectorXd q = jointVector(model, request.joint_state, Eigen::VectorXd::Zero(model.nq()), true,
                                            SolveFk::Response::INVALID_INPUT);
      bk::ChainData data(model);
      if (bk::forwardKinematics(model, data, q) != bk::KinematicsStatus::Success) {
        throw RequestError{SolveFk::Response::INVALID_INPUT, "forward kinematics rejected the joint positions"};
      }
      const std::string frame = request.frame_id.empty() ? base_ : request.frame_id;
      response.pose.header.frame_id = frame;
      response.pose.header.stamp = ros::Time::now();
      response.pose.pose = tf2::toMsg(Eigen::Isometry3d(baseFrom(frame).inverse() * data.tipPose()));
      response.error_code = SolveFk::Response::SUCCESS;
      response.message = "pose of '" + tip + "' in '" + frame + "'";
    } catch (const RequestError& error) {
      response.error_code = error.code;
      response.message = error.message;
    }
    return true;
  }

  std::string name_, base_, tip_;
  const std::string& description_;
  const Settings& settings_;
  tf2_ros::Buffer& tf_;
  std::map<std::string, std::unique_ptr<bk::GlobalIkSolver>> solvers_;
  ros::NodeHandle node_;
  ros::CallbackQueue queue_;
  ros::AsyncSpinner spinner_;
  ros::ServiceServer ik_, fk_;
};

}  // namespace

namespace {

const char* const kUsage = R"(usage: rosrun bimanual_skills ik_server [_param:=value ...]

Inverse and forward kinematics services for each arm of robot_description: <arm>/solve_ik
(bimanual_skills/SolveIk: the global CLIK solver, modes first/closest/all, any of the thesis' methods by name,
MoveIt error codes) and <arm>/solve_fk (bimanual_skills/SolveFk). Start it with launch/ik_server.launch.

parameters (private, config/ik_server.yaml): arms [{name, base_link, tip_link}] (default: those of robot, a robot
file, config/robots/*.yaml), method (default ED),
  default_timeout, max_timeout, max_attempts, tf_timeout
reads: robot_description, tf
example: rosservice call /left/solve_ik "{target: {header: {frame_id: world}, pose: {position: {x: 0.55, y: 0.25,
  z: 0.3}, orientation: {x: 1.0, y: 0.0, z: 0.0, w: 0.0}}}}"
)";

}  // namespace

int main(int argc, char** argv) {
  bimanual_skills::cli::pinNumerics(argv);
  bimanual_skills::nodes::handleCommandLine(argc, argv, kUsage);
  ros::init(argc, argv, "ik_server");
  ros::NodeHandle node;
  ros::AsyncSpinner global(1);  // the parameter and logging callbacks; each arm's services spin on their own
  global.start();
  ros::NodeHandle private_node("~");
  Settings settings;
  std::string robot_path;
  bimanual_skills::ros_layer::ParameterReader parameters(private_node, "ik_server");
  try {
    settings.method = parameters.text("method", settings.method, bk::methodNames());
    settings.default_timeout = parameters.number("default_timeout", settings.default_timeout, 1e-6, 3600.0);
    settings.max_timeout = parameters.number("max_timeout", settings.max_timeout, settings.default_timeout, 3600.0);
    settings.max_attempts = parameters.integer("max_attempts", settings.max_attempts, 1);
    settings.tf_timeout = parameters.number("tf_timeout", settings.tf_timeout, 0.0, 60.0);
    parameters.accept("arms");
    robot_path = parameters.text("robot", "");
    parameters.warnUnknown();
  } catch (const std::invalid_argument& e) {
    ROS_FATAL("ik_server: %s", e.what());
    return 2;
  }
  std::string description;
  if (!ros::param::get("robot_description", description)) {
    ROS_FATAL("ik_server: parameter 'robot_description' is not set");
    return 2;
  }
  // The arms: ~arms when set, else the robot file's.
  XmlRpc::XmlRpcValue arms;
  if (!private_node.hasParam("arms") && !robot_path.empty()) {
    try {
      const bimanual_skills::sim::RobotFile robot = bimanual_skills::sim::RobotFile::fromYamlFile(robot_path);
      arms.setSize(static_cast<int>(robot.arms.size()));
      for (std::size_t a = 0; a < robot.arms.size(); ++a) {
        arms[static_cast<int>(a)]["name"] = robot.arms[a].name;
        arms[static_cast<int>(a)]["base_link"] = robot.arms[a].base_link;
        arms[static_cast<int>(a)]["tip_link"] = robot.arms[a].tip_link;
      }
    } catch (const std::invalid_argument& e) {
      ROS_FATAL("ik_server: ~robot: %s", e.what());
      return 2;
    }
  } else if (!private_node.getParam("arms", arms) || arms.getType() != XmlRpc::XmlRpcValue::TypeArray ||
             arms.size() == 0) {
    ROS_FATAL("ik_server: ~arms must be a non-empty list of {name, base_link, tip_link} (or give ~robot)");
    return 2;
  }
  tf2_ros::Buffer tf;
  tf2_ros::TransformListener listener(tf);
  std::vector<std::unique_ptr<ArmServices>> services;
  try {
    for (int i = 0; i < arms.size(); ++i) {
      XmlRpc::XmlRpcValue& arm = arms[i];
      for (const char* key : {"name", "base_link", "tip_link"}) {
        if (arm.getType() != XmlRpc::XmlRpcValue::TypeStruct || !arm.hasMember(key) ||
            arm[key].getType() != XmlRpc::XmlRpcValue::TypeString) {
          throw std::invalid_argument("~arms[" + std::to_string(i) + "] needs a string '" + key + "'");
        }
      }
      services.push_back(std::make_unique<ArmServices>(
          static_cast<std::string>(arm["name"]), static_cast<std::string>(arm["base_link"]),
          static_cast<std::string>(arm["tip_link"]), description, settings, tf, node));
      ROS_INFO("ik_server: %s", services.back()->describe().c_str());
    }
  } catch (const std::invalid_argument& e) {
    ROS_FATAL("ik_server: %s", e.what());
    return 2;
  } catch (const RequestError& e) {
    ROS_FATAL("ik_server: %s", e.message.c_str());
    return 2;
  }
  ROS_INFO("ik_server: ready (method %s, default timeout %.3f s)", settings.method.c_str(), settings.default_timeout);
  ros::waitForShutdown();
  return 0;
}
