#include "bimanual_skills/sim/plant_model.hpp"

#include "io/yaml_io.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace bimanual_skills::sim {
namespace {

using io::fail;

void requireFinite(double value, const std::string& where, const char* name) {
  if (!std::isfinite(value)) fail(where + ": '" + name + "' must be finite");
}

void requireNonNegative(double value, const std::string& where, const char* name) {
  requireFinite(value, where, name);
  if (value < 0.0) fail(where + ": '" + std::string(name) + "' must be >= 0 (got " + std::to_string(value) + ")");
}

void validateVector(const Eigen::VectorXd& v, int n, const std::string& where, const char* name) {
  if (v.size() == 0) return;
  if (v.size() != n) {
    fail(where + ": '" + name + "' must have " + std::to_string(n) + " entries (got " + std::to_string(v.size()) + ")");
  }
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(v[i]) || v[i] < 0.0) {
      fail(where + ": '" + name + "' entry " + std::to_string(i + 1) + " must be finite and >= 0");
    }
  }
}

FrictionLaw readLaw(const YAML::Node& node, const std::string& where) {
  FrictionLaw law;
  law.static_friction = io::readDouble(node, "static", where, 0.0);
  law.coulomb = io::readDouble(node, "coulomb", where, 0.0);
  law.stribeck_velocity = io::readDouble(node, "stribeck_velocity", where, law.stribeck_velocity);
  law.viscous = io::readDouble(node, "viscous", where, 0.0);
  law.hysteresis = io::readDouble(node, "hysteresis", where, 0.0);
  law.ripple = io::readDouble(node, "ripple", where, 0.0);
  law.ripple_frequency = io::readDouble(node, "ripple_frequency", where, 0.0);
  if (node["ripple_phase"]) {
    const Eigen::VectorXd phase = io::readVector(node, "ripple_phase", where, 2);
    law.ripple_phase_positive = phase[0];
    law.ripple_phase_negative = phase[1];
  }
  return law;
}

Drive readDrive(const YAML::Node& node, const std::string& where) {
  if (!node.IsMap()) fail(where + ": must be a map");
  io::checkKeys(node, where,
                {"joint", "differential", "ratio", "static", "coulomb", "stribeck_velocity", "viscous", "hysteresis",
                 "ripple", "ripple_frequency", "ripple_phase"});
  Drive drive;
  if (node["joint"] && node["differential"]) fail(where + ": give either 'joint' or 'differential', not both");
  if (node["joint"]) {
    drive.first = io::readInt(node, "joint", where) - 1;
    if (node["ratio"]) fail(where + ": 'ratio' is only for a differential");
  } else if (node["differential"]) {
    const Eigen::VectorXd joints = io::readVector(node, "differential", where, 2);
    for (int k = 0; k < 2; ++k) {
      if (joints[k] != std::floor(joints[k]) || joints[k] < 1.0) {
        fail(where + ": 'differential' must list two joint numbers (1-based)");
      }
    }
    drive.first = static_cast<int>(joints[0]) - 1;
    drive.second = static_cast<int>(joints[1]) - 1;
    drive.ratio = io::readDouble(node, "ratio", where);
  } else {
    fail(where + ": needs 'joint' (direct drive) or 'differential' [i, j]");
  }
  drive.friction = readLaw(node, where);
  drive.friction.validate(where);
  if (drive.isDifferential() && (!(drive.ratio > 0.0) || !std::isfinite(drive.ratio))) {
    fail(where + ": 'ratio' must be > 0");
  }
  return drive;
}

ArmPlantParameters readArm(const YAML::Node& node, const std::string& where) {
  if (!node.IsMap()) fail(where + ": must be a map");
  io::checkKeys(node, where, {"rotor_inertia", "encoder_resolution", "velocity_noise", "saturate_torque", "friction"});
  ArmPlantParameters arm;
  if (node["rotor_inertia"]) arm.rotor_inertia = io::readVector(node, "rotor_inertia", where);
  if (node["encoder_resolution"]) {
    arm.encoder_resolution = io::readVector(node, "encoder_resolution", where);
  }
  if (node["velocity_noise"]) arm.velocity_noise = io::readVector(node, "velocity_noise", where);
  if (node["saturate_torque"]) arm.saturate_torque = io::readBool(node, "saturate_torque", where);
  if (node["friction"]) {
    const YAML::Node list = node["friction"];
    if (!list.IsSequence()) fail(where + ": 'friction' must be a list of drives");
    std::vector<int> seen;
    for (std::size_t k = 0; k < list.size(); ++k) {
      const std::string at = where + " friction entry " + std::to_string(k + 1);
      arm.drives.push_back(readDrive(list[k], at));
      for (const int joint : {arm.drives.back().first, arm.drives.back().second}) {
        if (joint < 0) continue;
        if (std::find(seen.begin(), seen.end(), joint) != seen.end()) {
          fail(at + ": joint " + std::to_string(joint + 1) + " appears in more than one friction entry");
        }
        seen.push_back(joint);
      }
    }
  }
  return arm;
}

}  // namespace

bool FrictionLaw::isZero() const noexcept {
  return static_friction == 0.0 && coulomb == 0.0 && viscous == 0.0;
}

void FrictionLaw::validate(const std::string& where) const {
  requireNonNegative(static_friction, where, "static");
  requireNonNegative(coulomb, where, "coulomb");
  requireNonNegative(viscous, where, "viscous");
  requireNonNegative(ripple_frequency, where, "ripple_frequency");
  requireFinite(ripple_phase_positive, where, "ripple_phase");
  requireFinite(ripple_phase_negative, where, "ripple_phase");
  if (static_friction < coulomb) {
    fail(where + ": 'static' (" + std::to_string(static_friction) + ") must be >= 'coulomb' (" +
         std::to_string(coulomb) + ")");
  }
  if (!(stribeck_velocity > 0.0) || !std::isfinite(stribeck_velocity)) {
    fail(where + ": 'stribeck_velocity' must be > 0");
  }
  if (!(hysteresis >= 0.0 && hysteresis < 1.0)) fail(where + ": 'hysteresis' must be in [0, 1)");
  if (!(ripple >= 0.0 && ripple < 1.0)) fail(where + ": 'ripple' must be in [0, 1)");
}

void ArmPlantParameters::validate(int n, const std::string& where) const {
  validateVector(rotor_inertia, n, where, "rotor_inertia");
  validateVector(encoder_resolution, n, where, "encoder_resolution");
  validateVector(velocity_noise, n, where, "velocity_noise");
  if (drives.empty()) return;
  std::vector<int> seen(static_cast<std::size_t>(n), 0);
  for (std::size_t k = 0; k < drives.size(); ++k) {
    const Drive& d = drives[k];
    const std::string at = where + " friction entry " + std::to_string(k + 1);
    for (int j = 0; j < (d.isDifferential() ? 2 : 1); ++j) {
      const int joint = j == 0 ? d.first : d.second;
      if (joint < 0 || joint >= n) {
        fail(at + ": joint " + std::to_string(joint + 1) + " does not exist (the arm has " + std::to_string(n) +
             " joints)");
      }
      if (seen[static_cast<std::size_t>(joint)]++ > 0) {
        fail(at + ": joint " + std::to_string(joint + 1) + " appears in more than one friction entry");
      }
    }
    if (d.isDifferential() && d.first == d.second) fail(at + ": a differential needs two different joints");
    if (d.isDifferential() && (!(d.ratio > 0.0) || !std::isfinite(d.ratio))) fail(at + ": 'ratio' must be > 0");
    d.friction.validate(at);
  }
  for (int i = 0; i < n; ++i) {
    if (seen[static_cast<std::size_t>(i)] == 0) {
      fail(where + ": joint " + std::to_string(i + 1) + " has no friction entry (list every joint once)");
    }
  }
}

ArmPlantParameters ArmPlantParameters::ideal() {
  ArmPlantParameters p;
  p.saturate_torque = false;
  return p;
}

PlantModel PlantModel::fromYamlFile(const std::string& path) {
  const std::string where = "plant model '" + path + "'";
  const YAML::Node root = io::loadYamlFile(path, where);
  if (!root.IsMap() || !root["arms"] || !root["arms"].IsMap() || root["arms"].size() == 0) {
    fail(where + ": needs a map 'arms' with one entry per arm name");
  }
  io::checkKeys(root, where, {"arms"});
  PlantModel model;
  for (const auto& entry : root["arms"]) {
    const std::string name = entry.first.as<std::string>();
    model.arms.emplace_back(name, readArm(entry.second, where + " arm '" + name + "'"));
  }
  return model;
}

bool PlantModel::hasArm(const std::string& name) const noexcept {
  for (const auto& [arm_name, parameters] : arms) {
    if (arm_name == name) return true;
  }
  return false;
}

const ArmPlantParameters& PlantModel::arm(const std::string& name) const {
  for (const auto& [arm_name, parameters] : arms) {
    if (arm_name == name) return parameters;
  }
  std::string names;
  for (const auto& [arm_name, parameters] : arms) names += (names.empty() ? "" : ", ") + arm_name;
  throw std::invalid_argument("plant model has no arm '" + name + "' (it has: " + names + ")");
}

}  // namespace bimanual_skills::sim
