#include "bimanual_skills/rollout/parallel_evaluator.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace bimanual_skills::rollout {

ParallelEvaluator::ParallelEvaluator(const Factory& factory, int threads) {
  if (threads < 0) throw std::invalid_argument("parallel evaluator: threads must be >= 0 (0: one per core)");
  const int count = threads > 0 ? threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  for (int i = 0; i < count; ++i) {
    tasks_.push_back(factory());
    if (!tasks_.back()) throw std::invalid_argument("parallel evaluator: the task factory returned no task");
  }
}

ParallelEvaluator::~ParallelEvaluator() = default;

std::vector<RolloutResult> ParallelEvaluator::evaluate(const std::vector<RolloutRequest>& batch, const Done& done,
                                                       const std::function<bool()>& stop) {
  std::vector<RolloutResult> results(batch.size());
  std::atomic<std::size_t> next{0};
  std::mutex mutex;
  std::exception_ptr error;
  bool stopped = false;
  const auto work = [&](RolloutTask& task) {
    for (;;) {
      {
        const std::lock_guard<std::mutex> lock(mutex);
        if (error || stopped) return;
        if (stop && stop()) {
          stopped = true;
          return;
        }
      }
      const std::size_t i = next++;
      if (i >= batch.size()) return;
      try {
        const auto start = std::chrono::steady_clock::now();
        RolloutResult result = task.run(batch[i].parameters, batch[i].seed);
        result.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        const std::lock_guard<std::mutex> lock(mutex);
        results[i] = std::move(result);
        if (done) done(i, results[i], &task);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mutex);
        if (!error) error = std::current_exception();
        return;
      }
    }
  };
  std::vector<std::thread> pool;
  const std::size_t threads = std::min(tasks_.size(), std::max<std::size_t>(batch.size(), 1));
  for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(work, std::ref(*tasks_[t]));
  work(*tasks_.front());
  for (std::thread& thread : pool) thread.join();
  if (error) std::rethrow_exception(error);
  if (stopped) throw std::runtime_error("stopped");
  return results;
}

}  // namespace bimanual_skills::rollout
