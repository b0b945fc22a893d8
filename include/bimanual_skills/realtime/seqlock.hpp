/// \file
/// A value one real-time thread writes and any number of other threads read whole (a sequence lock): the writer
/// never waits, a reader retries while a write is under way and never sees half of one write and half of another.
/// For what a loop reports to diagnostics (the time a scheduled command was done and for when it was scheduled,
/// always as a pair). The value is kept in atomic words, so there is no data race in the C++ sense.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace bimanual_skills::realtime {

template <typename T>
class SeqLock {
  static_assert(std::is_trivially_copyable_v<T>, "SeqLock holds trivially copyable values");

 public:
  explicit SeqLock(const T& initial = T()) noexcept { write(initial); }
  SeqLock(const SeqLock&) = delete;
  SeqLock& operator=(const SeqLock&) = delete;

  /// One writer thread. Real-time safe: no allocation, no lock, no wait.
  void write(const T& value) noexcept {
    std::array<std::uint64_t, kWords> words{};
    std::memcpy(words.data(), &value, sizeof(T));
    const std::uint64_t s = sequence_.load(std::memory_order_relaxed);
    sequence_.store(s + 1, std::memory_order_relaxed);  // odd: a write is under way
    std::atomic_thread_fence(std::memory_order_release);
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(words[i], std::memory_order_relaxed);
    sequence_.store(s + 2, std::memory_order_release);
  }

  /// Any thread: the last whole value written.
  T read() const noexcept {
    std::array<std::uint64_t, kWords> words{};
    for (;;) {
      const std::uint64_t before = sequence_.load(std::memory_order_acquire);
      if (before & 1U) continue;
      for (std::size_t i = 0; i < kWords; ++i) words[i] = words_[i].load(std::memory_order_relaxed);
      std::atomic_thread_fence(std::memory_order_acquire);
      if (sequence_.load(std::memory_order_relaxed) == before) break;
    }
    T value;
    std::memcpy(&value, words.data(), sizeof(T));
    return value;
  }

  /// Writes so far (any thread).
  std::uint64_t writes() const noexcept { return sequence_.load(std::memory_order_acquire) / 2 - 1; }

 private:
  static constexpr std::size_t kWords = (sizeof(T) + 7) / 8;
  std::array<std::atomic<std::uint64_t>, kWords> words_{};
  std::atomic<std::uint64_t> sequence_{0};
};

}  // namespace bimanual_skills::realtime
