/// \file
/// YAML files of friction models (what the controllers load), written with 17 significant digits.
/// Target bimanual_skills_dynamics. Offline: allocates and throws.
#pragma once

#include "bimanual_skills/dynamics/friction_model.hpp"

#include <string>

namespace bimanual_skills::dynamics {

/// Writes a friction model; `comment` goes at the top. \throws std::invalid_argument for an invalid model or a file
/// that cannot be written.
void saveFrictionModel(const FrictionModel& model, const std::string& path, const std::string& comment = "");
/// \throws std::invalid_argument naming the file and the entry at fault.
FrictionModel loadFrictionModel(const std::string& path);

}  // namespace bimanual_skills::dynamics
