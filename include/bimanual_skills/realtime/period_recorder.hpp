/// \file
/// The periods of a real-time loop (or any samples it takes, such as when commands arrived), recorded by the loop
/// and read by another thread for diagnostics and benchmarks: a ring of the most recent samples, written without
/// locks or allocation.
#pragma once

#include <atomic>
#include <cstddef>
#include <memory>
#include <ostream>
#include <vector>

namespace bimanual_skills::realtime {

/// Percentiles of a set of samples.
struct PeriodSummary {
  std::size_t count = 0;
  double median = 0.0, p99 = 0.0, p999 = 0.0, max = 0.0, mean = 0.0;
};

/// The p-quantile (0 ≤ p ≤ 1, nearest rank) of `samples`, which it sorts. 0 for no samples.
double quantile(std::vector<double>& samples, double p);
/// Count, mean, median, 99th and 99.9th percentiles and maximum of `samples` (sorted on return).
PeriodSummary summarize(std::vector<double>& samples);

/// Ring of the last `capacity` samples. record() is real-time safe (one relaxed atomic store per value); snapshot()
/// may run concurrently on another thread and returns the samples recorded so far (at most capacity), each whole.
class PeriodRecorder {
 public:
  /// \throws std::invalid_argument for a zero capacity.
  explicit PeriodRecorder(std::size_t capacity);

  /// Real-time safe: no allocation, no locks, no exceptions.
  void record(double value) noexcept;
  /// The recorded samples (oldest first as far as a concurrent writer allows) into `out` (allocates).
  void snapshot(std::vector<double>& out) const;
  /// Writes the recorded samples as CSV lines "series,value" (17 significant digits) to `out` (allocates).
  void writeCsv(std::ostream& out, const char* series) const;
  /// Total samples recorded since construction or clear().
  std::size_t recorded() const noexcept { return written_.load(std::memory_order_acquire); }
  /// Forgets the samples; not to be called while the writer records.
  void clear() noexcept { written_.store(0, std::memory_order_release); }

 private:
  std::unique_ptr<std::atomic<double>[]> ring_;
  std::size_t capacity_;
  std::atomic<std::size_t> written_{0};
};

}  // namespace bimanual_skills::realtime
