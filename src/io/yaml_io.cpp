#include "yaml_io.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace bimanual_skills::io {

void fail(const std::string& message) {
  throw std::invalid_argument(message);
}

YAML::Node loadYamlFile(const std::string& path, const std::string& where) {
  try {
    return YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    fail("cannot read " + where);
  } catch (const YAML::Exception& e) {
    fail(where + ": not valid YAML: " + e.what());
  }
}

std::string resolvePath(const std::string& file, const std::string& relative) {
  const std::filesystem::path p(relative);
  if (p.is_absolute()) return relative;
  return (std::filesystem::path(file).parent_path() / p).lexically_normal().string();
}

void checkKeys(const YAML::Node& node, const std::string& where, std::initializer_list<const char*> allowed) {
  checkKeys(node, where, std::vector<std::string>(allowed.begin(), allowed.end()));
}

void checkKeys(const YAML::Node& node, const std::string& where, const std::vector<std::string>& allowed) {
  if (!node.IsMap()) return;
  for (const auto& entry : node) {
    const std::string key = entry.first.as<std::string>();
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
      std::string names;
      for (const std::string& a : allowed) names += (names.empty() ? "" : ", ") + a;
      fail(where + ": unknown entry '" + key + "' (expected one of: " + names + ")");
    }
  }
}

YAML::Node required(const YAML::Node& node, const std::string& key, const std::string& where) {
  if (!node.IsMap() || !node[key]) fail(where + ": missing key '" + key + "'");
  return node[key];
}

double readDouble(const YAML::Node& node, const std::string& key, const std::string& where) {
  const double value = readScalar<double>(node, key, where, "a number");
  if (!std::isfinite(value)) fail(where + ": '" + key + "' must be finite");
  return value;
}

double readDouble(const YAML::Node& node, const std::string& key, const std::string& where, double fallback) {
  return node.IsMap() && node[key] ? readDouble(node, key, where) : fallback;
}

int readInt(const YAML::Node& node, const std::string& key, const std::string& where) {
  return readScalar<int>(node, key, where, "an integer");
}

bool readBool(const YAML::Node& node, const std::string& key, const std::string& where) {
  return readScalar<bool>(node, key, where, "true or false");
}

std::string readString(const YAML::Node& node, const std::string& key, const std::string& where) {
  return readScalar<std::string>(node, key, where, "a string");
}

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
    if (!ok || !std::isfinite(v[static_cast<Eigen::Index>(i)])) {
      fail(what + "; entry " + std::to_string(i + 1) + " is not a finite number" +
           (value[i].IsScalar() ? " ('" + value[i].Scalar() + "')" : ""));
    }
  }
  return v;
}

Eigen::VectorXd readVector(const YAML::Node& node, const std::string& key, const std::string& where, int size) {
  return toVector(required(node, key, where), where, "'" + key + "'", size);
}

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

void writeVector(YAML::Emitter& out, const std::string& key, const Eigen::Ref<const Eigen::VectorXd>& v) {
  out << YAML::Key << key << YAML::Value << YAML::Flow << std::vector<double>(v.data(), v.data() + v.size());
}

void writeMatrix(YAML::Emitter& out, const std::string& key, const Eigen::Ref<const Eigen::MatrixXd>& m) {
  out << YAML::Key << key << YAML::Value << YAML::BeginSeq;
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    const Eigen::VectorXd row = m.row(r).transpose();
    out << YAML::Flow << std::vector<double>(row.data(), row.data() + row.size());
  }
  out << YAML::EndSeq;
}

void saveYamlFile(const std::string& path, const std::string& what, const std::string& comment,
                  const std::function<void(YAML::Emitter&)>& body) {
  YAML::Emitter out;
  out.SetDoublePrecision(kYamlDigits);
  out.SetBoolFormat(YAML::TrueFalseBool);
  out << YAML::BeginMap;
  body(out);
  out << YAML::EndMap;
  std::ofstream file(path);
  std::stringstream text(comment);
  for (std::string line; std::getline(text, line);) file << "# " << line << '\n';
  file << out.c_str() << '\n';
  if (!file) fail("cannot write " + what + " '" + path + "'");
}

Eigen::Isometry3d readPose(const YAML::Node& node, const std::string& where) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  if (node["xyz"]) pose.translation() = readVector(node, "xyz", where, 3);
  if (node["rpy"]) {
    const Eigen::VectorXd rpy = readVector(node, "rpy", where, 3);
    pose.linear() =
        (Eigen::AngleAxisd(rpy[2], Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(rpy[1], Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(rpy[0], Eigen::Vector3d::UnitX()))
            .toRotationMatrix();
  }
  return pose;
}

}  // namespace bimanual_skills::io
