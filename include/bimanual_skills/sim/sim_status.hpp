/// \file
/// Outcome of the simulator's real-time calls (stepping, commands, grasps): bad input and divergence are reported
/// here, never by an exception or a crash.
#pragma once

namespace bimanual_skills::sim {

enum class SimStatus {
  Ok,
  InvalidArgument,  ///< Wrong size, NaN/Inf, out-of-range value: the call did nothing, the previous setting holds.
  UnknownArm,       ///< Arm index out of range.
  UnknownLink,      ///< Link handle that does not belong to this simulation.
  NoCloth,          ///< A cloth call on a simulation built without cloth.
  ClothDiverged,    ///< The cloth left its bounds (NaN, node speed, stretch): it is frozen until reset.
  ArmDiverged,      ///< An arm's state became non-finite or too fast: the arms are frozen until reset.
};

/// Name of a status ("Ok", "InvalidArgument", ...), for logs outside the real-time path.
const char* toString(SimStatus status) noexcept;

}  // namespace bimanual_skills::sim
