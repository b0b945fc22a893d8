/// \file
/// Status of the real-time filtering calls of the signal module.
#pragma once

namespace bimanual_skills::signal {

/// Outcome of a real-time filter update. On anything but Success the filter's state and output are unchanged.
enum class SignalStatus { Success, WrongSize, NotFinite };

/// Human-readable name of a status, for logs outside the real-time path.
const char* toString(SignalStatus status) noexcept;

}  // namespace bimanual_skills::signal
