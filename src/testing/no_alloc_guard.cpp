// NoAllocGuard: fails the current gtest when its scope allocates (counting in allocation_counter.cpp).
#include "testing/no_alloc_guard.hpp"

#include <gtest/gtest.h>

namespace bimanual_skills::testing {

NoAllocGuard::NoAllocGuard(const char* file, int line) noexcept : file_(file), line_(line) {}

NoAllocGuard::~NoAllocGuard() {
  const std::size_t count = counter_.allocations();
  if (count > 0) {
    ADD_FAILURE_AT(file_, line_) << count << " heap allocation(s) inside a NoAllocGuard scope";
  }
}

}  // namespace bimanual_skills::testing
