#include "bimanual_skills/sim/robot_file.hpp"

#include "bimanual_skills/kinematics/chain_model.hpp"
#include "io/yaml_io.hpp"

#include <cmath>
#include <set>
#include <stdexcept>

namespace bimanual_skills::sim {

namespace {

/// A list of `n` finite numbers ≥ 0 at `root[key]`.
Eigen::VectorXd readGains(const YAML::Node& root, const char* key, const std::string& where, int n) {
  const Eigen::VectorXd v = io::readVector(root, key, where, n);
  if ((v.array() < 0.0).any()) io::fail(where + ": '" + key + "' must be >= 0");
  return v;
}

}  // namespace

RobotFile RobotFile::fromYamlFile(const std::string& path) {
  const std::string where = "robot file '" + path + "'";
  const YAML::Node root = io::loadYamlFile(path, where);
  if (!root.IsMap()) io::fail(where + ": must be a map");
  io::checkKeys(root, where, {"name", "urdf", "plant", "rated_payload", "arms", "kp", "kv", "braking_damping"});
  RobotFile robot;
  robot.path = path;
  robot.name = io::readString(root, "name", where);
  robot.urdf_path = io::resolvePath(path, io::readString(root, "urdf", where));
  robot.plant_path = io::resolvePath(path, io::readString(root, "plant", where));
  robot.rated_payload = io::readDouble(root, "rated_payload", where);
  if (robot.rated_payload < 0.0 || robot.rated_payload > 1000.0) {
    io::fail(where + ": 'rated_payload' must lie in [0, 1000] kg");
  }
  const YAML::Node arms = root["arms"];
  if (!arms || !arms.IsSequence() || arms.size() == 0) io::fail(where + ": needs a non-empty list 'arms'");
  std::set<std::string> names;
  int joints = -1;
  for (std::size_t k = 0; k < arms.size(); ++k) {
    const std::string at = where + " arm " + std::to_string(k + 1);
    io::checkKeys(arms[k], at, {"name", "base_link", "tip_link", "start", "friction"});
    RobotArm arm;
    arm.name = io::readString(arms[k], "name", at);
    if (!names.insert(arm.name).second) io::fail(at + ": the name '" + arm.name + "' is taken by another arm");
    arm.base_link = io::readString(arms[k], "base_link", at);
    arm.tip_link = io::readString(arms[k], "tip_link", at);
    const std::string friction = arms[k]["friction"] ? io::readString(arms[k], "friction", at) : "";
    arm.friction_file = friction.empty() ? "" : io::resolvePath(path, friction);
    const kinematics::ChainModel chain = io::withContext(
        at + " (" + arm.base_link + " -> " + arm.tip_link + " in " + robot.urdf_path + ")",
        [&] { return kinematics::ChainModel::fromUrdfFile(robot.urdf_path, arm.base_link, arm.tip_link); });
    if (joints >= 0 && chain.nq() != joints) {
      io::fail(at + ": " + std::to_string(chain.nq()) + " joints where the first arm has " + std::to_string(joints) +
               " (the gains are per joint, for every arm)");
    }
    joints = chain.nq();
    arm.start = io::readVector(arms[k], "start", at, joints);
    if ((arm.start.array() < chain.lowerLimits().array()).any() ||
        (arm.start.array() > chain.upperLimits().array()).any()) {
      io::fail(at + ": 'start' lies outside the URDF's joint limits");
    }
    robot.arms.push_back(arm);
  }
  robot.kp = readGains(root, "kp", where, joints);
  robot.kv = readGains(root, "kv", where, joints);
  robot.braking_damping = readGains(root, "braking_damping", where, joints);
  return robot;
}

const RobotArm* RobotFile::arm(const std::string& name) const noexcept {
  for (const RobotArm& a : arms) {
    if (a.name == name) return &a;
  }
  return nullptr;
}

}  // namespace bimanual_skills::sim
