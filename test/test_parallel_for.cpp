// parallel::parallelFor, the one thread pool of the project: every index once, per-worker resources, a worker's
// exception at the caller (whichever thread threw it), an early stop, and the pools built on it.
#include "bimanual_skills/parallel/parallel_for.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

namespace bp = bimanual_skills::parallel;

TEST(ParallelFor, CallsEveryIndexOnceOnTheWorkersAsked) {
  std::vector<std::atomic<int>> calls(1000);
  std::vector<std::atomic<int>> per_worker(4);
  EXPECT_TRUE(bp::parallelFor(calls.size(), 4, [&](int worker, std::size_t i) {
    ++calls[i];
    ++per_worker[static_cast<std::size_t>(worker)];
  }));
  for (const auto& c : calls) EXPECT_EQ(c.load(), 1);
  int total = 0;
  for (const auto& w : per_worker) total += w.load();
  EXPECT_EQ(total, 1000);
  EXPECT_TRUE(bp::parallelFor(0, 4, [](int, std::size_t) { FAIL() << "no index to call"; }));
  EXPECT_EQ(bp::threadCount(3), 3);
  EXPECT_GE(bp::threadCount(0), 1);
  EXPECT_THROW(bp::threadCount(-1), std::invalid_argument);
}

TEST(ParallelFor, AWorkersExceptionReachesTheCaller) {
  // Thrown on a thread other than the caller's: the caller gets it, after the others have stopped.
  const std::thread::id caller = std::this_thread::get_id();
  std::atomic<int> after{0};
  for (int attempt = 0; attempt < 20; ++attempt) {
    try {
      bp::parallelFor(200, 3, [&](int, std::size_t i) {
        if (i == 50) {
          if (std::this_thread::get_id() == caller) throw std::logic_error("from the caller's thread");
          throw std::runtime_error("job 50 failed");
        }
        std::this_thread::sleep_for(std::chrono::microseconds(100));
        ++after;
      });
      FAIL() << "no exception";
    } catch (const std::runtime_error& e) {
      EXPECT_STREQ(e.what(), "job 50 failed");
      EXPECT_LT(after.load(), 200 * (attempt + 1));  // the handing out stopped
      return;
    } catch (const std::logic_error&) {
      // job 50 ran on the calling thread this time: try again for a worker's throw
    }
  }
  FAIL() << "job 50 never ran on another thread";
}

TEST(ParallelFor, StopsWhenAsked) {
  std::atomic<int> ran{0};
  EXPECT_FALSE(bp::parallelFor(
      1000, 2, [&](int, std::size_t) { ++ran; }, [&] { return ran.load() >= 10; }));
  EXPECT_LT(ran.load(), 1000);
}
