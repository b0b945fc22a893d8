/// \file
/// Per-call timing for Google Benchmark programs: median, p99 and worst case from timed batches.
#pragma once

#include "testing/allocation_counter.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <vector>

namespace bimanual_skills::bench {

/// Calls per timed batch: per-call = batch time / kBatch, so the steady clock's own cost is spread over the batch.
constexpr int kBatch = 8;

/// Runs `call(k)` for k cycling over [0, cycle) in timed batches of `batch` calls and sets the counters median_ns,
/// p99_ns, p999_ns and max_ns per call, and `allocations`: heap allocations counted over the whole measured loop
/// (the real-time calls must make none). Batches average the clock's cost away for calls of a few hundred ns; for
/// calls of microseconds, batch = 1 times every call and gives true tail percentiles.
template <typename Call>
void timeBatches(benchmark::State& state, int cycle, Call call, int batch = kBatch) {
  std::vector<double> per_call_ns;
  per_call_ns.reserve(1 << 22);
  // Untimed warm-up: a controller runs continuously, so its caches and branch predictors are warm; without this
  // the first calls after constructing the objects under test make up the p99.9 of short runs.
  for (int k = 0; k < std::min(cycle, 1000); ++k) call(k);
  int k = 0;
  const bimanual_skills::testing::AllocationCounter allocations;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    for (int b = 0; b < batch; ++b) {
      call(k);
      k = (k + 1) % cycle;
    }
    const auto stop = std::chrono::steady_clock::now();
    if (per_call_ns.size() < per_call_ns.capacity()) {
      per_call_ns.push_back(std::chrono::duration<double, std::nano>(stop - start).count() / batch);
    }
  }
  state.counters["allocations"] = static_cast<double>(allocations.allocations());
  state.SetItemsProcessed(state.iterations() * batch);
  std::sort(per_call_ns.begin(), per_call_ns.end());
  const auto at = [&](double fraction) {
    return per_call_ns[static_cast<std::size_t>(fraction * static_cast<double>(per_call_ns.size() - 1))];
  };
  state.counters["median_ns"] = at(0.5);
  state.counters["p99_ns"] = at(0.99);
  state.counters["p999_ns"] = at(0.999);
  state.counters["max_ns"] = per_call_ns.back();
}

}  // namespace bimanual_skills::bench
