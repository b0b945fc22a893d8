/// \file
/// Wall-clock intervals on the steady clock: the time of offline work (benchmarks, learning runs, dispatch) for
/// progress lines and results, and the simulator's profile of its step. Reading the clock neither allocates nor locks.
#pragma once

#include <chrono>

namespace bimanual_skills::realtime {

using Clock = std::chrono::steady_clock;

/// Seconds from `from` to `to`.
inline double seconds(Clock::time_point from, Clock::time_point to) {
  return std::chrono::duration<double>(to - from).count();
}

/// Seconds from `start` to now.
inline double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace bimanual_skills::realtime
