// Counting replacements of the global allocation functions, for the real-time allocation tests and benchmarks.
#include "testing/allocation_counter.hpp"

#include <Eigen/Core>

#include <malloc.h>

#include <cerrno>
#include <cstdlib>
#include <new>

extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* pointer, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* pointer);
}

namespace {

// Plain integers in the executable's static TLS block: reading them never allocates.
thread_local std::size_t t_allocations = 0;
thread_local int t_active_counters = 0;

inline void noteAllocation() noexcept {
  if (t_active_counters > 0) {
    ++t_allocations;
  }
}

void* allocateOrThrow(std::size_t size) {
  noteAllocation();
  void* pointer = __libc_malloc(size == 0 ? 1 : size);
  if (pointer == nullptr) throw std::bad_alloc();
  return pointer;
}

void* allocateAlignedOrThrow(std::size_t size, std::align_val_t alignment) {
  noteAllocation();
  void* pointer = __libc_memalign(static_cast<std::size_t>(alignment), size == 0 ? 1 : size);
  if (pointer == nullptr) throw std::bad_alloc();
  return pointer;
}

}  // namespace

extern "C" {
void* malloc(std::size_t size) {
  noteAllocation();
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) {
  noteAllocation();
  return __libc_calloc(count, size);
}
void* realloc(void* pointer, std::size_t size) {
  noteAllocation();
  return __libc_realloc(pointer, size);
}
void* memalign(std::size_t alignment, std::size_t size) {
  noteAllocation();
  return __libc_memalign(alignment, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  noteAllocation();
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** pointer, std::size_t alignment, std::size_t size) {
  noteAllocation();
  void* result = __libc_memalign(alignment, size);
  if (result == nullptr) return ENOMEM;
  *pointer = result;
  return 0;
}
void free(void* pointer) {
  __libc_free(pointer);
}
}

void* operator new(std::size_t size) {
  return allocateOrThrow(size);
}
void* operator new[](std::size_t size) {
  return allocateOrThrow(size);
}
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  noteAllocation();
  return __libc_malloc(size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  noteAllocation();
  return __libc_malloc(size == 0 ? 1 : size);
}
void* operator new(std::size_t size, std::align_val_t alignment) {
  return allocateAlignedOrThrow(size, alignment);
}
void* operator new[](std::size_t size, std::align_val_t alignment) {
  return allocateAlignedOrThrow(size, alignment);
}
void operator delete(void* pointer) noexcept {
  __libc_free(pointer);
}
void operator delete[](void* pointer) noexcept {
  __libc_free(pointer);
}
void operator delete(void* pointer, std::size_t) noexcept {
  __libc_free(pointer);
}
void operator delete[](void* pointer, std::size_t) noexcept {
  __libc_free(pointer);
}
void operator delete(void* pointer, std::align_val_t) noexcept {
  __libc_free(pointer);
}
void operator delete[](void* pointer, std::align_val_t) noexcept {
  __libc_free(pointer);
}
void operator delete(void* pointer, std::size_t, std::align_val_t) noexcept {
  __libc_free(pointer);
}
void operator delete[](void* pointer, std::size_t, std::align_val_t) noexcept {
  __libc_free(pointer);
}

namespace bimanual_skills::testing {

AllocationCounter::AllocationCounter() noexcept : start_(t_allocations), eigen_was_allowed_(true) {
  ++t_active_counters;
#ifdef EIGEN_RUNTIME_NO_MALLOC
  eigen_was_allowed_ = Eigen::internal::is_malloc_allowed();
  Eigen::internal::set_is_malloc_allowed(false);
#endif
}

AllocationCounter::~AllocationCounter() {
  --t_active_counters;
#ifdef EIGEN_RUNTIME_NO_MALLOC
  Eigen::internal::set_is_malloc_allowed(eigen_was_allowed_);
#endif
}

std::size_t AllocationCounter::allocations() const noexcept {
  return t_allocations - start_;
}

}  // namespace bimanual_skills::testing
