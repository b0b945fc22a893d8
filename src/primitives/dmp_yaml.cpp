#include "bimanual_skills/primitives/dmp_yaml.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace bimanual_skills::primitives {
namespace {

constexpr int kDigits = 17;  ///< max_digits10 of double: every double survives text and back exactly

[[noreturn]] void fail(const std::string& message) {
  throw std::invalid_argument(message);
}

// ---- Reading: every error names the file and the key ----

/// `node[key]`, which must exist.
YAML::Node required(const YAML::Node& node, const std::string& key, const std::string& where) {
  if (!node.IsMap() || !node[key]) fail(where + ": missing key '" + key + "'");
  return node[key];
}

/// A scalar of type T at `node[key]`.
template <typename T>
T readScalar(const YAML::Node& node, const std::string& key, const std::string& where, const char* what) {
  const YAML::Node value = required(node, key, where);
  try {
    if (value.IsScalar()) return value.as<T>();
  } catch (const YAML::Exception&) {
  }
  fail(where + ": '" + key + "' must be " + what + (value.IsScalar() ? " (got '" + value.Scalar() + "')" : ""));
}

double readDouble(const YAML::Node& node, const std::string& key, const std::string& where) {
  return readScalar<double>(node, key, where, "a number");
}

/// `value` as a list of numbers (`size` ≥ 0 requires that many); `at` says where, `name` what it is.
Eigen::VectorXd toVector(const YAML::Node& value, const std::string& at, const std::string& name, int size) {
  const std::string what =
      at + ": " + name + " must be a list of " + (size >= 0 ? std::to_string(size) + " " : "") + "numbers";
  if (!value.IsSequence()) fail(what);
  if (size >= 0 && static_cast<int>(value.size()) != size) fail(what + " (got " + std::to_string(value.size()) + ")");
  Eigen::VectorXd v(value.size());
  for (std::size_t i = 0; i < value.size(); ++i) {
    bool ok = value[i].IsScalar();
    try {
      if (ok) v[static_cast<Eigen::Index>(i)] = value[i].as<double>();
    } catch (const YAML::Exception&) {
      ok = false;
    }
    if (!ok) {
      fail(what + "; entry " + std::to_string(i + 1) + " is not a number" +
           (value[i].IsScalar() ? " ('" + value[i].Scalar() + "')" : ""));
    }
  }
  return v;
}

/// A list of numbers at `node[key]`; `size` ≥ 0 requires that many.
Eigen::VectorXd readVector(const YAML::Node& node, const std::string& key, const std::string& where, int size = -1) {
  return toVector(required(node, key, where), where, "'" + key + "'", size);
}

/// A list of `rows` lists of `cols` numbers at `node[key]`.
Eigen::MatrixXd readMatrix(const YAML::Node& node, const std::string& key, const std::string& where, int rows,
                           int cols) {
  const YAML::Node value = required(node, key, where);
  if (!value.IsSequence() || static_cast<int>(value.size()) != rows) {
    fail(where + ": '" + key + "' must be a list of " + std::to_string(rows) + " rows" +
         (value.IsSequence() ? " (got " + std::to_string(value.size()) + ")" : ""));
  }
  Eigen::MatrixXd m(rows, cols);
  for (int r = 0; r < rows; ++r) {
    m.row(r) = toVector(value[r], where, "'" + key + "' row " + std::to_string(r + 1), cols).transpose();
  }
  return m;
}

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
  parameters.kernels = readScalar<int>(p, "kernels", at, "an integer");
  parameters.alpha_z = readDouble(p, "alpha_z", at);
  parameters.beta_z = readDouble(p, "beta_z", at);
  parameters.alpha_x = readDouble(p, "alpha_x", at);
  parameters.goal_scaled_forcing = readScalar<bool>(p, "goal_scaled_forcing", at, "true or false");
  parameters.regularisation = readDouble(p, "regularisation", at);
  try {
    parameters.validate();
  } catch (const std::invalid_argument& e) {
    fail(at + ": " + e.what());
  }
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
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw std::runtime_error("cannot read " + where);
  } catch (const YAML::Exception& e) {
    fail(where + ": not valid YAML: " + e.what());
  }
  if (!root.IsMap()) fail(where + ": not a YAML map");
  const std::string found = readScalar<std::string>(root, "type", where, "a string");
  if (found != type) fail(where + ": 'type' is '" + found + "', expected '" + type + "'");
  return root;
}

/// Runs `build` (a constructor call) and prefixes the message of what it throws with `where`.
template <typename Build>
auto constructed(const std::string& where, Build build) -> decltype(build()) {
  try {
    return build();
  } catch (const std::invalid_argument& e) {
    fail(where + ": " + e.what());
  }
}

// ---- Writing ----

void writeVector(YAML::Emitter& out, const std::string& key, const Eigen::Ref<const Eigen::VectorXd>& v) {
  out << YAML::Key << key << YAML::Value << YAML::Flow << std::vector<double>(v.data(), v.data() + v.size());
}

void writeMatrix(YAML::Emitter& out, const std::string& key, const Eigen::MatrixXd& m) {
  out << YAML::Key << key << YAML::Value << YAML::BeginSeq;
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    const Eigen::VectorXd row = m.row(r).transpose();
    out << YAML::Flow << std::vector<double>(row.data(), row.data() + row.size());
  }
  out << YAML::EndSeq;
}

void writeQuaternion(YAML::Emitter& out, const std::string& key, const Eigen::Quaterniond& q) {
  out << YAML::Key << key << YAML::Value << YAML::Flow << std::vector<double>{q.x(), q.y(), q.z(), q.w()};
}

void writePose(YAML::Emitter& out, const std::string& key, const Pose& pose) {
  out << YAML::Key << key << YAML::Value << YAML::BeginMap;
  writeVector(out, "position", pose.position);
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
  writeVector(out, "y", state.y);
  writeVector(out, "yd", state.yd);
  writeVector(out, "ydd", state.ydd);
  writeVector(out, "goal", state.goal);
  out << YAML::Key << "x" << YAML::Value << state.x;
  out << YAML::Key << "t" << YAML::Value << state.t;
}

/// Opens an emitter's root map with `type`; `body` writes the rest; the file gets `comment` at the top.
template <typename Body>
void save(const std::string& path, const std::string& type, const std::string& comment, Body body) {
  YAML::Emitter out;
  out.SetDoublePrecision(kDigits);
  out.SetBoolFormat(YAML::TrueFalseBool);
  out << YAML::BeginMap << YAML::Key << "type" << YAML::Value << type;
  body(out);
  out << YAML::EndMap;
  std::ofstream file(path);
  std::stringstream text(comment);
  for (std::string line; std::getline(text, line);) file << "# " << line << '\n';
  file << out.c_str() << '\n';
  if (!file) throw std::runtime_error("cannot write " + type + " file '" + path + "'");
}

std::string toString(OrientationEncoding encoding) {
  return encoding == OrientationEncoding::UnitQuaternion ? "unit_quaternion" : "quaternion_vector";
}

}  // namespace

void saveDmp(const Dmp& dmp, const std::string& path, const std::string& comment) {
  save(path, "dmp", comment, [&](YAML::Emitter& out) {
    writeParameters(out, dmp.parameters());
    out << YAML::Key << "duration" << YAML::Value << dmp.duration();
    writeVector(out, "start", dmp.start());
    writeVector(out, "goal", dmp.goal());
    writeMatrix(out, "weights", dmp.weights());
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
  return constructed(where, [&] { return Dmp(parameters, weights, start, goal, duration); });
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
    writeMatrix(out, "position_weights", dmp.positionWeights());
    writeMatrix(out, "orientation_weights", dmp.orientationWeights());
  });
}

CartesianDmp loadCartesianDmp(const std::string& path) {
  const std::string where = "Cartesian DMP file '" + path + "'";
  const YAML::Node root = loadRoot(path, "cartesian_dmp", where);
  const std::string name = readScalar<std::string>(root, "orientation_encoding", where, "a string");
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
  return constructed(where, [&] {
    return CartesianDmp(parameters, encoding, position_weights, orientation_weights, start, goal, duration);
  });
}

void saveCartesianDmpState(const CartesianDmpState& state, const std::string& path, const std::string& comment) {
  save(path, "cartesian_dmp_state", comment, [&](YAML::Emitter& out) {
    out << YAML::Key << "position" << YAML::Value << YAML::BeginMap;
    writeDmpState(out, state.position);
    out << YAML::EndMap;
    writeQuaternion(out, "orientation", state.orientation);
    writeVector(out, "angular_velocity", state.angular_velocity);
    writeVector(out, "angular_acceleration", state.angular_acceleration);
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
