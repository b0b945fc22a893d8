#include "bimanual_skills/sim/sim_config.hpp"
#include "bimanual_skills/sim/robot_file.hpp"

#include "io/digest.hpp"
#include "io/yaml_io.hpp"

#include <cmath>
#include <set>
#include <stdexcept>

namespace bimanual_skills::sim {
namespace {

using io::fail;

/// A rigid body's name, shape, size, colour, friction and whether the arms feel it (an obstacle's or the object's).
Obstacle readBody(const YAML::Node& item, const std::string& here) {
  Obstacle o;
  o.name = io::readString(item, "name", here);
  const std::string shape = io::readString(item, "shape", here);
  if (shape == "box") {
    o.shape = Obstacle::Shape::Box;
  } else if (shape == "sphere") {
    o.shape = Obstacle::Shape::Sphere;
  } else if (shape == "cylinder") {
    o.shape = Obstacle::Shape::Cylinder;
  } else {
    io::fail(here + ": 'shape' must be box, sphere or cylinder (got '" + shape + "')");
  }
  const Eigen::VectorXd size = io::readVector(item, "size", here);
  const int wanted = sizeValues(o.shape);
  if (size.size() != wanted) {
    io::fail(here + ": 'size' of a " + shape + " needs " + std::to_string(wanted) +
             " value(s) (box: extents; sphere: radius; cylinder: radius, length)");
  }
  o.size.head(wanted) = size;
  if (item["colour"]) o.colour = io::readVector(item, "colour", here, 3);
  o.friction = io::readDouble(item, "friction", here, o.friction);
  if (item["collides"]) o.collides = io::readBool(item, "collides", here);
  return o;
}

/// The moving object of `node` (`object:`).
MovingObject readObject(const YAML::Node& node, const std::string& here) {
  io::checkKeys(node, here,
                {"name", "shape", "size", "colour", "friction", "collides", "grasp_point", "grasp_radius", "path"});
  MovingObject object;
  object.body = readBody(node, here);
  if (node["grasp_point"]) object.grasp_point = io::readVector(node, "grasp_point", here, 3);
  object.grasp_radius = io::readDouble(node, "grasp_radius", here, object.grasp_radius);
  const YAML::Node path = node["path"];
  if (!path || !path.IsMap()) io::fail(here + ": needs a map 'path'");
  const std::string at = here + " path";
  io::checkKeys(path, at,
                {"centre", "size", "max_speed", "max_acceleration", "min_speed_ratio", "pause_probability", "pause",
                 "away_probability", "away", "start_pause", "duration", "seed"});
  ObjectPathConfig& p = object.path;
  if (path["centre"]) p.centre = io::readVector(path, "centre", at, 3);
  if (path["size"]) p.size = io::readVector(path, "size", at, 3);
  p.max_speed = io::readDouble(path, "max_speed", at, p.max_speed);
  p.max_acceleration = io::readDouble(path, "max_acceleration", at, p.max_acceleration);
  p.min_speed_ratio = io::readDouble(path, "min_speed_ratio", at, p.min_speed_ratio);
  p.pause_probability = io::readDouble(path, "pause_probability", at, p.pause_probability);
  if (path["pause"]) p.pause = io::readVector(path, "pause", at, 2);
  p.away_probability = io::readDouble(path, "away_probability", at, p.away_probability);
  if (path["away"]) p.away = io::readVector(path, "away", at, 3);
  p.start_pause = io::readDouble(path, "start_pause", at, p.start_pause);
  p.duration = io::readDouble(path, "duration", at, p.duration);
  if (path["seed"]) {
    const double seed = io::readDouble(path, "seed", at);
    if (seed < 0 || seed > 4294967295.0 || seed != std::floor(seed)) io::fail(at + ": 'seed' must be in [0, 2^32)");
    p.seed = static_cast<std::uint32_t>(seed);
  }
  object.validate(here);
  return object;
}

/// The obstacles of `node`: a list, or the name of a file (relative to `path`) whose `obstacles:` is one.
std::vector<Obstacle> readObstacles(const YAML::Node& node, const std::string& path, const std::string& where) {
  YAML::Node list = node;
  std::string at = where;
  if (node.IsScalar()) {
    const std::string file = io::resolvePath(path, node.as<std::string>());
    at = "obstacles file '" + file + "'";
    const YAML::Node root = io::loadYamlFile(file, at);
    if (!root.IsMap()) io::fail(at + ": must be a map");
    io::checkKeys(root, at, {"obstacles"});
    list = root["obstacles"];
  }
  if (!list || !list.IsSequence()) io::fail(at + ": 'obstacles' must be a list (or the name of a file with one)");
  std::vector<Obstacle> obstacles;
  for (std::size_t k = 0; k < list.size(); ++k) {
    const YAML::Node item = list[k];
    const std::string here = at + " obstacle " + std::to_string(k + 1);
    io::checkKeys(item, here, {"name", "shape", "xyz", "rpy", "size", "colour", "friction", "collides", "mass"});
    Obstacle o = readBody(item, here);
    o.pose = io::readPose(item, here);
    o.mass = io::readDouble(item, "mass", here, o.mass);
    io::withContext(at, [&] { o.validate("the scene"); });
    for (const Obstacle& other : obstacles) {
      if (other.name == o.name) io::fail(here + ": the name '" + o.name + "' is taken by another obstacle");
    }
    obstacles.push_back(o);
  }
  return obstacles;
}

ClothParameters readCloth(const YAML::Node& node, const std::string& where, double& grasp_radius) {
  io::checkKeys(node, where,
                {"xyz", "rpy", "size", "nodes", "mass", "stretch_stiffness", "bending_stiffness", "damping", "friction",
                 "thickness", "position_iterations", "self_collision", "strain_limit", "step", "max_node_speed",
                 "max_stretch", "grasp_radius"});
  ClothParameters c;
  c.pose = io::readPose(node, where);
  if (node["size"]) {
    const Eigen::VectorXd size = io::readVector(node, "size", where, 2);
    c.length = size[0];
    c.width = size[1];
  }
  if (node["nodes"]) {
    const Eigen::VectorXd nodes = io::readVector(node, "nodes", where, 2);
    for (int k = 0; k < 2; ++k) {
      if (nodes[k] != std::floor(nodes[k]) || nodes[k] < 2 || nodes[k] > 1000) {
        fail(where + ": 'nodes' must be two integers in [2, 1000]");
      }
    }
    c.nodes_x = static_cast<int>(nodes[0]);
    c.nodes_y = static_cast<int>(nodes[1]);
  }
  c.mass = io::readDouble(node, "mass", where, c.mass);
  c.stretch_stiffness = io::readDouble(node, "stretch_stiffness", where, c.stretch_stiffness);
  c.bending_stiffness = io::readDouble(node, "bending_stiffness", where, c.bending_stiffness);
  c.damping = io::readDouble(node, "damping", where, c.damping);
  c.friction = io::readDouble(node, "friction", where, c.friction);
  c.thickness = io::readDouble(node, "thickness", where, c.thickness);
  if (node["position_iterations"]) {
    c.position_iterations = io::readInt(node, "position_iterations", where);
  }
  if (node["self_collision"]) c.self_collision = io::readBool(node, "self_collision", where);
  c.strain_limit = io::readDouble(node, "strain_limit", where, c.strain_limit);
  c.step = io::readDouble(node, "step", where, c.step);
  c.max_node_speed = io::readDouble(node, "max_node_speed", where, c.max_node_speed);
  c.max_stretch = io::readDouble(node, "max_stretch", where, c.max_stretch);
  grasp_radius = io::readDouble(node, "grasp_radius", where, grasp_radius);
  try {
    c.validate(where.c_str());
  } catch (const std::invalid_argument& e) {
    fail(e.what());
  }
  return c;
}

}  // namespace

void Table::validate(const char* where) const {
  if (!pose.matrix().allFinite()) throw std::invalid_argument(std::string(where) + ": table pose must be finite");
  if (!size.allFinite() || !(size.minCoeff() > 0.0)) {
    throw std::invalid_argument(std::string(where) + ": table 'size' must be three positive numbers");
  }
  if (!std::isfinite(friction) || friction < 0.0) {
    throw std::invalid_argument(std::string(where) + ": table 'friction' must be >= 0");
  }
}

void MovingObject::validate(const std::string& where) const {
  body.validate(where);
  path.validate(where + " path");
  if (!grasp_point.allFinite() || grasp_point.norm() > 1.0) {
    fail(where + ": 'grasp_point' must be finite, within 1 m of the object's centre");
  }
  if (!(grasp_radius > 0.0 && grasp_radius <= 1.0)) fail(where + ": 'grasp_radius' must lie in (0, 1] m");
}

void SimConfig::validate() const {
  const std::string where = "simulation configuration";
  if (urdf_path.empty()) fail(where + ": 'urdf' is empty");
  if (arms.empty()) fail(where + ": needs at least one arm");
  std::set<std::string> names;
  for (const ArmConfig& arm : arms) {
    if (arm.name.empty() || arm.base_link.empty() || arm.tip_link.empty()) {
      fail(where + ": every arm needs a name, a base_link and a tip_link");
    }
    if (!names.insert(arm.name).second) fail(where + ": two arms are called '" + arm.name + "'");
  }
  if (!(step > 0.0) || !std::isfinite(step)) fail(where + ": 'step' must be > 0");
  if (!gravity.allFinite()) fail(where + ": 'gravity' must be finite");
  if (!std::isfinite(grasp_radius) || grasp_radius < 0.0) fail(where + ": 'grasp_radius' must be >= 0");
  if (has_table) table.validate(where.c_str());
  if (has_object) {
    object.validate(where + " object");
    for (const Obstacle& o : obstacles) {
      if (o.name == object.body.name) fail(where + ": the object's name '" + o.name + "' is taken by an obstacle");
    }
  }
  if (has_cloth) {
    cloth.validate(where.c_str());
    for (const Obstacle& o : obstacles) {
      if (o.mass > 0.0) fail(where + ": the free obstacle '" + o.name + "' and the cloth are not simulated together");
    }
    const double ratio = cloth.step / step;
    if (std::abs(ratio - std::round(ratio)) > 1e-9 * ratio || std::round(ratio) < 1.0) {
      fail(where + ": the cloth 'step' (" + std::to_string(cloth.step) + " s) must be a whole multiple of 'step' (" +
           std::to_string(step) + " s)");
    }
  }
}

std::string SimConfig::worldDigest(const std::string& path, const std::string& robot) {
  const SimConfig config = fromYamlFile(path, robot);
  std::vector<std::string> files{path, config.urdf_path};
  if (!config.robot_path.empty()) files.push_back(config.robot_path);
  if (!config.plant_path.empty()) files.push_back(config.plant_path);
  const std::string digest = io::fileDigest(files);
  if (digest.empty()) throw std::invalid_argument("cannot read the files of the simulation '" + path + "'");
  return digest;
}

SimConfig SimConfig::fromYamlFile(const std::string& path, const std::string& robot) {
  const std::string where = "simulation file '" + path + "'";
  const YAML::Node root = io::loadYamlFile(path, where);
  if (!root.IsMap()) fail(where + ": must be a map");
  io::checkKeys(root, where,
                {"robot", "urdf", "plant", "step", "seed", "gravity", "arms", "table", "obstacles", "object", "cloth"});
  SimConfig config;
  if (root["robot"] && (root["urdf"] || root["plant"] || root["arms"])) {
    fail(where + ": names a 'robot' file and 'urdf', 'plant' or 'arms' too: the robot file gives them");
  }
  if (!robot.empty() || root["robot"]) {
    config.robot_path = robot.empty() ? io::resolvePath(path, io::readString(root, "robot", where)) : robot;
    const RobotFile file = RobotFile::fromYamlFile(config.robot_path);
    config.urdf_path = file.urdf_path;
    config.plant_path = file.plant_path;
    for (const RobotArm& arm : file.arms)
      config.arms.push_back({arm.name, arm.base_link, arm.tip_link, arm.start, arm.friction_file, arm.ik_seed});
    config.kp = file.kp;
    config.kv = file.kv;
  } else {
    config.urdf_path = io::resolvePath(path, io::readString(root, "urdf", where));
    config.plant_path = io::resolvePath(path, io::readString(root, "plant", where));
    const YAML::Node arms = root["arms"];
    if (!arms || !arms.IsSequence() || arms.size() == 0) fail(where + ": needs a non-empty list 'arms'");
    for (std::size_t k = 0; k < arms.size(); ++k) {
      const std::string at = where + " arm " + std::to_string(k + 1);
      io::checkKeys(arms[k], at, {"name", "base_link", "tip_link"});
      config.arms.push_back({io::readString(arms[k], "name", at),
                             io::readString(arms[k], "base_link", at),
                             io::readString(arms[k], "tip_link", at),
                             {},
                             "",
                             {}});
    }
  }
  config.step = io::readDouble(root, "step", where, config.step);
  if (root["seed"]) {
    const double seed = io::readDouble(root, "seed", where);
    if (seed < 0 || seed > 4294967295.0 || seed != std::floor(seed)) fail(where + ": 'seed' must be in [0, 2^32)");
    config.seed = static_cast<std::uint32_t>(seed);
  }
  if (root["gravity"]) config.gravity = io::readVector(root, "gravity", where, 3);

  config.has_table = static_cast<bool>(root["table"]);
  if (config.has_table) {
    const YAML::Node table = root["table"];
    const std::string at = where + " table";
    io::checkKeys(table, at, {"xyz", "rpy", "size", "friction"});
    config.table.pose = io::readPose(table, at);
    if (table["size"]) config.table.size = io::readVector(table, "size", at, 3);
    config.table.friction = io::readDouble(table, "friction", at, config.table.friction);
  }
  if (root["obstacles"]) config.obstacles = readObstacles(root["obstacles"], path, where);
  config.has_object = static_cast<bool>(root["object"]);
  if (config.has_object) config.object = readObject(root["object"], where + " object");
  config.has_cloth = static_cast<bool>(root["cloth"]);
  if (config.has_cloth) config.cloth = readCloth(root["cloth"], where + " cloth", config.grasp_radius);

  config.plant = PlantModel::fromYamlFile(config.plant_path);
  for (const ArmConfig& arm : config.arms) {
    if (!config.plant.hasArm(arm.name)) {
      fail(where + ": the plant model '" + config.plant_path + "' has no arm '" + arm.name + "'");
    }
  }
  try {
    config.validate();
  } catch (const std::invalid_argument& e) {
    fail(where + ": " + e.what());
  }
  return config;
}

}  // namespace bimanual_skills::sim
