/// \file
/// YAML files of DMPs and their running states (joint-space Dmp, CartesianDmp): "train anywhere, execute in C++".
/// Target bimanual_skills_primitives (yaml-cpp). Allocates and throws: never call
/// from a real-time loop.
///
/// Doubles are written with 17 significant digits, so save → load gives back every double bit for bit. Layout of a
/// Dmp file (a DmpState file has `type: dmp_state` and y, yd, ydd, goal, x, t; the Cartesian files nest the same
/// pieces, with poses as {position: [x, y, z], orientation: [x, y, z, w]}):
/// \code{.yaml}
///   type: dmp
///   parameters: {kernels: 25, alpha_z: 25, beta_z: 6.25, alpha_x: 4, goal_scaled_forcing: false,
///                regularisation: 1e-08}
///   duration: 2          # τ [s]
///   start: [...]         # dofs values
///   goal: [...]
///   weights:             # one row of `kernels` values per DoF
///     - [...]
/// \endcode
#pragma once

#include "bimanual_skills/primitives/cartesian_dmp.hpp"
#include "bimanual_skills/primitives/dmp.hpp"

#include <string>

namespace bimanual_skills::primitives {

/// Writes `dmp` to `path`; `comment` (any number of lines) goes at the top as YAML comments.
/// \throws std::invalid_argument when the file cannot be written.
void saveDmp(const Dmp& dmp, const std::string& path, const std::string& comment = "");
/// \throws std::invalid_argument naming the file (and the entry at fault) when the file cannot be read, for
///         malformed YAML, a wrong `type`, missing keys, non-numeric or non-finite values, wrong sizes, or values the
///         Dmp constructor refuses.
Dmp loadDmp(const std::string& path);

void saveDmpState(const DmpState& state, const std::string& path, const std::string& comment = "");
/// \throws as loadDmp(); y, yd, ydd and goal must have the same length.
DmpState loadDmpState(const std::string& path);

void saveCartesianDmp(const CartesianDmp& dmp, const std::string& path, const std::string& comment = "");
/// \throws as loadDmp(); `orientation_encoding` must be unit_quaternion or quaternion_vector.
CartesianDmp loadCartesianDmp(const std::string& path);

void saveCartesianDmpState(const CartesianDmpState& state, const std::string& path, const std::string& comment = "");
/// \throws as loadDmp(); the position part has 3 DoF, orientation_vector 3 or 0 (unit-quaternion DMPs), and the
///         quaternions are unit.
CartesianDmpState loadCartesianDmpState(const std::string& path);

}  // namespace bimanual_skills::primitives
