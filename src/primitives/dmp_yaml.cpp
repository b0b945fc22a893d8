#include "bimanual_skills/primitives/dmp_yaml.hpp"

#include "io/yaml_io.hpp"

#include <cmath>
#include <functional>
#include <string>

namespace bimanual_skills::primitives {
namespace {

using io::fail;
using io::readDouble;
using io::readMatrix;
using io::readVector;
using io::required;

// ---- Reading: every error names the file and the key ----

/// [x, y, z, w], which must be a unit quaternion.
Eigen::Quaterniond readQuaternion(const YAML::Node& node, const std::string& key, const std::string& where) {
  const Eigen::VectorXd c = readVector(node, key, where, 4);
  const Eigen::Quaterniond q(c[3], c[0], c[1], c[2]);
  if (!(std::abs(q.norm() - 1.0) <= 1e-6)) {
    fail(where + ": '" + key + "' must be a unit quaternion [x, y, z, w] (norm " + std::to_string(q.norm()) + ")");
  }
  return q;
}

Pose readPose(const YAML::Node& node, const std::string& key, const std::string& where) {
  const YAML::Node pose = required(node, key, where);
  const std::string at = where + " '" + key + "'";
  return Pose{readVector(pose, "position", at, 3), readQuaternion(pose, "orientation", at)};
}

DmpParameters readParameters(const YAML::Node& node, const std::string& where) {
  const YAML::Node p = required(node, "parameters", where);
  const std::string at = where + " 'parameters'";
  DmpParameters parameters;
  parameters.kernels = io::readInt(p, "kernels", at);
  parameters.alpha_z = readDouble(p, "alpha_z", at);
  parameters.beta_z = readDouble(p, "beta_z", at);
  parameters.alpha_x = readDouble(p, "alpha_x", at);
  parameters.goal_scaled_forcing = io::readBool(p, "goal_scaled_forcing", at);
  parameters.regularisation = readDouble(p, "regularisation", at);
  io::withContext(at, [&] { parameters.validate(); });
  return parameters;
}

DmpState readDmpState(const YAML::Node& node, const std::string& where, int size = -1) {
  DmpState state;
  state.y = readVector(node, "y", where, size);
  const int n = static_cast<int>(state.y.size());
  state.yd = readVector(node, "yd", where, n);
  state.ydd = readVector(node, "ydd", where, n);
  state.goal = readVector(node, "goal", where, n);
  state.x = readDouble(node, "x", where);
  state.t = readDouble(node, "t", where);
  return state;
}

/// The file's root map, of the given `type`.
YAML::Node loadRoot(const std::string& path, const std::string& type, const std::string& where) {
  const YAML::Node root = io::loadYamlFile(path, where);
  if (!root.IsMap()) fail(where + ": not a YAML map");
  const std::string found = io::readString(root, "type", where);
  if (found != type) fail(where + ": 'type' is '" + found + "', expected '" + type + "'");
  return root;
}

// ---- Writing ----

void writeQuaternion(YAML::Emitter& out, const std::string& key, const Eigen::Quaterniond& q) {
  out << YAML::Key << key << YAML::Value << YAML::Flow << std::vector<double>{q.x(), q.y(), q.z(), q.w()};
}

void writePose(YAML::Emitter& out, const std::string& key, const Pose& pose) {
  out << YAML::Key << key << YAML::Value << YAML::BeginMap;
  io::writeVector(out, "position", pose.position);
  writeQuaternion(out, "orientation", pose.orientation);
  out << YAML::EndMap;
}

void writeParameters(YAML::Emitter& out, const DmpParameters& p) {
  out << YAML::Key << "parameters" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "kernels" << YAML::Value << p.kernels;
  out << YAML::Key << "alpha_z" << YAML::Value << p.alpha_z;
  out << YAML::Key << "beta_z" << YAML::Value << p.beta_z;
  out << YAML::Key << "alpha_x" << YAML::Value << p.alpha_x;
  out << YAML::Key << "goal_scaled_forcing" << YAML::Value << p.goal_scaled_forcing;
  out << YAML::Key << "regularisation" << YAML::Value << p.regularisation;
  out << YAML::EndMap;
}

void writeDmpState(YAML::Emitter& out, const DmpState& state) {
  io::writeVector(out, "y", state.y);
  io::writeVector(out, "yd", state.yd);
  io::writeVector(out, "ydd", state.ydd);
  io::writeVector(out, "goal", state.goal);
  out << YAML::Key << "x" << YAML::Value << state.x;
  out << YAML::Key << "t" << YAML::Value << state.t;
}

/// A file of the given `type`: the root map starts with it, `body` writes the rest.
void save(const std::string& path, const std::string& type, const std::string& comment,
          const std::function<void(YAML::Emitter&)>& body) {
  io::saveYamlFile(path, type + " file", comment, [&](YAML::Emitter& out) {
    out << YAML::Key << "type" << YAML::Value << type;
    body(out);
  });
}

std::string toString(OrientationEncoding encoding) {
  return encoding == OrientationEncoding::UnitQuaternion ? "unit_quaternion" : "quaternion_vector";
}

}  // namespace

void saveDmp(const Dmp& dmp, const std::string& path, const std::string& comment) {
  save(path, "dmp", comment, [&](YAML::Emitter& out) {
    writeParameters(out, dmp.parameters());
    out << YAML::Key << "duration" << YAML::Value << dmp.duration();
    io::writeVector(out, "start", dmp.start());
    io::writeVector(out, "goal", dmp.goal());
    io::writeMatrix(out, "weights", dmp.weights());
  });
}

Dmp loadDmp(const std::string& path) {
  const std::string where = "DMP file '" + path + "'";
  const YAML::Node root = loadRoot(path, "dmp", where);
  const DmpParameters parameters = readParameters(root, where);
  const double duration = readDouble(root, "duration", where);
  const Eigen::VectorXd start = readVector(root, "start", where);
  const Eigen::VectorXd goal = readVector(root, "goal", where, static_cast<int>(start.size()));
  const Eigen::MatrixXd weights =
      readMatrix(root, "weights", where, static_cast<int>(start.size()), parameters.kernels);
  return io::withContext(where, [&] { return Dmp(parameters, weights, start, goal, duration); });
}

void saveDmpState(const DmpState& state, const std::string& path, const std::string& comment) {
  save(path, "dmp_state", comment, [&](YAML::Emitter& out) { writeDmpState(out, state); });
}

DmpState loadDmpState(const std::string& path) {
  const std::string where = "DMP state file '" + path + "'";
  return readDmpState(loadRoot(path, "dmp_state", where), where);
}

void saveCartesianDmp(const CartesianDmp& dmp, const std::string& path, const std::string& comment) {
  save(path, "cartesian_dmp", comment, [&](YAML::Emitter& out) {
    out << YAML::Key << "orientation_encoding" << YAML::Value << toString(dmp.encoding());
    writeParameters(out, dmp.parameters());
    out << YAML::Key << "duration" << YAML::Value << dmp.duration();
    writePose(out, "start", dmp.start());
    writePose(out, "goal", dmp.goal());
    io::writeMatrix(out, "position_weights", dmp.positionWeights());
    io::writeMatrix(out, "orientation_weights", dmp.orientationWeights());
  });
}

CartesianDmp loadCartesianDmp(const std::string& path) {
  const std::string where = "Cartesian DMP file '" + path + "'";
  const YAML::Node root = loadRoot(path, "cartesian_dmp", where);
  const std::string name = io::readString(root, "orientation_encoding", where);
  if (name != toString(OrientationEncoding::UnitQuaternion) &&
      name != toString(OrientationEncoding::QuaternionVector)) {
    fail(where + ": 'orientation_encoding' must be unit_quaternion or quaternion_vector (got '" + name + "')");
  }
  const OrientationEncoding encoding = name == toString(OrientationEncoding::UnitQuaternion)
                                           ? OrientationEncoding::UnitQuaternion
                                           : OrientationEncoding::QuaternionVector;
  const DmpParameters parameters = readParameters(root, where);
  const double duration = readDouble(root, "duration", where);
  const Pose start = readPose(root, "start", where);
  const Pose goal = readPose(root, "goal", where);
  const Eigen::MatrixXd position_weights = readMatrix(root, "position_weights", where, 3, parameters.kernels);
  const Eigen::MatrixXd orientation_weights = readMatrix(root, "orientation_weights", where, 3, parameters.kernels);
  return io::withContext(where, [&] {
    return CartesianDmp(parameters, encoding, position_weights, orientation_weights, start, goal, duration);
  });
}

void saveCartesianDmpState(const CartesianDmpState& state, const std::string& path, const std::string& comment) {
  save(path, "cartesian_dmp_state", comment, [&](YAML::Emitter& out) {
    out << YAML::Key << "position" << YAML::Value << YAML::BeginMap;
    writeDmpState(out, state.position);
    out << YAML::EndMap;
    writeQuaternion(out, "orientation", state.orientation);
    io::writeVector(out, "angular_velocity", state.angular_velocity);
    io::writeVector(out, "angular_acceleration", state.angular_acceleration);
    writeQuaternion(out, "goal_orientation", state.goal_orientation);
    out << YAML::Key << "orientation_vector" << YAML::Value << YAML::BeginMap;
    writeDmpState(out, state.orientation_vector);
    out << YAML::EndMap;
  });
}

CartesianDmpState loadCartesianDmpState(const std::string& path) {
  const std::string where = "Cartesian DMP state file '" + path + "'";
  const YAML::Node root = loadRoot(path, "cartesian_dmp_state", where);
  CartesianDmpState state;
  state.position = readDmpState(required(root, "position", where), where + " 'position'", 3);
  state.orientation = readQuaternion(root, "orientation", where);
  state.angular_velocity = readVector(root, "angular_velocity", where, 3);
  state.angular_acceleration = readVector(root, "angular_acceleration", where, 3);
  state.goal_orientation = readQuaternion(root, "goal_orientation", where);
  state.orientation_vector = readDmpState(required(root, "orientation_vector", where), where + " 'orientation_vector'");
  if (state.orientation_vector.y.size() != 0 && state.orientation_vector.y.size() != 3) {
    fail(where + ": 'orientation_vector' must have 3 values per entry (quaternion_vector) or none (unit_quaternion)");
  }
  return state;
}

}  // namespace bimanual_skills::primitives
