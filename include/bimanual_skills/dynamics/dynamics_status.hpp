/// \file
/// Status of the real-time calls of the dynamics module.
#pragma once

namespace bimanual_skills::dynamics {

/// Outcome of a real-time dynamics call. On anything but Success the outputs are left unchanged.
enum class DynamicsStatus { Success, WrongSize, NotFinite, NotPositiveDefinite };

/// Human-readable name of a status, for logs outside the real-time path.
const char* toString(DynamicsStatus status) noexcept;

}  // namespace bimanual_skills::dynamics
