#include "bimanual_skills/sim/robot_file.hpp"

#include "bimanual_skills/dynamics/rigid_body_dynamics.hpp"
#include "bimanual_skills/kinematics/chain_kinematics.hpp"
#include "bimanual_skills/kinematics/global_ik.hpp"
#include "bimanual_skills/sim/sim_config.hpp"
#include "bullet_arm.hpp"
#include "io/yaml_io.hpp"

#include <cmath>
#include <iomanip>
#include <set>
#include <sstream>
#include <stdexcept>

namespace bimanual_skills::sim {

namespace {

/// Attempts of postureFromToolPose's search: enough to find every distinct solution branch of a 7-DoF arm's pose
/// many times over (never the time budget: the same answer under any load).
constexpr int kPostureAttempts = 200;

/// A list of `n` finite numbers ≥ 0 at `root[key]`.
Eigen::VectorXd readGains(const YAML::Node& root, const char* key, const std::string& where, int n) {
  const Eigen::VectorXd v = io::readVector(root, key, where, n);
  if ((v.array() < 0.0).any()) io::fail(where + ": '" + key + "' must be >= 0");
  return v;
}

std::string jointName(const kinematics::ChainModel& model, int i) {
  return "joint '" + model.jointNames()[static_cast<std::size_t>(i)] + "'";
}

std::string format(double x) {
  std::ostringstream out;
  out << std::setprecision(3) << x;
  return out.str();
}

/// Runs `derive` for entry `key` of `where`: a failure names the entry and what to give instead.
template <typename Derive>
auto derivedEntry(const std::string& where, const std::string& key, const std::string& instead, Derive derive) {
  try {
    return derive();
  } catch (const std::invalid_argument& e) {
    io::fail(where + ": no '" + key + "' and none derived from the model (" + e.what() + "): give " + instead);
  }
}

}  // namespace

void gainsFromBandwidth(const kinematics::ChainModel& model, const Eigen::VectorXd& q, const Eigen::VectorXd& hz,
                        double zeta, Eigen::VectorXd& kp, Eigen::VectorXd& kv) {
  if (hz.size() != model.nq() || !hz.allFinite() || (hz.array() <= 0.0).any() || !std::isfinite(zeta) || zeta <= 0.0) {
    throw std::invalid_argument("the bandwidth needs " + std::to_string(model.nq()) +
                                " finite values > 0 and the damping ratio a finite value > 0");
  }
  dynamics::DynamicsData data(model);
  if (dynamics::massMatrix(model, data, q) != dynamics::DynamicsStatus::Success) {
    throw std::invalid_argument("no mass matrix at the posture given");
  }
  kp.resize(model.nq());
  kv.resize(model.nq());
  for (int i = 0; i < model.nq(); ++i) {
    const double inertia = data.mass_matrix(i, i), omega = 2.0 * M_PI * hz[i];
    if (!std::isfinite(inertia) || inertia <= 0.0) {
      throw std::invalid_argument(jointName(model, i) + " moves no inertia in the URDF");
    }
    kp[i] = inertia * omega * omega;
    kv[i] = 2.0 * zeta * inertia * omega;
  }
}

Eigen::VectorXd brakingFromLimits(const kinematics::ChainModel& model) {
  Eigen::VectorXd damping(model.nq());
  for (int i = 0; i < model.nq(); ++i) {
    const double effort = model.effortLimits()[i], velocity = model.velocityLimits()[i];
    if (!std::isfinite(effort) || effort <= 0.0 || !std::isfinite(velocity) || velocity <= 0.0) {
      throw std::invalid_argument(jointName(model, i) + " has no effort or velocity limit in the URDF");
    }
    damping[i] = effort / (2.0 * velocity);
  }
  return damping;
}

double payloadFromEfforts(const kinematics::ChainModel& model, const Eigen::VectorXd& q) {
  dynamics::DynamicsData data(model);
  Eigen::VectorXd own(model.nq()), loaded(model.nq());
  dynamics::Payload kilogram;
  kilogram.mass = 1.0;
  if (dynamics::gravityTorques(model, data, q, own) != dynamics::DynamicsStatus::Success ||
      dynamics::gravityTorques(model, data, q, loaded, kilogram) != dynamics::DynamicsStatus::Success) {
    throw std::invalid_argument("no gravity torques at the posture given");
  }
  const double weight = model.gravity().norm();
  double payload = std::numeric_limits<double>::infinity();
  for (int i = 0; i < model.nq(); ++i) {
    const double effort = model.effortLimits()[i];
    if (!std::isfinite(effort) || effort <= 0.0) {
      throw std::invalid_argument(jointName(model, i) + " has no effort limit in the URDF");
    }
    const double budget = 0.5 * effort - std::abs(own[i]);
    if (budget <= 0.0) {
      throw std::invalid_argument(jointName(model, i) + " needs " + format(std::abs(own[i])) +
                                  " N m to hold the arm, more than half its effort limit " + format(effort));
    }
    const double per_kilogram = std::abs(loaded[i] - own[i]);
    if (per_kilogram > 1e-6 * weight) payload = std::min(payload, budget / per_kilogram);
  }
  if (!std::isfinite(payload)) throw std::invalid_argument("no joint carries a weight at the tool");
  return payload;
}

Eigen::VectorXd postureFromToolPose(const kinematics::ChainModel& model, const Eigen::Isometry3d& tool_in_base) {
  kinematics::GlobalIkParameters parameters;
  parameters.mode = kinematics::SolutionMode::AllDistinct;
  parameters.max_attempts = kPostureAttempts;
  parameters.timeout = 60.0;  // never binding: the attempts end the search
  parameters.distinct_tolerance = 0.05;
  kinematics::GlobalIkSolver solver(model, parameters);
  const Eigen::VectorXd middle = kinematics::middleOfLimits(model);
  Eigen::VectorXd q = middle;
  (void)solver.solve(tool_in_base, middle, q);
  if (solver.solutionCount() == 0) {
    throw std::invalid_argument("global IK found no posture within the joint limits for the tool pose");
  }
  // Unlimited joints count a full turn either way.
  const Eigen::ArrayXd lower = model.lowerLimits().array().max(-M_PI), upper = model.upperLimits().array().min(M_PI);
  const Eigen::ArrayXd range = upper - lower;
  double best = std::numeric_limits<double>::infinity();
  for (int s = 0; s < solver.solutionCount(); ++s) {
    const double distance = ((solver.solution(s).array() - middle.array()) / range).square().sum();
    if (distance < best) {
      best = distance;
      q = solver.solution(s);
    }
  }
  return q;
}

RobotFile RobotFile::fromYamlFile(const std::string& path) {
  const std::string where = "robot file '" + path + "'";
  const YAML::Node root = io::loadYamlFile(path, where);
  if (!root.IsMap()) io::fail(where + ": must be a map");
  io::checkKeys(
      root, where,
      {"name", "urdf", "plant", "rated_payload", "arms", "kp", "kv", "bandwidth", "damping_ratio", "braking_damping"});
  RobotFile robot;
  robot.path = path;
  robot.name = io::readString(root, "name", where);
  robot.urdf_path = io::resolvePath(path, io::readString(root, "urdf", where));
  robot.plant_path = io::resolvePath(path, io::readString(root, "plant", where));
  const YAML::Node arms = root["arms"];
  if (!arms || !arms.IsSequence() || arms.size() == 0) io::fail(where + ": needs a non-empty list 'arms'");
  std::set<std::string> names;
  std::vector<kinematics::ChainModel> chains;
  int joints = -1;
  for (std::size_t k = 0; k < arms.size(); ++k) {
    const std::string at = where + " arm " + std::to_string(k + 1);
    io::checkKeys(arms[k], at, {"name", "base_link", "tip_link", "start", "start_tool", "ik_seed", "friction"});
    RobotArm arm;
    arm.name = io::readString(arms[k], "name", at);
    if (!names.insert(arm.name).second) io::fail(at + ": the name '" + arm.name + "' is taken by another arm");
    arm.base_link = io::readString(arms[k], "base_link", at);
    arm.tip_link = io::readString(arms[k], "tip_link", at);
    const std::string friction = arms[k]["friction"] ? io::readString(arms[k], "friction", at) : "";
    arm.friction_file = friction.empty() ? "" : io::resolvePath(path, friction);
    // The chain with gravity in its base frame (the base may stand tilted in the world).
    const UrdfArm urdf =
        io::withContext(at + " (" + arm.base_link + " -> " + arm.tip_link + " in " + robot.urdf_path + ")", [&] {
          return loadUrdfArm(robot.urdf_path, {arm.name, arm.base_link, arm.tip_link, {}, "", {}}, SimConfig{}.gravity);
        });
    const kinematics::ChainModel& chain = chains.emplace_back(urdf.model);
    if (joints >= 0 && chain.nq() != joints) {
      io::fail(at + ": " + std::to_string(chain.nq()) + " joints where the first arm has " + std::to_string(joints) +
               " (the gains are per joint, for every arm)");
    }
    joints = chain.nq();
    if (arms[k]["start"] && arms[k]["start_tool"]) io::fail(at + ": give 'start' or 'start_tool', not both");
    if (arms[k]["start"]) {
      arm.start = io::readVector(arms[k], "start", at, joints);
    } else if (arms[k]["start_tool"]) {
      const Eigen::Isometry3d tool = io::readPose(arms[k]["start_tool"], at + " start_tool");
      arm.start = derivedEntry(at, "start", "'start' (joint positions) or a reachable 'start_tool'",
                               [&] { return postureFromToolPose(chain, urdf.base_pose.inverse() * tool); });
      robot.derived.push_back("the start of '" + arm.name + "': global IK on its start_tool");
    } else {
      io::fail(at + ": needs 'start' (joint positions) or 'start_tool' ({xyz, rpy} of the tool in the world frame, " +
               "solved by global IK)");
    }
    if ((arm.start.array() < chain.lowerLimits().array()).any() ||
        (arm.start.array() > chain.upperLimits().array()).any()) {
      io::fail(at + ": 'start' lies outside the URDF's joint limits");
    }
    arm.ik_seed = arms[k]["ik_seed"] ? io::readVector(arms[k], "ik_seed", at, joints) : arm.start;
    robot.arms.push_back(arm);
  }

  if (root["kp"] || root["kv"]) {
    if (root["bandwidth"]) io::fail(where + ": give 'kp' and 'kv', or a 'bandwidth', not both");
    robot.kp = readGains(root, "kp", where, joints);
    robot.kv = readGains(root, "kv", where, joints);
  } else if (root["bandwidth"]) {
    const Eigen::VectorXd hz = root["bandwidth"].IsScalar()
                                   ? Eigen::VectorXd::Constant(joints, io::readDouble(root, "bandwidth", where))
                                   : io::readVector(root, "bandwidth", where, joints);
    const double zeta = io::readDouble(root, "damping_ratio", where, 1.0);
    derivedEntry(where, "kp", "'kp' and 'kv'", [&] {
      gainsFromBandwidth(chains.front(), robot.arms.front().start, hz, zeta, robot.kp, robot.kv);
      return 0;
    });
    robot.derived.push_back("kp, kv: a bandwidth of " + format(hz.minCoeff()) + "-" + format(hz.maxCoeff()) +
                            " Hz, damping ratio " + format(zeta) + ", at the first arm's start");
  } else {
    io::fail(where + ": needs 'kp' and 'kv' [per joint], or a 'bandwidth' [Hz] to derive them from the inertias");
  }
  if (root["damping_ratio"] && !root["bandwidth"]) io::fail(where + ": 'damping_ratio' goes with 'bandwidth'");

  if (root["braking_damping"]) {
    robot.braking_damping = readGains(root, "braking_damping", where, joints);
  } else {
    robot.braking_damping = derivedEntry(where, "braking_damping", "'braking_damping' [N m s/rad per joint]",
                                         [&] { return brakingFromLimits(chains.front()); });
    robot.derived.push_back("braking_damping: half the effort limit at the velocity limit");
  }

  if (root["rated_payload"]) {
    robot.rated_payload = io::readDouble(root, "rated_payload", where);
  } else {
    robot.rated_payload = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < robot.arms.size(); ++k) {
      robot.rated_payload = std::min(robot.rated_payload,
                                     derivedEntry(where, "rated_payload", "'rated_payload' [kg]",
                                                  [&] { return payloadFromEfforts(chains[k], robot.arms[k].start); }));
    }
    robot.derived.push_back("rated_payload " + format(robot.rated_payload) +
                            " kg: half the effort limits at the starts");
  }
  if (robot.rated_payload < 0.0 || robot.rated_payload > 1000.0) {
    io::fail(where + ": 'rated_payload' must lie in [0, 1000] kg");
  }
  return robot;
}

const RobotArm* RobotFile::arm(const std::string& name) const noexcept {
  for (const RobotArm& a : arms) {
    if (a.name == name) return &a;
  }
  return nullptr;
}

}  // namespace bimanual_skills::sim
