/// \file
/// The project's one YAML layer (yaml-cpp), shared by every file reader and writer (friction models, DMP files,
/// simulation and node configuration): reading with messages that name the file and the entry at fault, writing
/// doubles with 17 significant digits (every double comes back bit for bit), one exception type,
/// std::invalid_argument, for every problem (unreadable or unwritable file, malformed YAML, missing or bad entries).
/// Internal: not installed; link the target bimanual_skills_yaml_io.
#pragma once

#include <yaml-cpp/yaml.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <functional>
#include <initializer_list>
#include <string>
#include <vector>

namespace bimanual_skills::io {

/// max_digits10 of double.
inline constexpr int kYamlDigits = 17;

/// Throws std::invalid_argument(message).
[[noreturn]] void fail(const std::string& message);

/// The root node of a YAML file. `where` names the file in messages (e.g. "friction model 'a.yaml'").
YAML::Node loadYamlFile(const std::string& path, const std::string& where);

/// Fails on any key of the map `node` that is not in `allowed` (catches misspelt entries).
void checkKeys(const YAML::Node& node, const std::string& where, std::initializer_list<const char*> allowed);
void checkKeys(const YAML::Node& node, const std::string& where, const std::vector<std::string>& allowed);

/// `relative` as written in the file `file`: unchanged when absolute, else relative to the file's directory.
std::string resolvePath(const std::string& file, const std::string& relative);

/// `node[key]`, which must exist.
YAML::Node required(const YAML::Node& node, const std::string& key, const std::string& where);

/// A scalar of type T at `node[key]`; `what` describes the expected value ("a number").
template <typename T>
T readScalar(const YAML::Node& node, const std::string& key, const std::string& where, const char* what) {
  const YAML::Node value = required(node, key, where);
  try {
    if (value.IsScalar()) return value.as<T>();
  } catch (const YAML::Exception&) {
  }
  fail(where + ": '" + key + "' must be " + what + (value.IsScalar() ? " (got '" + value.Scalar() + "')" : ""));
}

/// A finite number at `node[key]`.
double readDouble(const YAML::Node& node, const std::string& key, const std::string& where);
/// The same, or `fallback` when the key is absent.
double readDouble(const YAML::Node& node, const std::string& key, const std::string& where, double fallback);
int readInt(const YAML::Node& node, const std::string& key, const std::string& where);
bool readBool(const YAML::Node& node, const std::string& key, const std::string& where);
std::string readString(const YAML::Node& node, const std::string& key, const std::string& where);

/// `value` as a list of finite numbers (`size` ≥ 0 requires that many); `at` says where, `name` what it is.
Eigen::VectorXd toVector(const YAML::Node& value, const std::string& at, const std::string& name, int size = -1);
/// A list of finite numbers at `node[key]`; `size` ≥ 0 requires that many.
Eigen::VectorXd readVector(const YAML::Node& node, const std::string& key, const std::string& where, int size = -1);
/// A pose {xyz: [x, y, z], rpy: [roll, pitch, yaw]} at `node` (about fixed x, y, z, as in URDF; each entry
/// defaults to zero).
Eigen::Isometry3d readPose(const YAML::Node& node, const std::string& where);
/// A list of `rows` lists of `cols` finite numbers at `node[key]`.
Eigen::MatrixXd readMatrix(const YAML::Node& node, const std::string& key, const std::string& where, int rows,
                           int cols);

/// Runs `build` (typically a constructor or validate() call) and prefixes the message of the
/// std::invalid_argument it throws with `where`.
template <typename Build>
auto withContext(const std::string& where, Build build) -> decltype(build()) {
  try {
    return build();
  } catch (const std::invalid_argument& e) {
    fail(where + ": " + e.what());
  }
}

void writeVector(YAML::Emitter& out, const std::string& key, const Eigen::Ref<const Eigen::VectorXd>& v);
void writeMatrix(YAML::Emitter& out, const std::string& key, const Eigen::Ref<const Eigen::MatrixXd>& m);

/// Writes a YAML file: `comment` (any number of lines) at the top as comments, then the map `body` writes into an
/// emitter set to 17 significant digits and true/false booleans. `what` names the file kind in messages.
void saveYamlFile(const std::string& path, const std::string& what, const std::string& comment,
                  const std::function<void(YAML::Emitter&)>& body);

}  // namespace bimanual_skills::io
