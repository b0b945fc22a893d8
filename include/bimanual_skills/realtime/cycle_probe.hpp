/// \file
/// A probe that measures a part of a real-time cycle (its allocation count, say): the hosting loop's control part
/// and the robot's step apart, a simulated task's control part. Real-time safe. Target bimanual_skills_realtime.
#pragma once

#include <cstddef>
#include <optional>

namespace bimanual_skills::realtime {

/// begin() and end() bracket the part measured.
class CycleProbe {
 public:
  virtual ~CycleProbe() = default;
  virtual void begin() noexcept = 0;
  /// Events (allocations, say) since begin().
  virtual std::size_t end() noexcept = 0;

 protected:
  CycleProbe() = default;
  CycleProbe(const CycleProbe&) = default;
  CycleProbe& operator=(const CycleProbe&) = default;
};

/// A CycleProbe over a scoped counter (a type whose constructor starts counting and whose `allocations()` gives the
/// count since), such as the package's testing::AllocationCounter.
template <typename Counter>
class ScopedCounterProbe final : public CycleProbe {
 public:
  void begin() noexcept override { counter_.emplace(); }
  std::size_t end() noexcept override {
    const std::size_t n = counter_->allocations();
    counter_.reset();
    return n;
  }

 private:
  std::optional<Counter> counter_;
};

}  // namespace bimanual_skills::realtime
