#include "bimanual_skills/parallel/parallel_for.hpp"

#include <algorithm>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace bimanual_skills::parallel {

int threadCount(int requested) {
  if (requested < 0) throw std::invalid_argument("thread count must be >= 0 (0: one per core)");
  return requested > 0 ? requested : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

bool parallelFor(std::size_t count, int threads, const std::function<void(int, std::size_t)>& job,
                 const std::function<bool()>& stop) {
  const int workers = static_cast<int>(
      std::min<std::size_t>(static_cast<std::size_t>(threadCount(threads)), std::max<std::size_t>(count, 1)));
  std::mutex mutex;
  std::size_t next = 0;
  std::exception_ptr error;
  bool stopped = false;
  const auto work = [&](int worker) {
    for (;;) {
      std::size_t i = 0;
      {
        const std::lock_guard<std::mutex> lock(mutex);
        if (error || stopped || next >= count) return;
        if (stop && stop()) {
          stopped = true;
          return;
        }
        i = next++;
      }
      try {
        job(worker, i);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(mutex);
        if (!error) error = std::current_exception();
        return;
      }
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(static_cast<std::size_t>(workers - 1));
  try {
    for (int w = 1; w < workers; ++w) pool.emplace_back(work, w);
  } catch (...) {
    const std::lock_guard<std::mutex> lock(mutex);
    if (!error) error = std::current_exception();  // a thread could not start: stop the others, then report it
  }
  work(0);
  for (std::thread& thread : pool) thread.join();
  if (error) std::rethrow_exception(error);
  return !stopped;
}

}  // namespace bimanual_skills::parallel
