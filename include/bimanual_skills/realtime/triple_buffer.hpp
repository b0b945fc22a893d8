/// \file
/// Lock-free handoff of the latest value between two threads (the pattern of realtime_tools' RealtimeBuffer,
/// without its mutex): one writer thread and one reader thread, neither ever waits for the other. The writer fills
/// a slot of its own and publishes it; the reader takes the newest published slot. Intermediate values the reader
/// did not take are overwritten (latest wins), which is what a command or a state snapshot wants.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace bimanual_skills::realtime {

/// Triple buffer. Exactly one thread may call the writer functions (writeSlot, publish) and exactly one thread the
/// reader functions (readNew, current); both sides are wait-free and do not allocate (copies into the slots are the
/// caller's, so a T with preallocated storage of the right sizes is copied without allocation).
template <typename T>
class TripleBuffer {
 public:
  /// Every slot starts as a copy of `initial` (e.g. vectors already sized), so neither side allocates later.
  explicit TripleBuffer(const T& initial = T()) : slots_{initial, initial, initial} {}
  TripleBuffer(const TripleBuffer&) = delete;
  TripleBuffer& operator=(const TripleBuffer&) = delete;

  /// Writer: the slot to fill; it is invisible to the reader until publish().
  T& writeSlot() noexcept { return slots_[back_]; }
  /// Writer: makes the filled slot the newest value and takes another slot to fill next.
  void publish() noexcept {
    const std::uint8_t previous =
        middle_.exchange(static_cast<std::uint8_t>(back_ | kFresh), std::memory_order_acq_rel);
    back_ = previous & kIndex;
  }
  /// Writer: copies `value` into the write slot and publishes it.
  void write(const T& value) {
    writeSlot() = value;
    publish();
  }

  /// Reader: the newest value if one was published since the last call, else nullptr. The pointer stays valid
  /// (and the value unchanged) until the next readNew().
  const T* readNew() noexcept {
    if ((middle_.load(std::memory_order_acquire) & kFresh) == 0) return nullptr;
    const std::uint8_t previous = middle_.exchange(front_, std::memory_order_acq_rel);
    front_ = previous & kIndex;
    return &slots_[front_];
  }
  /// Reader: the value the last readNew() returned (the initial value before any).
  const T& current() const noexcept { return slots_[front_]; }

 private:
  static constexpr std::uint8_t kIndex = 3, kFresh = 4;
  std::array<T, 3> slots_;
  std::uint8_t back_ = 0;                ///< Writer's slot.
  std::uint8_t front_ = 1;               ///< Reader's slot.
  std::atomic<std::uint8_t> middle_{2};  ///< The slot in between, with kFresh set when it holds an unread value.
};

}  // namespace bimanual_skills::realtime
