/// \file
/// Test utility: proves that a scope performs no heap allocation.
///
/// Linking the bimanual_skills_testing library into a test executable replaces the global operator new/delete and
/// malloc/calloc/realloc/posix_memalign/aligned_alloc/memalign with counting versions (forwarding to glibc). Counting
/// is per thread and only while an AllocationCounter is alive in that thread. With EIGEN_RUNTIME_NO_MALLOC defined,
/// Eigen's own run-time check is switched on for the scope as well (Eigen's allocations then also assert in builds
/// with assertions).
///
/// \code
///   { NoAllocGuard guard; status = forwardKinematics(model, data, q); }  // fails the test on any allocation
/// \endcode
#pragma once

#include "testing/allocation_counter.hpp"

namespace bimanual_skills::testing {

/// Fails the current gtest (non-fatally, naming file and line) if its scope allocates on the heap.
class NoAllocGuard {
 public:
  explicit NoAllocGuard(const char* file = __builtin_FILE(), int line = __builtin_LINE()) noexcept;
  ~NoAllocGuard();
  NoAllocGuard(const NoAllocGuard&) = delete;
  NoAllocGuard& operator=(const NoAllocGuard&) = delete;

 private:
  AllocationCounter counter_;
  const char* file_;
  int line_;
};

}  // namespace bimanual_skills::testing
