/// \file
/// The one way the project runs independent work on threads (offline work: rollouts, workspace voxels, pair sums,
/// experiment runs; never the control loop). Every parallel loop uses it, so every one carries a worker's exception
/// to the caller and stops the same way.
#pragma once

#include <cstddef>
#include <functional>

namespace bimanual_skills::parallel {

/// `requested` threads, or one per core for 0 (at least 1). \throws std::invalid_argument for a negative count.
int threadCount(int requested);

/// Calls job(worker, i) once for every i in [0, count), on min(threads, count) threads (the calling thread is
/// worker 0; threads as in threadCount). Indices are handed out in increasing order as workers become free; `worker`
/// in [0, threads) lets a job use per-thread resources. The first exception a job throws stops the handing out; it
/// is rethrown to the caller once every thread has finished its current job. `stop`, if given, is asked before each
/// index (under a lock): true ends the loop early, and parallelFor returns false; otherwise it returns true.
bool parallelFor(std::size_t count, int threads, const std::function<void(int worker, std::size_t i)>& job,
                 const std::function<bool()>& stop = {});

}  // namespace bimanual_skills::parallel
