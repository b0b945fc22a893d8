#include "bimanual_skills/dynamics/friction_yaml.hpp"

#include "io/yaml_io.hpp"

#include <string>
#include <vector>

namespace bimanual_skills::dynamics {
namespace {

using io::fail;

JointFriction readJoint(const YAML::Node& node, FrictionModelType type, const std::string& where) {
  JointFriction joint;
  joint.type = type;
  if (!node.IsMap()) fail(where + ": must be a map with a list 'b'");
  joint.b = io::readVector(node, "b", where);
  joint.s = io::readDouble(node, "s", where, joint.s);
  joint.z = io::readDouble(node, "z", where, joint.z);
  joint.h = io::readDouble(node, "h", where, joint.h);
  io::withContext(where, [&] { joint.validate(); });
  return joint;
}

void writeJoint(YAML::Emitter& out, const JointFriction& joint) {
  out << YAML::BeginMap;
  io::writeVector(out, "b", joint.b);
  out << YAML::Key << "s" << YAML::Value << joint.s;
  out << YAML::Key << "z" << YAML::Value << joint.z;
  out << YAML::Key << "h" << YAML::Value << joint.h;
  out << YAML::EndMap;
}

}  // namespace

void saveFrictionModel(const FrictionModel& model, const std::string& path, const std::string& comment) {
  model.validate();
  io::saveYamlFile(path, "friction model", comment, [&](YAML::Emitter& out) {
    out << YAML::Key << "model" << YAML::Value << (model.joints.empty() ? "viscous" : toString(model.joints[0].type));
    out << YAML::Key << "joints" << YAML::Value << YAML::BeginSeq;
    for (const JointFriction& joint : model.joints) writeJoint(out, joint);
    out << YAML::EndSeq;
    out << YAML::Key << "pairs" << YAML::Value << YAML::BeginSeq;
    for (const CoupledPair& pair : model.pairs) {
      out << YAML::BeginMap;
      out << YAML::Key << "joints" << YAML::Value << YAML::Flow << std::vector<int>{pair.first + 1, pair.second + 1};
      out << YAML::Key << "epsilon" << YAML::Value << pair.epsilon;
      out << YAML::Key << "reduced" << YAML::Value << YAML::BeginSeq;
      writeJoint(out, pair.reduced_first);
      writeJoint(out, pair.reduced_second);
      out << YAML::EndSeq << YAML::EndMap;
    }
    out << YAML::EndSeq;
  });
}

FrictionModel loadFrictionModel(const std::string& path) {
  const std::string where = "friction model '" + path + "'";
  const YAML::Node root = io::loadYamlFile(path, where);
  FrictionModelType type;
  if (!root.IsMap() || !root["model"] || !parseFrictionModelType(root["model"].as<std::string>(""), type)) {
    fail(where + ": 'model' must be viscous, initial, basic or advanced");
  }
  if (!root["joints"] || !root["joints"].IsSequence() || root["joints"].size() == 0) {
    fail(where + ": needs a non-empty list 'joints'");
  }
  FrictionModel model;
  for (std::size_t i = 0; i < root["joints"].size(); ++i) {
    model.joints.push_back(readJoint(root["joints"][i], type, where + " joint " + std::to_string(i + 1)));
  }
  if (root["pairs"]) {
    if (!root["pairs"].IsSequence()) fail(where + ": 'pairs' must be a list");
    for (std::size_t k = 0; k < root["pairs"].size(); ++k) {
      const YAML::Node node = root["pairs"][k];
      const std::string at = where + " pair " + std::to_string(k + 1);
      if (!node["joints"] || !node["joints"].IsSequence() || node["joints"].size() != 2 || !node["reduced"] ||
          !node["reduced"].IsSequence() || node["reduced"].size() != 2) {
        fail(at + ": needs 'joints' [i, j] and two 'reduced' models");
      }
      CoupledPair pair;
      const Eigen::VectorXd joints = io::toVector(node["joints"], at, "'joints'", 2);
      if (joints != joints.array().round().matrix()) fail(at + ": 'joints' must be two joint numbers");
      pair.first = static_cast<int>(joints[0]) - 1;
      pair.second = static_cast<int>(joints[1]) - 1;
      pair.epsilon = io::readDouble(node, "epsilon", at, pair.epsilon);
      pair.reduced_first = readJoint(node["reduced"][0], type, at + " reduced 1");
      pair.reduced_second = readJoint(node["reduced"][1], type, at + " reduced 2");
      model.pairs.push_back(pair);
    }
  }
  io::withContext(where, [&] { model.validate(); });
  return model;
}

}  // namespace bimanual_skills::dynamics
