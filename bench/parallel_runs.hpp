/// \file
/// Independent runs of the experiment programs: the per-run generator and run-level parallelism whose results do
/// not depend on the number of threads (every run draws only from its own generator and writes only its own slot).
#pragma once

#include "experiment_cli.hpp"

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace bimanual_skills::bench {

/// The generator of one run, seeded by (seed, experiment, run): the same for every algorithm of the experiment.
inline std::mt19937 runGenerator(const ExperimentOptions& options, const std::string& experiment, int run) {
  std::seed_seq seq{options.seed, static_cast<std::uint32_t>(std::hash<std::string>{}(experiment)&0xffffffffu),
                    static_cast<std::uint32_t>(run)};
  return std::mt19937(seq);
}

/// Calls job(i) for i in [0, count) on up to `threads` threads, and done(i) once per i, in increasing i, as soon as
/// jobs 0 … i have all finished (under a lock: done() may write files and print). The first exception of a job is
/// rethrown after every thread has stopped.
inline void parallelRuns(int count, int threads, const std::function<void(int)>& job,
                         const std::function<void(int)>& done) {
  std::atomic<int> next{0};
  std::mutex mutex;
  std::vector<bool> finished(static_cast<std::size_t>(std::max(count, 0)), false);
  int reported = 0;
  std::exception_ptr failure;
  const auto worker = [&]() {
    for (int i = next++; i < count; i = next++) {
      try {
        job(i);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mutex);
        if (!failure) failure = std::current_exception();
        next = count;
        return;
      }
      const std::lock_guard<std::mutex> lock(mutex);
      finished[static_cast<std::size_t>(i)] = true;
      while (reported < count && finished[static_cast<std::size_t>(reported)] && !failure) done(reported++);
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::min(threads, count); ++t) pool.emplace_back(worker);
  worker();
  for (std::thread& thread : pool) thread.join();
  if (failure) std::rethrow_exception(failure);
}

}  // namespace bimanual_skills::bench
