/// \file
/// The wall-clock time of offline work (benchmarks, learning runs, dispatch), for progress lines and results. Not
/// for real-time paths.
#pragma once

#include <chrono>

namespace bimanual_skills::tools {

using Clock = std::chrono::steady_clock;

/// Seconds from `start` to now.
inline double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace bimanual_skills::tools
