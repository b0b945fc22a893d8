/// \file
/// Independent runs of the experiment programs: the per-run generator and run-level parallelism whose results do
/// not depend on the number of threads (every run draws only from its own generator and writes only its own slot).
#pragma once

#include "bimanual_skills/parallel/parallel_for.hpp"
#include "experiment_cli.hpp"

#include <algorithm>
#include <cstdint>
#include <functional>
#include <mutex>
#include <random>
#include <string>
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
  std::mutex mutex;
  std::vector<bool> finished(static_cast<std::size_t>(std::max(count, 0)), false);
  int reported = 0;
  parallel::parallelFor(static_cast<std::size_t>(std::max(count, 0)), threads, [&](int, std::size_t i) {
    job(static_cast<int>(i));
    const std::lock_guard<std::mutex> lock(mutex);
    finished[i] = true;
    while (reported < count && finished[static_cast<std::size_t>(reported)]) done(reported++);
  });
}

}  // namespace bimanual_skills::bench
