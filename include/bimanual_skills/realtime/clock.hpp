/// \file
/// Wall-clock intervals on the steady clock: the time of offline work (benchmarks, learning runs, dispatch) for
/// progress lines and results, the simulator's profile of its step, and the monotonic time of the control loops and
/// their waits (never the system time or a simulator's /clock). Reading the clock neither allocates nor locks.
#pragma once

#include <chrono>

namespace bimanual_skills::realtime {

using Clock = std::chrono::steady_clock;

/// Seconds from `from` to `to`.
inline double seconds(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double>(to - from).count();
}

/// Seconds on the steady clock since its epoch: a time stamp of the control loops and their statistics.
inline double monotonicSeconds() noexcept {
  return std::chrono::duration<double>(Clock::now().time_since_epoch()).count();
}

/// Seconds from `start` to now.
inline double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace bimanual_skills::realtime
