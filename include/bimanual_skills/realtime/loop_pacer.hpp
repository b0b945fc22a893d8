/// \file
/// Pacing of a periodic loop on the monotonic wall clock: absolute deadlines t_k = t_0 + k T (no drift from the
/// time a cycle takes), sleeps that end early when the caller has other work (services, pause), and re-anchoring
/// when the loop is off schedule by more than a threshold, so a pause, a reset, a long step or an overloaded machine
/// never leads to a burst of catch-up cycles or to one long sleep.
#pragma once

#include <chrono>

namespace bimanual_skills::realtime {

/// One periodic loop's deadlines. Real-time safe after construction: no allocation, no exceptions, no locks.
class LoopPacer {
 public:
  using Clock = std::chrono::steady_clock;

  /// Period T [s] (> 0) and the largest tolerated lag or lead [s] before the schedule is re-anchored at "now".
  /// \throws std::invalid_argument for a non-positive period or threshold.
  explicit LoopPacer(double period, double max_drift = 0.05);

  /// Starts a new schedule: the next deadline is now (a cycle is due at once). Call after a pause, a reset or a
  /// change of period.
  void reanchor() noexcept;
  /// Sets the period; the schedule is re-anchored. Ignores a non-positive or non-finite period (returns false).
  bool setPeriod(double period) noexcept;

  /// Sleeps until the next deadline, but at most `max_slice` [s]; true if the deadline has come (a cycle is due).
  bool waitUntilDue(double max_slice) noexcept;
  /// Marks the due cycle as done: the next deadline is one period later. If that deadline already lies more than
  /// max_drift in the past (the loop fell behind), the schedule is re-anchored instead of running catch-up cycles.
  void advance() noexcept;

  /// Seconds from now until the next deadline (negative when late).
  double untilDeadline() const noexcept;
  double period() const noexcept { return period_; }
  /// How often the schedule was re-anchored because the loop fell behind (explicit reanchor() calls not counted).
  long slips() const noexcept { return slips_; }

 private:
  double period_, max_drift_;
  Clock::time_point deadline_;
  long slips_ = 0;
};

/// Asks the kernel to run the calling thread with SCHED_FIFO at `priority` (1–99) and locks the process' memory
/// (mlockall), as a real-time control loop on a PREEMPT_RT kernel would. Returns an empty string on success, else
/// why not (e.g. no permission): the loop then runs at normal priority. Not real-time safe (call once at start).
const char* requestRealtimeScheduling(int priority) noexcept;

}  // namespace bimanual_skills::realtime
