#include "bimanual_skills/realtime/loop_pacer.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace bimanual_skills::realtime {

namespace {

LoopPacer::Clock::duration seconds(double s) {
  return std::chrono::duration_cast<LoopPacer::Clock::duration>(std::chrono::duration<double>(s));
}

/// Sleeps until `until` on CLOCK_MONOTONIC, the clock of std::chrono::steady_clock on Linux.
void sleepUntil(LoopPacer::Clock::time_point until) noexcept {
  const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(until.time_since_epoch()).count();
  timespec t{};
  t.tv_sec = static_cast<time_t>(ns / 1000000000);
  t.tv_nsec = static_cast<long>(ns % 1000000000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &t, nullptr) == EINTR) {
  }
}

}  // namespace

LoopPacer::LoopPacer(double period, double max_drift) : period_(period), max_drift_(max_drift) {
  if (!(period > 0.0) || !std::isfinite(period) || !(max_drift > 0.0)) {
    throw std::invalid_argument("LoopPacer: the period and the drift threshold must be > 0");
  }
  reanchor();
}

void LoopPacer::reanchor() noexcept {
  deadline_ = Clock::now();
}

bool LoopPacer::setPeriod(double period) noexcept {
  if (!(period > 0.0) || !std::isfinite(period)) return false;
  period_ = period;
  reanchor();
  return true;
}

double LoopPacer::untilDeadline() const noexcept {
  return std::chrono::duration<double>(deadline_ - Clock::now()).count();
}

bool LoopPacer::waitUntilDue(double max_slice) noexcept {
  const Clock::time_point now = Clock::now();
  if (now >= deadline_) return true;
  if (deadline_ - now > seconds(max_drift_ + period_)) {
    // Ahead of schedule by more than a period plus the threshold (the clock or the period changed): start afresh.
    ++slips_;
    reanchor();
    return true;
  }
  const Clock::time_point slice_end = now + seconds(std::max(0.0, max_slice));
  sleepUntil(std::min(deadline_, slice_end));
  return Clock::now() >= deadline_;
}

void LoopPacer::advance() noexcept {
  deadline_ += seconds(period_);
  if (Clock::now() - deadline_ > seconds(max_drift_)) {
    ++slips_;
    reanchor();
  }
}

const char* requestRealtimeScheduling(int priority) noexcept {
  sched_param parameters{};
  parameters.sched_priority = priority;
  const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &parameters);
  if (error != 0) return strerror(error);
  if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) return strerror(errno);
  return "";
}

}  // namespace bimanual_skills::realtime
