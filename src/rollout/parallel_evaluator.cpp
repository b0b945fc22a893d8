#include "bimanual_skills/rollout/parallel_evaluator.hpp"

#include "bimanual_skills/parallel/parallel_for.hpp"
#include "bimanual_skills/realtime/clock.hpp"

#include <algorithm>
#include <chrono>
#include <mutex>
#include <stdexcept>

namespace bimanual_skills::rollout {

ParallelEvaluator::ParallelEvaluator(const Factory& factory, int threads) {
  if (threads < 0) throw std::invalid_argument("parallel evaluator: threads must be >= 0 (0: one per core)");
  const int count = parallel::threadCount(threads);
  for (int i = 0; i < count; ++i) {
    tasks_.push_back(factory());
    if (!tasks_.back()) throw std::invalid_argument("parallel evaluator: the task factory returned no task");
  }
}

ParallelEvaluator::~ParallelEvaluator() = default;

std::vector<RolloutResult> ParallelEvaluator::evaluate(const std::vector<RolloutRequest>& batch, const Done& done,
                                                       const std::function<bool()>& stop) {
  std::vector<RolloutResult> results(batch.size());
  std::mutex mutex;  // results and done()
  const bool finished = parallel::parallelFor(
      batch.size(), static_cast<int>(tasks_.size()),
      [&](int worker, std::size_t i) {
        RolloutTask& task = *tasks_[static_cast<std::size_t>(worker)];
        const auto start = std::chrono::steady_clock::now();
        RolloutResult result = task.run(batch[i].parameters, batch[i].seed);
        result.wall_seconds = realtime::secondsSince(start);
        const std::lock_guard<std::mutex> lock(mutex);
        results[i] = std::move(result);
        if (done) done(i, results[i], &task);
      },
      stop);
  if (!finished) throw std::runtime_error("stopped");
  return results;
}

}  // namespace bimanual_skills::rollout
