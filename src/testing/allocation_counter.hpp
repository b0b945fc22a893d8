/// \file
/// Counts heap allocations per thread. Linking bimanual_skills_allocation_counter into an executable replaces the
/// global operator new/delete and malloc/calloc/realloc/posix_memalign/aligned_alloc/memalign with counting versions
/// (forwarding to glibc); counting happens only while an AllocationCounter is alive in the thread. With
/// EIGEN_RUNTIME_NO_MALLOC defined, Eigen's own run-time check is switched on for the scope as well
/// (set_is_malloc_allowed(false): an Eigen allocation then also asserts in builds with assertions).
#pragma once

#include <cstddef>

namespace bimanual_skills::testing {

/// Counts heap allocations made by the current thread while it is alive. Nestable.
class AllocationCounter {
 public:
  AllocationCounter() noexcept;
  ~AllocationCounter();
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;

  /// Allocations (operator new or the malloc family) by this thread since construction.
  std::size_t allocations() const noexcept;

 private:
  std::size_t start_;
  bool eigen_was_allowed_;
};

}  // namespace bimanual_skills::testing
